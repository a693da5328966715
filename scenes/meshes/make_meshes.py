"""Make the example meshes in this folder from fixed formulas (no randomness), so they can be rebuilt.

    .venv/bin/python scenes/meshes/make_meshes.py

torus_knot.ply  a (2, 3) torus knot swept as a tube: 144 rings × 10 sides = 1,440 vertices,
                2,880 triangles, watertight; coarse enough that flat shading shows its facets. It stores the
                tube's exact vertex normals (nx, ny, nz): its sides meet at 36°, beyond the 30° crease that
                a file without normals gets, and the knot is a smooth surface.
painted_knot.ply  the same knot with a colour per vertex, a hue wheel once round the curve (binary PLY,
                red/green/blue/alpha properties): vertex colours as k_d and k_a (docs/meshes.md).
dice.obj, dice.mtl  a cube of 12 triangles with one normal per face (`vn`) and three materials, one per pair
                of opposite faces: `red` (illum 2, Phong), `green` (illum 1, no specular term) and `blue`
                (illum 2, Ka 0 and a small Ke): several materials per mesh and normals from the file.
still_life.glb  a glTF 2.0 binary: a gold metallic sphere (metallic 1, roughness 0.3), a red plastic box
                (metallic 0, roughness 0.6) and a grey plane, placed by node transforms, with normals.

Every file here is written by this script from fixed formulas; none comes from elsewhere (public domain).
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
    # The tube's own normals (unit, outward from the curve), stored in the file: 10 sides meet at 36°, more
    # than the 30° at which a file without normals is creased, so without them the knot would be faceted.
    mesh.vertex_normals = offsets.reshape(-1, 3)
    return mesh


DICE_MTL = """# dice.mtl: three materials for dice.obj (raycast-phong's scenes/meshes/make_meshes.py)
newmtl red
Ka 0.2 0.05 0.05
Kd 0.8 0.1 0.1
Ks 0.5 0.5 0.5
Ns 40
illum 2

newmtl green
Ka 0.05 0.2 0.05
Kd 0.1 0.7 0.2
Ks 0.9 0.9 0.9
Ns 10
illum 1

newmtl blue
Ka 0 0 0
Kd 0.1 0.2 0.9
Ks 0.3 0.3 0.3
Ke 0.05 0.05 0.1
Ns 80
illum 2
"""


def dice_obj() -> str:
    """A unit cube, two triangles per side, one `vn` per side, the sides ±x red, ±y green, ±z blue."""
    corners = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    lines = ["# dice.obj: a cube with three materials and face normals (make_meshes.py)", "mtllib dice.mtl",
             "o dice"]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in corners]
    sides = []  # (material, normal, four corners counter-clockwise seen from outside)
    for axis, material in enumerate(("red", "green", "blue")):
        for sign in (1, -1):
            normal = [0, 0, 0]
            normal[axis] = sign
            ring = [i for i, c in enumerate(corners) if c[axis] == sign * 0.5]
            centre = np.mean([corners[i] for i in ring], axis=0)
            # Order the four corners by angle round the side's normal, counter-clockwise seen from outside.
            u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
            ring.sort(key=lambda i: sign * np.arctan2((np.subtract(corners[i], centre)) @ v,
                                                      (np.subtract(corners[i], centre)) @ u))
            sides.append((material, normal, ring))
    lines += [f"vn {n[0]} {n[1]} {n[2]}" for _, n, _ in sides]
    for material in ("red", "green", "blue"):
        lines.append(f"usemtl {material}")
        for k, (name, _, ring) in enumerate(sides):
            if name == material:
                a, b, c, d = (i + 1 for i in ring)
                lines += [f"f {a}//{k + 1} {b}//{k + 1} {c}//{k + 1}", f"f {a}//{k + 1} {c}//{k + 1} {d}//{k + 1}"]
    return "\n".join(lines) + "\n"


def painted(knot: trimesh.Trimesh, rings: int, sides: int) -> trimesh.Trimesh:
    """The knot with a hue wheel along the curve: ring i gets hue i / rings, full saturation and value."""
    hue = np.repeat(np.arange(rings) / rings, sides)
    rgb = np.clip(np.abs(((hue[:, None] * 6 + np.array([0, 4, 2])) % 6) - 3) - 1, 0, 1)  # HSV → RGB, S = V = 1
    colours = np.column_stack([np.round(255 * rgb), np.full(len(rgb), 255)]).astype(np.uint8)
    mesh = trimesh.Trimesh(knot.vertices, knot.faces, vertex_colors=colours, process=False)
    mesh.vertex_normals = knot.vertex_normals
    return mesh


def still_life() -> trimesh.Scene:
    """Three parts with glTF metallic-roughness materials, placed by node transforms."""
    pbr = trimesh.visual.material.PBRMaterial
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.6)
    sphere.visual = trimesh.visual.TextureVisuals(material=pbr(name="gold", baseColorFactor=[255, 196, 77, 255],
                                                               metallicFactor=1.0, roughnessFactor=0.3))
    box = trimesh.creation.box(extents=[0.8, 0.8, 0.8])
    box.visual = trimesh.visual.TextureVisuals(material=pbr(name="red_plastic", baseColorFactor=[204, 38, 31, 255],
                                                            metallicFactor=0.0, roughnessFactor=0.6))
    floor = trimesh.creation.box(extents=[3.2, 0.05, 2.0])
    floor.visual = trimesh.visual.TextureVisuals(material=pbr(name="grey", baseColorFactor=[160, 160, 160, 255],
                                                              metallicFactor=0.0, roughnessFactor=0.9))
    scene = trimesh.Scene()
    move = trimesh.transformations.translation_matrix
    scene.add_geometry(sphere, node_name="sphere", transform=move([-0.6, 0.6, 0.0]))
    scene.add_geometry(box, node_name="box", transform=move([0.75, 0.4, 0.1])
                       @ trimesh.transformations.rotation_matrix(np.radians(30), [0, 1, 0]))
    scene.add_geometry(floor, node_name="floor", transform=move([0.0, -0.025, 0.0]))
    return scene


def main() -> None:
    t = 2 * np.pi * np.arange(144) / 144
    knot = tube(torus_knot_curve(t), radius=0.45, sides=10)
    assert knot.is_watertight and knot.volume > 0
    knot.export(HERE / "torus_knot.ply", vertex_normal=True)
    print(f"torus_knot.ply: {len(knot.vertices)} vertices, {len(knot.faces)} faces")
    painted(knot, 144, 10).export(HERE / "painted_knot.ply", vertex_normal=True)
    (HERE / "dice.mtl").write_text(DICE_MTL, encoding="utf-8")
    (HERE / "dice.obj").write_text(dice_obj(), encoding="utf-8")
    still_life().export(HERE / "still_life.glb", include_normals=True)
    print("painted_knot.ply, dice.obj + dice.mtl, still_life.glb")


if __name__ == "__main__":
    main()
