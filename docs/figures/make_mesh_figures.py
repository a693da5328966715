"""Make the pictures of docs/meshes.md with the command line (run from the repository root).

    .venv/bin/python docs/figures/make_mesh_figures.py

Renders each shipped model of scenes/meshes/ as `raycast-phong render MODEL` does, into docs/meshes/;
the STL and OFF pictures are of the torus knot converted to those formats (they carry no materials).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import trimesh

OUT = Path("docs/meshes")
MESHES = Path("scenes/meshes")
SIZE = ["--width", "480", "--height", "360", "--samples", "2"]


def render(model: Path, name: str, *options: str) -> None:
    command = [sys.executable, "-m", "raycast_phong.cli", "render", str(model), "-o", str(OUT / name),
               *SIZE, *options]
    print(" ".join(["raycast-phong", *command[3:]]))
    subprocess.run(command, check=True)


def main() -> None:
    OUT.mkdir(exist_ok=True)
    render(MESHES / "dice.obj", "dice-obj.png")
    render(MESHES / "painted_knot.ply", "painted-knot-ply.png")
    render(MESHES / "still_life.glb", "still-life-glb.png")
    render(MESHES / "still_life.glb", "still-life-glb-top.png", "--view", "top")
    with tempfile.TemporaryDirectory() as folder:
        knot = trimesh.load(MESHES / "torus_knot.ply", process=False)
        for suffix in ("stl", "off"):
            path = Path(folder) / f"torus_knot.{suffix}"
            knot.export(path)
            render(path, f"torus-knot-{suffix}.png", "--shading", "flat")


if __name__ == "__main__":
    main()
