"""The whole render() against Open3D's ray caster plus numpy shading, in one run (issue 12's ≤ 0.4× target).

Scene: bench_frame's (icosphere of 6 subdivisions, 81,920 triangles, 1000×1000, one point light, Phong
shading and specular, --threads 2). Timed, interleaved run by run, median of --repeats:
  ours    raycast_phong.render(scene): geometry (the sphere and its vertex normals), BVH, frame;
  Open3D  RaycastingScene + add_triangles, create_rays_pinhole, cast_rays (the BVH is built at the first
          cast) and the same Phong model in numpy over the hits: the normal interpolated from the corner
          normals with the hit's barycentrics, ambient + diffuse + specular, written into an (H, W, 3) image.
Open3D is handed our mesh and corner normals for free (built beforehand, untimed), so the ratio flatters it.
Both images are compared at the end, to show the two sides do the same work.

Open3D is not a dependency: `pip install -e '.[bench]'` (or `pip install open3d-cpu`).
Usage: python benchmarks/bench_render.py [--size 1000] [--repeats 7] [--threads 2]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np
from bench_frame import benchmark_scene

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry

try:
    import open3d as o3d
except ImportError:
    sys.exit("bench_render needs Open3D, which raycast-phong does not depend on: pip install -e '.[bench]' "
             "(or pip install open3d-cpu)")


class Open3DRender:
    """Open3D's build + cast and numpy Phong shading of one scene of one material and one point light."""

    def __init__(self, scene: rp.Scene):
        geometry = build_geometry(scene)  # the mesh and its normals, given to Open3D untimed
        self.vertices = np.ascontiguousarray(geometry.vertices, np.float32)
        self.faces = np.ascontiguousarray(geometry.faces, np.uint32)
        self.corner_normals = geometry.corner_normals.astype(np.float32)
        self.scene = scene
        (self.material,) = scene.materials.values()
        (self.light,) = scene.lights

    def __call__(self, threads: int) -> tuple[np.ndarray, float, float]:
        """(image (H, W, 3) float32 linear, seconds of build + cast, seconds of shading)."""
        scene, camera = self.scene, self.scene.camera
        width, height = scene.render.width, scene.render.height
        start = time.perf_counter()
        caster = o3d.t.geometry.RaycastingScene(nthreads=threads)
        caster.add_triangles(o3d.core.Tensor(self.vertices), o3d.core.Tensor(self.faces))
        # Open3D's fov is horizontal, ours vertical: the same for a square image. Its image y runs against its up
        # vector: give it ours reversed, and its pixel (row, column) is ours.
        rays = caster.create_rays_pinhole(fov_deg=camera.fov, center=list(camera.look_at), eye=list(camera.position),
                                          up=[-c for c in camera.up], width_px=width, height_px=height)
        found = caster.cast_rays(rays, nthreads=threads)
        cast = time.perf_counter() - start
        start = time.perf_counter()
        image = self.shade(rays.numpy().reshape(-1, 6), found["t_hit"].numpy().ravel(),
                           found["primitive_ids"].numpy().ravel(), found["primitive_uvs"].numpy().reshape(-1, 2))
        return image.reshape(height, width, 3), cast, time.perf_counter() - start

    def shade(self, rays, t, face, uv) -> np.ndarray:
        """I = I_a k_a + I_a,light k_a + I_d k_d max(n·l, 0) + I_s k_s max(r·v, 0)^f (0 where n·l ≤ 0) per hit."""
        m, light = self.material, self.light
        image = np.empty((len(t), 3), np.float32)
        image[:] = self.scene.render.background
        hit = np.flatnonzero(np.isfinite(t))
        face, u, v = face[hit], uv[hit, 0:1], uv[hit, 1:2]
        corners = self.corner_normals[face]
        normal = (1 - u - v) * corners[:, 0] + u * corners[:, 1] + v * corners[:, 2]
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        origin, direction = rays[hit, :3], rays[hit, 3:]
        point = origin + t[hit, None] * direction  # t is in units of the (not unit) direction
        to_light = np.asarray(light.position, np.float32) - point
        to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
        to_viewer = -direction / np.linalg.norm(direction, axis=1, keepdims=True)
        n_dot_l = np.einsum("ij,ij->i", normal, to_light)[:, None]
        reflected = 2 * n_dot_l * normal - to_light
        r_dot_v = np.maximum(np.einsum("ij,ij->i", reflected, to_viewer), 0)[:, None]
        specular = np.where(n_dot_l > 0, r_dot_v ** m.shininess, 0)
        ambient = np.asarray(m.ka) * (np.asarray(self.scene.ambient) + np.asarray(light.ambient))
        image[hit] = (ambient + np.asarray(light.diffuse) * np.asarray(m.kd) * np.maximum(n_dot_l, 0)
                      + np.asarray(light.specular) * np.asarray(m.ks) * specular)
        return image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    scene = benchmark_scene(args.size)
    theirs = Open3DRender(scene)
    rp.render(benchmark_scene(64), threads=args.threads)  # compile or load the kernels first
    theirs(args.threads)  # and Open3D's own first-call set-up
    ours_s, splits, open3d_s, casts, shades = [], [], [], [], []
    for _ in range(args.repeats):
        start = time.perf_counter()
        result = rp.render(scene, threads=args.threads)
        ours_s.append(time.perf_counter() - start)
        splits.append(result.timings)
        start = time.perf_counter()
        image, cast, shade = theirs(args.threads)
        open3d_s.append(time.perf_counter() - start)
        casts.append(cast)
        shades.append(shade)
    ours, open3d = statistics.median(ours_s), statistics.median(open3d_s)
    split = ", ".join(f"{key} {statistics.median(s[key] for s in splits) * 1e3:.1f} ms"
                      for key in ("geometry", "build", "frame"))
    difference = np.abs(result.image.astype(np.float64) - image)
    print(f"{args.size}×{args.size}, {result.triangles:,} triangles, {args.threads} threads, median of {args.repeats}, "
          f"Open3D {o3d.__version__}")
    print(f"ours     {ours * 1e3:7.1f} ms  ({split})")
    print(f"Open3D   {open3d * 1e3:7.1f} ms  (build + cast {statistics.median(casts) * 1e3:.1f} ms, numpy shading "
          f"{statistics.median(shades) * 1e3:.1f} ms)")
    print(f"ratio    {ours / open3d:7.2f}     (ours / Open3D; target ≤ 0.4)")
    print(f"images   |ours − Open3D's| mean {difference.mean():.1e}, max {difference.max():.1e} (linear RGB; float32 "
          "rounding: the same rays, hits and model)")


if __name__ == "__main__":
    main()
