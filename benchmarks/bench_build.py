"""BVH build: our Accelerator against Embree's own rtcCommitScene on the same prepared arrays (issue 12).

  embree       rtcCommitScene alone, on the unit-frame float32 vertices and int32 faces already shared with a
               fresh scene (what Embree itself needs; the floor for any binding)
  accelerator  unit_frame + Accelerator(geometry, frame): everything render() times as "build" (the float64 →
               unit frame → float32 conversion, device, scene, shared buffers, commit)
  embreex      the same through embreex's TriangleMesh (the fallback, and the path before issue 12)
at 82k triangles (icosphere, 6 subdivisions) and 2M (a 1000 × 1000 grid, rippled so the BVH has depth).
Wall time (Embree builds on its own thread pool), min of --repeats. Target: accelerator ≤ 1.5 × embree.
Usage: python benchmarks/bench_build.py [--repeats 5] [--skip-embreex]
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

import numpy as np

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer import embree_library as embree
from raycast_phong.renderer.intersect import Accelerator, unit_frame
from raycast_phong.shapes import plane_mesh


def meshes() -> dict[str, SimpleNamespace]:
    sphere = build_geometry(rp.validate_scene({"objects": [{"shape": "icosphere", "subdivisions": 6}]},
                                              source="benchmark"), vertex_normals=False)
    vertices, faces = plane_mesh((2.0, 2.0), (1000, 1000))
    vertices[:, 1] = 0.1 * np.sin(9 * vertices[:, 0]) * np.cos(7 * vertices[:, 2])
    return {"82k icosphere": SimpleNamespace(vertices=sphere.vertices, faces=sphere.faces),
            "2M grid": SimpleNamespace(vertices=vertices, faces=np.ascontiguousarray(faces, np.int32))}


def embree_commit_seconds(lib: embree.Library, geometry) -> float:
    """rtcCommitScene alone, the scene's shared buffers prepared beforehand (as EmbreeScene prepares them)."""
    frame = unit_frame(geometry.vertices)
    padded = np.zeros(geometry.vertices.size + 1, np.float32)
    padded[:-1] = frame.to_unit(geometry.vertices).reshape(-1)
    faces = np.ascontiguousarray(geometry.faces, np.int32)
    device = lib.rtcNewDevice(None)
    scene = lib.rtcNewScene(device)
    lib.rtcSetSceneFlags(scene, embree.RTC_SCENE_FLAG_ROBUST)
    mesh = lib.rtcNewGeometry(device, embree.RTC_GEOMETRY_TYPE_TRIANGLE)
    lib.rtcSetSharedGeometryBuffer(mesh, embree.RTC_BUFFER_TYPE_VERTEX, 0, embree.RTC_FORMAT_FLOAT3,
                                   padded.ctypes.data, 0, 12, len(geometry.vertices))
    lib.rtcSetSharedGeometryBuffer(mesh, embree.RTC_BUFFER_TYPE_INDEX, 0, embree.RTC_FORMAT_UINT3,
                                   faces.ctypes.data, 0, 12, len(faces))
    lib.rtcCommitGeometry(mesh)
    lib.rtcAttachGeometry(scene, mesh)
    lib.rtcReleaseGeometry(mesh)
    start = time.perf_counter()
    lib.rtcCommitScene(scene)
    seconds = time.perf_counter() - start
    embree.device_error(lib, device, "building the benchmark's BVH")
    lib.rtcReleaseScene(scene)
    lib.rtcReleaseDevice(device)
    return seconds


def accelerator_seconds(geometry) -> float:
    start = time.perf_counter()
    Accelerator(geometry, unit_frame(geometry.vertices))
    return time.perf_counter() - start


def embreex_seconds(geometry) -> float:
    """embreex's TriangleMesh and first query (its commit) on the same unit-frame mesh (the renderer no
    longer uses embreex; this is a yardstick)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    start = time.perf_counter()
    scene = rtcore_scene.EmbreeScene(robust=True)
    TriangleMesh(scene, unit_frame(geometry.vertices).to_unit(geometry.vertices).astype(np.float32),
                 np.ascontiguousarray(geometry.faces, np.int32))
    scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--skip-embreex", action="store_true", help="do not time embreex's TriangleMesh")
    args = parser.parse_args()
    lib = embree.library()
    for name, geometry in meshes().items():
        times = {"embree": [], "accelerator": [], "embreex": []}
        for _ in range(args.repeats):  # interleaved, so a busy moment hits all three alike
            times["embree"].append(embree_commit_seconds(lib, geometry))
            times["accelerator"].append(accelerator_seconds(geometry))
            if not args.skip_embreex:
                times["embreex"].append(embreex_seconds(geometry))
        best = {key: min(value) for key, value in times.items() if value}
        print(f"{name} ({len(geometry.faces):,} triangles), min of {args.repeats}: " + ", ".join(
            f"{key} {seconds * 1e3:.1f} ms" for key, seconds in best.items()))
        print(f"  accelerator / embree {best['accelerator'] / best['embree']:.2f} (target ≤ 1.5)"
              + (f", embreex / embree {best['embreex'] / best['embree']:.2f}" if "embreex" in best else ""))


if __name__ == "__main__":
    main()
