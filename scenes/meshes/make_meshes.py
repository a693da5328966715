"""Make the example meshes in this folder from fixed formulas (no randomness), so they can be rebuilt.

    .venv/bin/python scenes/meshes/make_meshes.py

torus_knot.ply  a (2, 3) torus knot swept as a tube: 144 rings × 10 sides = 1,440 vertices,
                2,880 triangles, watertight; coarse enough that flat shading shows its facets.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).parent


def torus_knot_curve(t: np.ndarray, p: int = 2, q: int = 3) -> np.ndarray:
    """Points (N, 3) of the (p, q) torus knot at parameters t in [0, 2π): r = 2 + cos(q t)."""
    r = 2.0 + np.cos(q * t)
    return np.column_stack([r * np.cos(p * t), r * np.sin(p * t), -np.sin(q * t)])


def tube(curve: np.ndarray, radius: float, sides: int) -> trimesh.Trimesh:
    """A closed tube of `radius` around a closed curve (N, 3), with rotation-minimising frames.

    Frames are parallel-transported along the curve (double reflection, Wang et al. 2008); the twist
    left over where the loop closes is spread evenly over the rings, so the seam has no step.
    """
    count = len(curve)
    tangent = np.roll(curve, -1, axis=0) - np.roll(curve, 1, axis=0)  # central differences, closed loop
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    # Start from any normal perpendicular to the first tangent.
    seed = np.cross(tangent[0], [0.0, 0.0, 1.0])
    normals = np.zeros_like(curve)
    normals[0] = seed / np.linalg.norm(seed)
    for i in range(count):
        # Double reflection carries frame i to i + 1 (index count is ring 0 again, to measure the twist).
        j = (i + 1) % count
        v1 = curve[j] - curve[i]
        c1 = v1 @ v1
        r_l = normals[i] - (2 / c1) * (v1 @ normals[i]) * v1
        t_l = tangent[i] - (2 / c1) * (v1 @ tangent[i]) * v1
        v2 = tangent[j] - t_l
        c2 = v2 @ v2
        transported = r_l - (2 / c2) * (v2 @ r_l) * v2
        if j == 0:
            closing = transported
        else:
            normals[j] = transported
    # Angle between the transported normal and ring 0's: undo it a little on every ring.
    binormal0 = np.cross(tangent[0], normals[0])
    twist = np.arctan2(closing @ binormal0, closing @ normals[0])
    angles = -twist * np.arange(count) / count
    binormals = np.cross(tangent, normals)
    normals, binormals = (np.cos(angles)[:, None] * normals + np.sin(angles)[:, None] * binormals,
                          -np.sin(angles)[:, None] * normals + np.cos(angles)[:, None] * binormals)

    around = 2 * np.pi * np.arange(sides) / sides
    offsets = (np.cos(around)[None, :, None] * normals[:, None, :]
               + np.sin(around)[None, :, None] * binormals[:, None, :])
    vertices = (curve[:, None, :] + radius * offsets).reshape(-1, 3)
    ring, side = np.meshgrid(np.arange(count), np.arange(sides), indexing="ij")
    a = (ring * sides + side).ravel()
    b = (((ring + 1) % count) * sides + side).ravel()
    c = (((ring + 1) % count) * sides + (side + 1) % sides).ravel()
    d = (ring * sides + (side + 1) % sides).ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if mesh.volume < 0:  # wind the faces so the normals point out of the tube
        mesh.invert()
    return mesh


def main() -> None:
    t = 2 * np.pi * np.arange(144) / 144
    knot = tube(torus_knot_curve(t), radius=0.45, sides=10)
    assert knot.is_watertight and knot.volume > 0
    knot.export(HERE / "torus_knot.ply")
    print(f"torus_knot.ply: {len(knot.vertices)} vertices, {len(knot.faces)} faces")


if __name__ == "__main__":
    main()
