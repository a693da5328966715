"""A batch of small scenes with --jobs 1 against --jobs 2 (issue 6's speed target: ≥ 1.7× on 2 cores), and the
start-up overhead a worker process pays before its first scene.

Scenes: --scenes copies of one icosphere (--subdivisions) at --size × --size, --samples² rays per pixel, each
file different by a comment so every one renders. Each batch is the whole `raycast-phong batch --force`
command in a fresh process (what a user waits for), median of --repeats. Start-up, measured in fresh
processes: interpreter start, `import raycast_phong`, the first render's extra time (numba loads its cached
kernels) and, per scene, load + geometry + BVH build (the part of a scene that is not its pixels).
Usage: python benchmarks/bench_batch.py [--scenes 20] [--size 256] [--samples 2] [--subdivisions 4] [--repeats 3]
"""

from __future__ import annotations

import argparse
import re
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENE = """\
# copy {index}
[render]
width = {size}
height = {size}
samples = {samples}
shading = "phong"

[camera]
position = [0, 0, 4]
fov = 40

[[lights]]
position = [2, 2, 3]

[materials.m]
kd = [0.7, 0.5, 0.3]
ks = 0.5
shininess = 32

[[objects]]
shape = "icosphere"
subdivisions = {subdivisions}
material = "m"
"""

STARTUP = """
import time, sys
started = time.perf_counter()
import raycast_phong as rp
imported = time.perf_counter()
scene = rp.load_scene(sys.argv[1])
first = rp.render(scene, threads=1)
rendered = time.perf_counter()
again = min((rp.render(scene, threads=1) for _ in range(3)), key=lambda r: r.timings["frame"])
second = min(rp.render(scene, threads=1).timings["frame"] for _ in range(3))
print(imported - started, (rendered - imported) - (again.timings["geometry"] + again.timings["build"] + second),
      again.timings["geometry"] + again.timings["build"], second)
"""


def run_batch(folder: Path, out: Path, jobs: int) -> tuple[float, float]:
    """(whole command, the batch itself as the command reports it: after its own imports)."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "cli", "batch", str(folder), "--out", str(out), "--jobs", str(jobs),
                           "--force"], check=True, cwd=Path(__file__).resolve().parents[1], capture_output=True,
                          text=True)
    whole = time.perf_counter() - start
    inside = float(re.search(r"failed in ([0-9.]+)s", done.stdout).group(1))
    return whole, inside


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=20)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--samples", type=int, default=2)
    parser.add_argument("--subdivisions", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        folder, out = Path(temporary) / "scenes", Path(temporary) / "out"
        folder.mkdir()
        for index in range(args.scenes):
            (folder / f"scene{index:02}.toml").write_text(SCENE.format(index=index, size=args.size,
                                                                       samples=args.samples,
                                                                       subdivisions=args.subdivisions))
        # Start-up: a bare interpreter, then the package's imports, kernel load and per-scene BVH.
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], check=True)
        interpreter = time.perf_counter() - start
        measured = subprocess.run([sys.executable, "-c", STARTUP, str(folder / "scene00.toml")], check=True,
                                  capture_output=True, text=True).stdout.split()
        imports, kernels, bvh, frame = map(float, measured)
        times = {jobs: [] for jobs in (1, 2)}
        for _ in range(args.repeats):
            for jobs in (1, 2):
                times[jobs].append(run_batch(folder, out, jobs))
        manifest = json.loads((out / "manifest.json").read_text())["scenes"]
        total = statistics.median(entry["seconds"]["total"] for entry in manifest.values())
    one, two = (statistics.median(whole for whole, _ in times[j]) for j in (1, 2))
    inside_one, inside_two = (statistics.median(inside for _, inside in times[j]) for j in (1, 2))
    print(f"{args.scenes} scenes of {args.size}×{args.size}, {args.samples}² samples, icosphere of "
          f"{20 * 4 ** args.subdivisions:,} triangles; median of {args.repeats} whole `batch --force` commands")
    print(f"--jobs 1  {one:7.2f} s   ({', '.join(f'{t:.2f}' for t, _ in times[1])}); the batch itself "
          f"{inside_one:.2f} s")
    print(f"--jobs 2  {two:7.2f} s   ({', '.join(f'{t:.2f}' for t, _ in times[2])}); the batch itself "
          f"{inside_two:.2f} s")
    print(f"speed-up  {one / two:7.2f}× whole command, {inside_one / inside_two:.2f}× the batch after the "
          "command's own start-up (target ≥ 1.7)")
    print(f"start-up per worker process: interpreter {interpreter:.3f} s + imports {imports:.3f} s + "
          f"numba kernel load {max(kernels, 0):.3f} s = {interpreter + imports + max(kernels, 0):.3f} s")
    print(f"per scene: load + geometry + BVH {bvh * 1e3:.1f} ms, frame {frame * 1e3:.1f} ms (one thread); "
          f"median scene in the --jobs 2 batch {total * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
