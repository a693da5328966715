"""Mesh preparation on real scans, against trimesh's raw load of the same file (issue 22), in one run.

For each scan of make_scans.py (public scans subdivided to millions of triangles: bunny-1m, bunny-4m,
beast-2m) in each format (binary PLY, binary STL, GLB, OBJ), a fresh subprocess measures:
  trimesh     trimesh.load(path, process=False): the raw parse, the reference of the ratio
  geometry    build_geometry of a scene holding the file: read (io/meshes/read.py), merge repeated points,
              winding check (and repair), placing, face and corner normals — load + geometry; with the corner
              normals in float32, as render() asks for them (it shades in float32); wall, and CPU of the
              process (all its threads: a large mesh's preparation runs on --threads threads)
  read        geometry.object_mesh alone (read, checks, merge): the part of `geometry` that is reading
  peak        VmHWM during one build_geometry above the process's VmRSS after imports and a warm-up render
              of the same file (the high-water mark reset through /proc/self/clear_refs), bytes per triangle
  render peak the same during a whole render() at --size² pixels (geometry, BVH, frame; 0: skipped)
  render      that whole render() of the file on 2 threads (read included), wall
  open3d      Open3D (the `bench` extra) on the same file and the same --size² rays: read_triangle_mesh,
              compute_vertex_normals, RaycastingScene.add_triangles (its BVH), cast_rays, 2 threads, wall
Times are wall seconds, the minimum of --repeats (the first call of a kernel loads it from numba's cache;
the warm-up pays that). On a virtual machine the first touch of memory the guest has handed back to the
host costs ~5 ms/MB (measured here), so a single cold run mostly measures allocation; the minimum measures the work.
--torus N adds the synthetic bumpy torus of N triangles (binary PLY) of the earlier rounds.
Every line carries the CPU (model and its widest SIMD) and the load average. Targets: geometry/trimesh ≤ 3, peak
≤ 300 B/triangle, render/Open3D ≤ 0.5.
--before PATH measures another source tree too, file by file (its line first), for a before/after table.
--threads N: the render's and the preparation's threads (default 2).
Usage: python benchmarks/bench_mesh.py [--scan bunny-1m bunny-4m] [--formats ply stl glb obj] [--repeats 3]
       [--size 1000] [--torus 1000000 ...] [--threads 2] [--before PATH]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

TARGET_RATIO, TARGET_PEAK, TARGET_OPEN3D = 3.0, 300.0, 0.5
ROOT = Path(__file__).resolve().parents[1]


def cpu() -> str:
    """The CPU model and the widest vector ISA it reports (what Embree and LLVM can pick), e.g. "AMD EPYC, AVX-512"."""
    text = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    model = next((line.split(":", 1)[1].strip() for line in text.splitlines() if line.startswith("model name")), "?")
    flags = next((set(line.split(":", 1)[1].split()) for line in text.splitlines() if line.startswith("flags")), set())
    isa = ("AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "AVX" if "avx" in flags
           else "SSE4.2" if "sse4_2" in flags else "?")
    return f"{model}, {isa}, {len([ln for ln in text.splitlines() if ln.startswith('processor')])} cores"


def write_torus(path: Path, triangles: int) -> int:
    """A closed bumpy torus of about `triangles` faces as a binary little-endian PLY; returns the count.
    n × m grid, quads split in two (V = n m, F = 2 n m); the radius wobbles so neighbouring normals differ."""
    m = max(3, round(math.sqrt(triangles / 4)))
    n = max(3, round(triangles / (2 * m)))
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n, endpoint=False),
                       np.linspace(0, 2 * np.pi, m, endpoint=False), indexing="ij")
    tube = 0.5 + 0.05 * np.sin(3 * u) * np.cos(5 * v)
    ring = 1.5 + tube * np.cos(v)
    vertices = np.column_stack([(ring * np.cos(u)).ravel(), (ring * np.sin(u)).ravel(),
                                (tube * np.sin(v)).ravel()]).astype("<f4")
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    a = (i * m + j).ravel()
    b = (((i + 1) % n) * m + j).ravel()
    c = (((i + 1) % n) * m + (j + 1) % m).ravel()
    d = (i * m + (j + 1) % m).ravel()
    record = np.dtype([("count", "u1"), ("corners", "<i4", (3,))])
    faces = np.empty(2 * len(a), record)
    faces["count"] = 3
    faces["corners"][0::2] = np.column_stack([a, b, c])  # counter-clockwise seen from outside: outward
    faces["corners"][1::2] = np.column_stack([a, c, d])
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(vertices.tobytes())
        out.write(faces.tobytes())
    return len(faces)


def vm(field: str) -> int:
    """VmRSS or VmHWM of this process, bytes."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    raise KeyError(field)


def scene_for(path: Path, size: int) -> dict:
    return {
        "render": {"width": size, "height": size, "shading": "phong"},
        "camera": {"position": [0, -4, 3], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 40},
        "lights": [{"type": "point", "position": [3, -3, 5]}],
        "objects": [{"shape": "mesh", "path": str(path)}],
    }


def best(step, repeats: int, clock=time.perf_counter) -> float:
    """The least time of `repeats` calls of step() (its result dropped before the next) on `clock` (wall, or
    time.process_time: the CPU of every thread)."""
    times = []
    for _ in range(repeats):
        start = clock()
        step()
        times.append(clock() - start)
    return min(times)


def prep_threads(threads: int):
    """The preparation's thread bound (normals.prep_threads) where the tree has it; a tree from before it: none."""
    try:
        from raycast_phong.geometry.normals import prep_threads as bound
    except ImportError:
        import contextlib
        return contextlib.nullcontext()
    return bound(threads)


def open3d_cast(path: Path, size: int, repeats: int) -> float:
    """Least wall seconds of Open3D reading `path`, computing its vertex normals, building its BVH and casting
    the size² rays of scene_for's camera (NaN without Open3D: pip install -e '.[bench]')."""
    try:
        import open3d as o3d
    except ImportError:
        return math.nan
    camera = scene_for(path, size)["camera"]

    def cast() -> None:
        mesh = o3d.io.read_triangle_mesh(str(path))
        mesh.compute_vertex_normals()
        caster = o3d.t.geometry.RaycastingScene(nthreads=2)
        caster.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                             o3d.core.Tensor(np.asarray(mesh.triangles, np.uint32)))
        # Open3D's fov is horizontal, ours vertical: the same for a square image.
        rays = caster.create_rays_pinhole(fov_deg=camera["fov"], center=camera["look_at"], eye=camera["position"],
                                          up=[-c for c in camera["up"]], width_px=size, height_px=size)
        caster.cast_rays(rays, nthreads=2)["t_hit"].numpy()
    cast()  # Open3D's own first-call set-up
    return best(cast, repeats)


def measure(path: Path, repeats: int, size: int, threads: int = 2) -> dict:
    """One file in this (fresh) process: the peaks first (after a warm-up), then the times."""
    import trimesh

    import raycast_phong as rp
    from raycast_phong.geometry.build import build_geometry
    from raycast_phong.geometry.templates import object_mesh

    scene = rp.validate_scene(scene_for(path, 8), source=str(path))
    triangles = rp.render(scene).triangles  # warm-up: kernels loaded, trimesh's lazy imports done
    baseline = vm("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")  # VmHWM := VmRSS now
    geometry = build_geometry(scene, normal_dtype=np.float32)
    found = {"file": path.name, "triangles": triangles, "peak_bytes_per_triangle": (vm("VmHWM") - baseline) / triangles}
    del geometry
    if size:
        baseline = vm("VmRSS")
        Path("/proc/self/clear_refs").write_text("5")
        rp.render(rp.validate_scene(scene_for(path, size), source=str(path)))
        found["render_peak_bytes_per_triangle"] = (vm("VmHWM") - baseline) / triangles
    if size:
        # The whole render of the file (read, preparation, BVH, frame) against Open3D's read + vertex normals +
        # BVH + first cast of the same file and the same size² rays (its RaycastingScene, 2 threads each).
        found["render"] = best(lambda: rp.render(rp.validate_scene(scene_for(path, size), source=str(path)),
                                                 threads=threads), repeats)
        found["open3d"] = open3d_cast(path, size, repeats)
    found["trimesh"] = best(lambda: trimesh.load(str(path), process=False), repeats)
    with prep_threads(threads):
        found["geometry"] = best(lambda: build_geometry(scene, normal_dtype=np.float32), repeats)
        found["geometry_cpu"] = best(lambda: build_geometry(scene, normal_dtype=np.float32), repeats,
                                     time.process_time)
    found["read"] = best(lambda: object_mesh(scene, 0), repeats)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scan", nargs="*", default=["bunny-1m", "bunny-4m"])
    parser.add_argument("--formats", nargs="+", default=["ply", "stl", "glb", "obj"])
    parser.add_argument("--torus", type=int, nargs="*", default=[])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--size", type=int, default=1000, help="pixels a side of the render-peak render; 0: none")
    parser.add_argument("--threads", type=int, default=2, help="the render's and the preparation's threads")
    parser.add_argument("--before", type=Path, help="another source tree (git archive REV | tar -x -C PATH) measured "
                        "the same way, file by file before this one")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # internal: measure this file in this process
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(Path(args.one), args.repeats, args.size, args.threads)))
        return
    from make_scans import scan  # this script's folder is on sys.path

    where = cpu()
    print(f"CPU: {where}; targets: geometry/trimesh ≤ {TARGET_RATIO:g}, peak ≤ {TARGET_PEAK:g} B/triangle, "
          f"render/Open3D ≤ {TARGET_OPEN3D:g}", flush=True)
    with tempfile.TemporaryDirectory() as folder:
        files = [scan(name, fmt) for name in args.scan for fmt in args.formats]
        for count in args.torus:
            files.append(Path(folder) / f"torus-{count}.ply")
            write_torus(files[-1], count)
        met = True
        trees = {"": ROOT} if args.before is None else {"before ": args.before.resolve(), "after  ": ROOT}
        for path, (label, tree) in ((path, tree) for path in files for tree in trees.items()):
            # The tree's package first on the path (an editable install's finder comes after PYTHONPATH).
            out = subprocess.run([sys.executable, __file__, "--one", str(path), "--repeats", str(args.repeats),
                                  "--size", str(args.size), "--threads", str(args.threads)],
                                 env={**os.environ, "PYTHONPATH": str(tree)}, capture_output=True, text=True)
            if out.returncode:
                print(f"{label}{path.name}: failed: {out.stderr.strip().splitlines()[-1:]}", flush=True)
                met = False
                continue
            row = json.loads(out.stdout.splitlines()[-1])
            if label == "before ":
                print(f"{label}{path.name}: trimesh {row['trimesh']:.3f} s, geometry {row['geometry']:.3f} s "
                      f"(CPU {row['geometry_cpu']:.3f} s), "
                      f"geometry/trimesh {row['geometry'] / row['trimesh']:.2f}, peak "
                      f"{row['peak_bytes_per_triangle']:.0f} B/triangle (render "
                      f"{row.get('render_peak_bytes_per_triangle', math.nan):.0f}); render "
                      f"{row.get('render', math.nan):.3f} s / Open3D {row.get('open3d', math.nan):.3f} s = "
                      f"{row.get('render', math.nan) / row.get('open3d', math.nan):.2f}", flush=True)
                continue
            ratio = row["geometry"] / row["trimesh"]
            versus = row.get("render", math.nan) / row.get("open3d", math.nan)
            met &= (ratio <= TARGET_RATIO and row["peak_bytes_per_triangle"] <= TARGET_PEAK
                    and not versus > TARGET_OPEN3D)
            print(f"{label}{row['file']:>16} {row['triangles']:>10,} triangles: trimesh {row['trimesh']:.3f} s, "
                  f"geometry {row['geometry']:.3f} s (CPU {row['geometry_cpu']:.3f} s, read {row['read']:.3f} s), "
                  f"geometry/trimesh {ratio:.2f}, "
                  f"peak {row['peak_bytes_per_triangle']:.0f} B/triangle (render "
                  f"{row.get('render_peak_bytes_per_triangle', math.nan):.0f}); render "
                  f"{row.get('render', math.nan):.3f} s / Open3D {row.get('open3d', math.nan):.3f} s = "
                  f"{versus:.2f}  [{where}; load {os.getloadavg()[0]:.1f}]", flush=True)
    print("targets met" if met else "targets NOT met")


if __name__ == "__main__":
    main()
