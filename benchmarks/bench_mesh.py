"""Mesh preparation at millions of triangles (issue 11's Scale targets), as ratios measured in one run.

For each size a binary PLY (or an OBJ) is written by `write_surface` (a closed, bumpy torus of n × m vertices:
F = 2 n m triangles on V = F / 2 vertices, each vertex shared by 6 faces, like a scanned surface) into a
temporary folder, and a fresh subprocess per size measures, in CPU seconds of its own thread
(time.thread_time, min of --repeats; other programs on the machine barely move it):
  trimesh   trimesh.load(..., process=False) of the file: the reference the targets are ratios of
  load      geometry.object_mesh: read, check, merge duplicate vertices (what process() did)
  prepare   the rest of build_geometry: winding check, placing, face and corner normals
  BVH       Accelerator(geometry) (wall seconds: Embree builds on every core)
  frame     the whole render() at --size² pixels minus geometry and BVH (wall seconds)
  peak      VmHWM during the whole render above the process's VmRSS after imports and a warm-up render
            (the high-water mark is reset through /proc/self/clear_refs), bytes per triangle
Then it fits log(seconds) against log(triangles) per stage: a slope of 1 is linear.
Usage: python benchmarks/bench_mesh.py [--triangles 100000 1000000 2000000] [--size 1000] [--crease 30]
       [--format ply|obj] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

STAGES = ("trimesh", "load", "prepare", "BVH", "frame")


def write_surface(path: Path, triangles: int) -> int:
    """A closed bumpy torus with about `triangles` faces as a binary little-endian PLY, or as an OBJ if
    `path` ends in .obj; returns the count.

    n × m grid on the torus (n ≈ 2m), quads split in two: V = n m, F = 2 n m. The radius wobbles
    (3 × 5 bumps) so neighbouring normals differ and a crease angle has edges to split.
    """
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
    if path.suffix == ".obj":
        with open(path, "w") as out:
            np.savetxt(out, vertices, fmt="v %.7g %.7g %.7g")
            np.savetxt(out, faces["corners"] + 1, fmt="f %d %d %d")
        return len(faces)
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


def scene_for(path: Path, size: int, crease: float) -> dict:
    return {
        "render": {"width": size, "height": size, "shading": "phong"},
        "camera": {"position": [0, -4, 3], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 40},
        "lights": [{"type": "point", "position": [3, -3, 5]}],
        "materials": {"m": {"ka": 0.2, "kd": 0.7, "ks": 0.4, "shininess": 32}},
        "objects": [{"shape": "mesh", "path": str(path), "material": "m", "crease_angle": crease}],
    }


def measure(path: Path, size: int, crease: float, repeats: int) -> dict:
    """One size in this (fresh) process: the peak first, then the CPU times."""
    import trimesh

    import raycast_phong as rp
    from raycast_phong.geometry.build import build_geometry, object_mesh
    from raycast_phong.renderer.intersect import Accelerator

    scene = rp.validate_scene(scene_for(path, size, crease), source=str(path))
    rp.render(rp.validate_scene(scene_for(path, 8, crease), source="warm-up"))  # kernels compiled and loaded
    baseline = vm("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")  # VmHWM := VmRSS now
    start = time.perf_counter()
    result = rp.render(scene)
    total = time.perf_counter() - start
    peak = vm("VmHWM") - baseline
    found = {"triangles": result.triangles, "peak_bytes_per_triangle": peak / result.triangles,
             "BVH": result.timings["build"],
             "frame": total - result.timings["geometry"] - result.timings["build"]}
    del result

    from bench_geometry import best  # thread CPU seconds, min of `repeats` (this script's folder is on sys.path)

    found["trimesh"] = best(lambda: trimesh.load(str(path), process=False), repeats)
    found["load"] = best(lambda: object_mesh(scene, scene.objects[0], 0, str(path)), repeats)
    found["load+prepare"] = best(lambda: build_geometry(scene, str(path)), repeats)
    found["prepare"] = found["load+prepare"] - found["load"]
    geometry = build_geometry(scene, str(path))
    found["BVH"] = min(found["BVH"], *(_wall(lambda: Accelerator(geometry)) for _ in range(repeats)))
    return found


def _wall(step) -> float:
    start = time.perf_counter()
    step()
    return time.perf_counter() - start


def slope(xs, ys) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, nargs="+", default=[100_000, 1_000_000, 2_000_000])
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--crease", type=float, default=180.0)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--format", choices=["ply", "obj"], default="ply")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # internal: measure this file in this process
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(Path(args.one), args.size, args.crease, args.repeats)))
        return
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for count in args.triangles:
            path = Path(folder) / f"surface-{count}.{args.format}"
            write_surface(path, count)
            out = subprocess.run([sys.executable, __file__, "--one", str(path), "--size", str(args.size),
                                  "--crease", str(args.crease), "--repeats", str(args.repeats)],
                                 capture_output=True, text=True, check=True)
            rows.append(json.loads(out.stdout.splitlines()[-1]))
            path.unlink()
            row = rows[-1]
            print(f"{row['triangles']:>10,} triangles: " + ", ".join(f"{s} {row[s]:.3f} s" for s in STAGES)
                  + f"; (load+prepare)/trimesh {row['load+prepare'] / row['trimesh']:.2f}; peak "
                  f"{row['peak_bytes_per_triangle']:.0f} B/triangle", flush=True)
    if len(rows) > 1:
        counts = [r["triangles"] for r in rows]
        print("log-log slopes: " + ", ".join(f"{s} {slope(counts, [r[s] for r in rows]):.2f}"
                                             for s in (*STAGES, "load+prepare"))
              + f", peak {slope(counts, [r['peak_bytes_per_triangle'] * r['triangles'] for r in rows]):.2f}")


if __name__ == "__main__":
    main()
