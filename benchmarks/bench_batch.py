"""A batch of 20 scenes with --jobs 1 against --jobs 2 (issue 6's speed target: ≥ 1.7× on 2 cores), and the
start-up a batch pays before its first scene.

Workloads (--workloads, default all three), 20 scenes each (--scenes), every file different by a comment so
every one renders:
  tiny      an icosphere of 5,120 triangles at 128×128, 1 ray per pixel (≈ 20 ms of work per scene)
  small     the same at 256×256, 2×2 rays per pixel (≈ 50 ms per scene)
  examples  the shipped scenes/ (640×360 and so on, one with an 18k-triangle mesh), cycled to 20
Each batch is the whole `raycast-phong batch --force` command in a fresh process, median of --repeats. Three
figures per batch: the whole command (what `time` shows); the batch as the command reports it (after its
imports, which load no renderer); the batch after loading the renderer (its imports and numba kernels: the
command reports that part, the start-up both job counts pay once; what remains includes forking the workers
and their first scenes); and the steady state
(seconds per scene between the first and the last finished scene, from the command's progress lines).
Start-up, measured in fresh processes: interpreter, imports, numba's first dispatch, forking a worker, and
per scene load + geometry + BVH, the BVH split into embreex's copy of the mesh and Embree's build.
Usage: python benchmarks/bench_batch.py [--workloads tiny,small,examples] [--scenes 20] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SPHERE = """\
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
subdivisions = 4
material = "m"
"""

STARTUP = """
import json, sys, time
import numpy as np
started = time.perf_counter()
import raycast_phong as rp
import raycast_phong.renderer.frame  # the package's names load lazily: this is what a render imports
imported = time.perf_counter()
render = sys.modules["raycast_phong.renderer.frame"]
render.warm_kernels()
warmed = time.perf_counter()
from concurrent.futures import ProcessPoolExecutor
import multiprocessing
with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork")) as pool:
    pool.submit(int).result()
forked = time.perf_counter()
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.intersect import unit_frame
def per_scene(path):
    best = {}
    for _ in range(5):
        t0 = time.perf_counter()
        scene = rp.load_scene(path)
        t1 = time.perf_counter()
        geometry = build_geometry(scene)
        t2 = time.perf_counter()
        frame = unit_frame(geometry.vertices)
        embree = rtcore_scene.EmbreeScene(robust=True)
        TriangleMesh(embree, frame.to_unit(geometry.vertices).astype(np.float32), geometry.faces.astype(np.int32))
        t3 = time.perf_counter()
        embree.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))
        t4 = time.perf_counter()
        times = dict(load=t1 - t0, geometry=t2 - t1, copy=t3 - t2, build=t4 - t3, triangles=len(geometry.faces))
        best = {k: min(v, best.get(k, v)) for k, v in times.items()}
    return best
print(json.dumps(dict(imports=imported - started, numba=warmed - imported, fork=forked - warmed,
                      scenes={path: per_scene(path) for path in sys.argv[1:]})))
"""


def write_workload(kind: str, folder: Path, scenes: int) -> None:
    """`scenes` scene files of one workload in `folder` (with the meshes they read)."""
    folder.mkdir(parents=True)
    if kind in ("tiny", "small"):
        size, samples = (128, 1) if kind == "tiny" else (256, 2)
        for index in range(scenes):
            (folder / f"scene{index:02}.toml").write_text(SPHERE.format(index=index, size=size, samples=samples))
        return
    shutil.copytree(ROOT / "scenes" / "meshes", folder / "meshes")
    shipped = sorted(p for p in (ROOT / "scenes").glob("*.toml") if not p.is_symlink())
    for index in range(scenes):
        source = shipped[index % len(shipped)]
        (folder / f"{source.stem}{index:02}.toml").write_text(f"# copy {index}\n" + source.read_text())


def run_batch(folder: Path, out: Path, jobs: int) -> dict[str, float]:
    """One whole `batch --force` command: whole, batch (as it reports) and steady (s per scene) seconds."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "cli", "batch", str(folder), "-o", str(out), "--jobs", str(jobs),
                           "--force"], check=True, cwd=ROOT, capture_output=True, text=True)
    whole = time.perf_counter() - start
    finished = [float(t) for t in re.findall(r"^\[\d+/\d+ ([0-9.]+)s\]", done.stderr, re.M)]
    batch, kernels = map(float, re.search(r"failed in ([0-9.]+)s \(([0-9.]+)s of it loading", done.stdout).groups())
    return {"whole": whole, "batch": batch, "scenes": batch - kernels, "first": finished[0],
                "steady": (finished[-1] - finished[0]) / (len(finished) - 1)}


def median(runs: list[dict[str, float]], key: str) -> float:
    return statistics.median(run[key] for run in runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workloads", default="tiny,small,examples")
    parser.add_argument("--scenes", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    kinds = args.workloads.split(",")
    with tempfile.TemporaryDirectory() as temporary:
        temporary = Path(temporary)
        for kind in kinds:
            write_workload(kind, temporary / kind, args.scenes)
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], check=True)
        interpreter = time.perf_counter() - start
        probes = [temporary / "small" / "scene00.toml"] if "small" in kinds else []
        if "examples" in kinds:
            probes += sorted((temporary / "examples").glob("*0[0-5].toml"))
        startup = json.loads(subprocess.run([sys.executable, "-c", STARTUP, *map(str, probes)], check=True,
                                            cwd=ROOT, capture_output=True, text=True).stdout)
        runs = {}
        for kind in kinds:
            runs[kind] = {1: [], 2: []}
            for _ in range(args.repeats):
                for jobs in (1, 2):  # alternate, so a busy spell hits both
                    runs[kind][jobs].append(run_batch(temporary / kind, temporary / f"out-{kind}", jobs))

    print(f"{args.scenes} scenes per workload; median of {args.repeats} whole `batch --force` commands; "
          "speed-up = --jobs 1 / --jobs 2 (target ≥ 1.7)")
    print(f"{'workload':10} {'':7} {'whole command':>15} {'the batch':>11} {'after loading':>14} "
          f"{'first scene':>12} {'steady':>14}")
    for kind in kinds:
        for jobs in (1, 2):
            r = runs[kind][jobs]
            print(f"{kind:10} --jobs {jobs} {median(r, 'whole'):13.2f} s {median(r, 'batch'):9.2f} s "
                  f"{median(r, 'scenes'):12.2f} s {median(r, 'first'):10.2f} s {median(r, 'steady') * 1e3:9.1f} ms/sc")
        one, two = runs[kind][1], runs[kind][2]
        print(f"{kind:10} speed-up {median(one, 'whole') / median(two, 'whole'):13.2f}× "
              f"{median(one, 'batch') / median(two, 'batch'):10.2f}× "
              f"{median(one, 'scenes') / median(two, 'scenes'):13.2f}× {'':12} "
              f"{median(one, 'steady') / median(two, 'steady'):13.2f}×")
    print(f"start-up, once per command: interpreter {interpreter:.3f} s, imports "
          f"{startup['imports']:.3f} s (what a render imports), "
          f"numba's first dispatch (warm_kernels) {startup['numba']:.3f} s; "
          f"forking a warm worker {startup['fork'] * 1e3:.1f} ms")
    print("per scene (best of 5, one thread):   load  geometry  embreex copy  Embree build  triangles")
    for path, t in startup["scenes"].items():
        print(f"  {Path(path).stem:22} {t['load'] * 1e3:8.1f} {t['geometry'] * 1e3:9.1f} {t['copy'] * 1e3:13.1f} "
              f"{t['build'] * 1e3:13.1f} {t['triangles']:10,} ms")


if __name__ == "__main__":
    main()
