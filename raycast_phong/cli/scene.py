"""`scene` and `schema`: the scene file a mesh file stands for, and the JSON Schema of the format."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

import raycast_phong as rp

from .common import (
    SetOption,
    UpOption,
    ViewOption,
    _view,
    app,
    check_verbosity,
    exit_codes,
    note,
    quiet_option,
    verbose_option,
)


@app.command("scene", epilog="""
**Examples**

  raycast-phong scene model.obj > model.toml           # then edit it and render model.toml

  raycast-phong scene model.glb --view front --up z -o model.toml   # file paths written relative to model.toml

  raycast-phong scene model.ply --set render.width=1280 --set render.height=720

  raycast-phong scene -o default.toml                  # the built-in default scene, to edit

  raycast-phong scene --example mesh -o mesh.toml      # an example scene; --example list names them all
""")
def scene_command(
    scene: Annotated[Path | None, typer.Argument(help="Mesh file (or a scene file, written out with every key); "
                                                 "none: the built-in default scene.", show_default=False,
                                                 dir_okay=False)] = None,
    example: Annotated[str | None, typer.Option("--example", metavar="NAME", help="An example scene shipped with "
                       "the package instead of SCENE (`--example list` names them); its meshes and maps are "
                       "named where the package keeps them, or relative to -o's folder.")] = None,
    output: Annotated[Path | None, typer.Option("--output", "-o", help="Write the TOML here (atomically) instead "
                      "of to standard output; the files the scene names (meshes, texture maps) are then written "
                      "relative to its folder.")] = None,
    set_: SetOption = [],
    view: ViewOption = None,
    up: UpOption = None,
    quiet: Annotated[bool, quiet_option("notes on what the mesh file's materials left out")] = False,
    verbose: Annotated[bool, verbose_option("the files the scene reads (meshes, colour maps): each key path "
                       "and the file it resolves to")] = False,
) -> None:
    """Print the scene file a mesh file stands for: its materials, the framing camera, the key light and
    every other key with its value. `render` of that file gives the same image as `render` of the mesh."""
    from raycast_phong.io.scene_toml import scene_toml
    from raycast_phong.scene.load import is_mesh_file
    check_verbosity(quiet, verbose)
    with exit_codes():
        scene = _chosen(scene, example)
        if scene is None:  # --example list
            return
        loaded = rp.load_scene(scene, set_, view=_view(view), up=up)
        notes = ()
        if is_mesh_file(scene):
            from raycast_phong.io.meshes.source import mesh_source, source_key
            source = loaded.mesh_sources.get(source_key(scene)) or mesh_source(scene)  # framing's, as loaded
            notes = source.bounds().notes
        header = (f"# The scene `raycast-phong render {scene.name}` renders: written by `raycast-phong scene`.\n"
                  "# A [materials.NAME] table overrides the mesh file's material of that name; see docs/meshes.md.")
        if output is not None:
            from raycast_phong.io.files import check_output_file
            check_output_file(output, inputs=(scene, *loaded.files_read()))  # nor its .mtl, maps, buffers
        text = scene_toml(loaded, header, relative_to=output.parent if output is not None else None)
        if output is not None:
            from raycast_phong.io.atomic import write_text
            write_text(output, text)
    if not quiet:
        for line in notes:
            note(line)
    if verbose:
        from raycast_phong.codes import OUTPUT_PATH
        from raycast_phong.values.messages import dotted
        for key, path in loaded.named_files().items():
            if key != OUTPUT_PATH:  # the one file a scene names that it writes, not reads
                typer.echo(f"reads {dotted(key)}: {loaded.resolve(path)}", err=True)
    if output is None:
        typer.echo(text, nl=False)


@app.command(epilog="""
**Examples**

  raycast-phong schema > scene.schema.json
""")
def schema(
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print only warnings and errors besides the schema "
                     "(the schema is all it prints either way).")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", help="Nothing more to print: the schema is the whole "
                       "output (taken so that every command takes it).")] = False,
) -> None:
    """Print the JSON Schema of the scene format (the same as docs/scene.schema.json)."""
    check_verbosity(quiet, verbose)
    from raycast_phong.scene.schema import scene_json_schema
    typer.echo(json.dumps(scene_json_schema(), indent=2, ensure_ascii=False))


def _chosen(scene: Path | None, example: str | None) -> Path | None:
    """The scene file to write: SCENE, an example's, or the default's; None after printing `--example list`."""
    from raycast_phong.errors import OptionError
    from raycast_phong.scene.schema import example_names, examples_folder
    if example is None:
        return scene if scene is not None else rp.default_scene_path()
    if scene is not None:
        raise OptionError(f"--example {example!r} and the scene {str(scene)!r}: give one of them")
    names = example_names()
    if example == "list":
        typer.echo("\n".join(names))
        return None
    if example not in names:
        from raycast_phong.values.messages import did_you_mean
        raise OptionError(f"--example: no example scene {example!r}{did_you_mean(example, names)}; examples: "
                          f"{', '.join(names)}")
    return examples_folder() / f"{example}.toml"
