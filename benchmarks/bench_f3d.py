"""A whole `raycast-phong render FILE -o x.png` against f3d's offscreen render of the same file to PNG, both as the
process a user starts (issue 46): interpreter, imports, reading, framing, the frame and the PNG, all counted.

Each round runs both on every file, alternating which goes first, so the two see the same load; the table gives
each side's least wall and CPU time (user + sys, children included) over the rounds, the ratios, and the load
average beside them. Our kernels are warm (one untimed run first); f3d (`pip install f3d`, 4.x, EGL offscreen)
has nothing to compile. Both render 640×480 from their own default framing.

Files: the 1.1M-triangle Stanford bunny of make_scans.py in binary PLY, GLB, binary STL and OBJ; small files from
the repository (a textured GLB, an OBJ with its MTL); and the default scene (ours alone: the start-up target, set
beside `python -c "import numpy"`). --files adds any others.
Usage: python benchmarks/bench_f3d.py [--rounds 5] [--files PATH ...] [--no-scans]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OURS = "import raycast_phong.cli as cli; cli.main()"
F3D = """
import sys, f3d
f3d.Log.set_verbose_level(f3d.Log.VerboseLevel.QUIET)
engine = f3d.Engine.create(True)
engine.window.size = (640, 480)
engine.scene.add(sys.argv[1])
engine.window.render_to_image().save(sys.argv[2])
"""
NUMPY = "import numpy"
SMALL = ("scenes/meshes/still_life.glb", "tests/data/models/BoxTextured.glb")


def timed(command: list[str]) -> tuple[float, float, int]:
    """Wall seconds, CPU seconds (user + sys of the process and its children) and the exit status of `command`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        print(f"  {command[-3:]}: exit {done.returncode}: {done.stderr.decode(errors='replace').strip()[:200]}")
    return wall, cpu, done.returncode


def commands(path: Path | None, out: Path) -> dict[str, list[str]]:
    """The two processes for `path` (None: the default scene, ours against numpy's import)."""
    if path is None:
        return {"ours": [sys.executable, "-c", OURS, "render", "-q", "-o", str(out / "ours.png")],
                "peer": [sys.executable, "-c", NUMPY]}
    return {"ours": [sys.executable, "-c", OURS, "render", str(path), "-q", "-o", str(out / "ours.png"),
                     "--width", "640", "--height", "480"],
            "peer": [sys.executable, "-c", F3D, str(path), str(out / "f3d.png")]}


def files(arguments) -> list[Path | None]:
    chosen: list[Path | None] = [None]
    if not arguments.no_scans:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from make_scans import scan
        chosen += [scan("stanford-bunny-1m", fmt) for fmt in ("ply", "glb", "stl", "obj")]
    chosen += [ROOT / name for name in SMALL]
    chosen += [Path(name) for name in arguments.files]
    return chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--files", nargs="*", default=[])
    parser.add_argument("--no-scans", action="store_true", help="leave out the 1.1M-triangle bunny")
    arguments = parser.parse_args()
    try:
        import f3d  # noqa: F401
    except ImportError:
        sys.exit("bench_f3d.py needs the f3d package: pip install f3d")
    chosen = files(arguments)
    print(f"{os.cpu_count()} cores; load at the start {os.getloadavg()[0]:.1f}; {arguments.rounds} rounds")
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch)
        for path in chosen:
            runs = commands(path, out)
            timed(runs["ours"])  # the kernels in the cache, the file in the page cache
            timed(runs["peer"])
            best = {side: [float("inf"), float("inf")] for side in runs}
            loads = []
            for k in range(arguments.rounds):
                for side in (("ours", "peer") if k % 2 == 0 else ("peer", "ours")):
                    wall, cpu, _ = timed(runs[side])
                    best[side] = [min(best[side][0], wall), min(best[side][1], cpu)]
                loads.append(os.getloadavg()[0])
            name = "default scene (peer: import numpy)" if path is None else path.name
            rows.append((name, *best["ours"], *best["peer"], min(loads), max(loads)))
            print(f"{name}: ours {best['ours'][0]:.2f} s ({best['ours'][1]:.2f} CPU), peer {best['peer'][0]:.2f} s "
                  f"({best['peer'][1]:.2f} CPU), load {min(loads):.1f}-{max(loads):.1f}", flush=True)
    print("\n| file | ours wall | ours CPU | f3d wall | f3d CPU | wall ratio | CPU ratio | load |")
    print("|---|---|---|---|---|---|---|---|")
    for name, wall, cpu, peer_wall, peer_cpu, low, high in rows:
        print(f"| {name} | {wall:.2f} | {cpu:.2f} | {peer_wall:.2f} | {peer_cpu:.2f} | {wall / peer_wall:.2f} | "
              f"{cpu / peer_cpu:.2f} | {low:.1f}-{high:.1f} |")


if __name__ == "__main__":
    main()
