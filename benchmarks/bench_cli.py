"""Wall time of a warm `raycast-phong render` of the default scene (issue 22's ≤ 0.6 s target), and where it goes.

Each run is a fresh process, as a user starts it (`python -c "from raycast_phong.cli import main; main()"
render -q -o …`, what the console script runs); beforehand the package is compiled to bytecode (compileall,
as pip does at install) and one run makes sure the kernels are in numba's cache. Reports the minimum over
--repeats of the wall time and of the process's CPU time (user + sys; two tile threads may make it exceed the
wall), then the import time per package (`python -X importtime`) and the start-up in stages, timed in one
process: imports, loading the scene, the first kernel calls, the shading kernel, the render, the write and the
interpreter's teardown at exit (which the program, cli.main, skips).

--before PATH times another source tree too (e.g. `git archive REV | tar -x -C PATH`), interleaved run by run,
so both sides see the same machine load.
Usage: python benchmarks/bench_cli.py [--repeats 3] [--before PATH]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The program as the console script runs it (cli.main; a tree from before it had only app).
CLI = "import raycast_phong.cli as cli; getattr(cli, 'main', cli.app)()"
STAGES = """
import time
start = time.perf_counter()
marks = []
def mark(name):
    marks.append((name, time.perf_counter()))
import raycast_phong as rp, raycast_phong.cli
assert rp.__file__.startswith(TREE), rp.__file__
mark("import the CLI (typer)")
scene = rp.load_scene(rp.default_scene_path())
mark("load the scene (pydantic, the schema)")
import raycast_phong.io.image_io
mark("import the output's writer (OpenImageIO)")
import numpy as np
from raycast_phong.renderer import frame as render
mark("import the renderer (numba, embreex, the stages)")
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.intersect import unit_frame
from raycast_phong.renderer.pack import RayGenerator, camera_rig
geometry = build_geometry(scene)
frame = unit_frame(geometry.vertices)
RayGenerator(camera_rig(scene), frame, 2, 2, 1, 4).rows(0, 2)
mark("the first kernel calls: geometry, rays (numba's set-up, kernels loaded)")
render.warm_kernels((np.float32,))
mark("load the shading kernel")
result = render.render(scene)
mark("render (frame %.3f s)" % result.timings["frame"])
rp.write_image(OUTPUT, result.image, colour=result.colour)
mark("write the PNG")
last = start
for name, at in marks:
    print(f"{(at - last) * 1e3:8.1f} ms  {name}")
    last = at
print(f"{(last - start) * 1e3:8.1f} ms  total after Python's own start")
print(f"END {time.time()!r}")  # the parent adds the exit: the interpreter's teardown (which cli.main skips)
"""


def run(tree: Path, arguments: list[str], importtime: bool = False) -> tuple[float, float, str]:
    """(wall seconds, CPU seconds, stderr) of one fresh `python -c CLI arguments` on source tree `tree`."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    # From a neutral folder: `python -c` puts the current folder first on sys.path, before PYTHONPATH.
    done = subprocess.run([sys.executable, *(["-X", "importtime"] if importtime else []), "-c", CLI, *arguments],
                          env=env, capture_output=True, text=True, timeout=600, cwd=tempfile.gettempdir())
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        sys.exit(f"{tree}: raycast-phong {' '.join(arguments)} failed:\n{done.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), done.stderr


def import_breakdown(stderr: str, top: int = 12) -> list[tuple[str, float]]:
    """Milliseconds of import per package the program pulls in (-X importtime): a module imported by the
    package's own code or at top level counts with everything it imports, under its top-level name; the
    package's own modules count their own time only."""
    rows = [(int(own), int(total), name.strip(), (len(name) - len(name.lstrip(" "))) // 2)
            for own, total, name in re.findall(r"^import time:\s+(\d+) \|\s+(\d+) \|( *\S+)$", stderr, re.MULTILINE)]
    seconds: dict[str, float] = defaultdict(float)
    for index, (own, total, name, depth) in enumerate(rows):
        # A module's importer is the next line at a smaller depth (children are listed before their parent).
        importer = next((row[2] for row in rows[index + 1:] if row[3] < depth), "")
        if name.startswith("raycast_phong"):
            seconds["raycast_phong (own modules)"] += own / 1e3
        elif not importer or importer.startswith("raycast_phong"):
            seconds[name.split(".")[0]] += total / 1e3
    return sorted(seconds.items(), key=lambda item: -item[1])[:top]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", type=Path, help="another source tree to time the same way, interleaved")
    args = parser.parse_args()
    trees = {"this tree": ROOT}
    if args.before:
        trees = {"before": args.before.resolve(), **trees}
    with tempfile.TemporaryDirectory() as folder:
        arguments = ["render", "-q", "-o", str(Path(folder) / "out.png")]
        for tree in trees.values():
            # Bytecode, as an installed package has it (pip compiles at install): with PYTHONDONTWRITEBYTECODE
            # set, as here, each run would otherwise compile the package's modules from source (≈ 0.1 s).
            subprocess.run([sys.executable, "-m", "compileall", "-q", str(tree / "raycast_phong")], check=True)
            run(tree, arguments)  # compiles the kernels if this tree's cache lacks them
        walls: dict[str, list[float]] = defaultdict(list)
        cpus: dict[str, list[float]] = defaultdict(list)
        for _ in range(args.repeats):
            for name, tree in trees.items():
                wall, cpu, _ = run(tree, arguments)
                walls[name].append(wall)
                cpus[name].append(cpu)
        print(f"warm `raycast-phong render` of the default scene, min of {args.repeats} (target ≤ 0.6 s wall):")
        for name in trees:
            print(f"  {name:10s} wall {min(walls[name]):.3f} s   CPU {min(cpus[name]):.3f} s   "
                  f"(walls {', '.join(f'{w:.2f}' for w in walls[name])})")
        if args.before:
            print(f"  after / before: wall {min(walls['this tree']) / min(walls['before']):.2f}, "
                  f"CPU {min(cpus['this tree']) / min(cpus['before']):.2f}")
        for name, tree in trees.items():
            _, _, stderr = run(tree, arguments, importtime=True)
            print(f"\nimport time by package, {name} (ms, one run):")
            for package, milliseconds in import_breakdown(stderr):
                print(f"  {milliseconds:7.1f}  {package}")
            code = STAGES.replace("OUTPUT", repr(arguments[-1])).replace("TREE", repr(str(tree)))
            stages = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": str(tree)},
                                    capture_output=True, text=True, timeout=600, cwd=folder)
            ended = time.time()
            lines, _, end = stages.stdout.rpartition("END ")
            teardown = f"{(ended - float(end)) * 1e3:8.1f} ms  the exit (the interpreter's teardown, as app() " \
                       "ends; cli.main skips it)\n" if end.strip() else ""
            print(f"start-up in stages, {name} (one process):\n{lines}{teardown}{stages.stderr}")


if __name__ == "__main__":
    main()
