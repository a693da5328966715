"""The specular scene (three unit spheres, shininess 8, 64, 512) against the analytic reference, pixel by pixel.

reference.py shades the exact spheres in float64; the renderer shades 4-times-subdivided icospheres. The
difference is the tessellation's, and it is bounded from the mesh itself (no measured fudge):
- the mesh hit lies on the same ray as the exact one, between the inscribed sphere (r_in, the nearest face
  plane) and the true one, so |Δp| ≤ (r − r_in) / (n·v);
- the Phong normal is the mix of the corner normals renormalised; each corner normal is within ε_v of its
  vertex's radial direction, and a mix of radial directions at the mesh point is the radial direction there,
  so the normal turns by |Δn| ≤ ε_v + |Δp| / r_in (angles, radians);
- l and v turn by |Δp| over their distance: |Δl| ≤ |Δp| / (|light − centre| − r), |Δv| ≤ |Δp| / (|eye − centre| − r);
- diffuse: k_d I_d max(n·l, 0) moves by ≤ k_d I_d (|Δn| + |Δl|); ambient does not move;
- specular: x = r·v with r = 2(n·l)n − l moves by |Δx| ≤ 3|Δn| + 3|Δl| + |Δv| (each unit vector's turn
  counted where it enters), and k_s I_s x^f by ≤ k_s I_s f · min(1, x + |Δx|)^(f−1) · |Δx| (x^f is convex
  and increasing on [0, 1]), with x read back from the reference's own specular term.
Only pixels whose ray meets the sphere at n·v ≥ 0.5 are compared (a silhouette pixel may see the mesh or
not); the image is rendered in float64, so rounding is far below these bounds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import pixel_centre_rays

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.pack import camera_rig
from raycast_phong.tools.reference import analytic_reference

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "specular.toml"
CENTRES = np.array([[-2.4, 0, 0], [0, 0, 0], [2.4, 0, 0]])
SHININESS = (8, 64, 512)
KD, KS, ID, IS = 0.8, 0.8, 0.8, 1.0  # the largest k_d channel, k_s, the light's I_d and I_s (scenes/specular.toml)
LIGHT = np.array([-4.0, 5.0, 8.0])


def specular_scene():
    return rp.load_scene(SCENE, ["render.width=128", "render.height=48", "render.precision=float64",
                                 "render.shading=phong", "output.path=x.exr",
                                 'output.aovs=["ambient", "diffuse", "specular"]'])


def pixel_geometry(scene):
    """Per pixel: which sphere the centre ray meets (−1: none or at n·v < 0.5) and n·v there."""
    rig = camera_rig(scene)
    w, h = scene.render.width, scene.render.height
    _, d = pixel_centre_rays(rig, w, h)
    which, n_dot_v = np.full((h, w), -1), np.zeros((h, w))
    for index, centre in enumerate(CENTRES):
        oc = rig.eye - centre
        b = d @ oc
        disc = b * b - (oc @ oc - 1)
        t = -b - np.sqrt(np.maximum(disc, 0))
        cosine = np.einsum("...i,...i", rig.eye + t[..., None] * d - centre, -d)
        take = (disc > 0) & (cosine >= 0.5)
        which[take], n_dot_v[take] = index, cosine[take]
    return which, n_dot_v


def tessellation_bounds(scene) -> tuple[float, float]:
    """r − r_in and ε_v of the unit icosphere the scene uses (all three are the same mesh, translated)."""
    geometry = build_geometry(scene)
    first = geometry.face_object == 0
    faces, centre = geometry.faces[first], CENTRES[0]
    r_in = np.min(np.einsum("ij,ij->i", geometry.vertices[faces[:, 0]] - centre, geometry.face_normals[first]))
    radial = geometry.vertices[faces] - centre
    radial /= np.linalg.norm(radial, axis=-1, keepdims=True)
    cosine = np.clip(np.einsum("ijk,ijk->ij", radial, geometry.corner_normals[first]), -1, 1)
    return 1 - r_in, float(np.arccos(cosine).max())


def test_phong_render_is_within_the_tessellation_bound_of_the_exact_spheres():
    scene = specular_scene()
    result = rp.render(scene)
    exact = analytic_reference(scene)
    which, n_dot_v = pixel_geometry(scene)
    gap, vertex_error = tessellation_bounds(scene)
    inside = which >= 0
    assert inside.sum() > 300

    dp = gap / n_dot_v[inside]
    dn = vertex_error + dp / (1 - gap)
    dl = dp / (np.linalg.norm(LIGHT - CENTRES, axis=1).min() - 1)
    dv = dp / (10 - 2.4 - 1)  # the eye is 10 in front of the middle sphere; the outer ones are nearer the axis
    # Ambient + diffuse.
    rendered = result.aovs["ambient"] + result.aovs["diffuse"]
    exact_rest = exact.image - exact.specular
    bound = KD * ID * (dn + dl)
    error = np.abs(rendered - exact_rest)[inside].max(axis=1)
    assert (error <= bound).all(), f"diffuse off by {error.max():.3g}, bound {bound[np.argmax(error)]:.3g}"
    # Specular, by the exponent of each pixel's sphere.
    f = np.asarray(SHININESS)[which[inside]]
    x = (exact.specular[inside][:, 0] / (KS * IS)) ** (1.0 / f)
    dx = 3 * dn + 3 * dl + dv
    bound = KS * IS * f * np.minimum(1, x + dx) ** (f - 1) * dx
    error = np.abs(result.aovs["specular"] - exact.specular)[inside].max(axis=1)
    assert (error <= bound).all(), f"specular off by {error.max():.3g}, bound {bound[np.argmax(error)]:.3g}"
    # The bound is tight enough to mean something: k_d 5 % off moves the diffuse term by 0.05 · 0.8 · I_d · n·l,
    # over 0.01 wherever n·l > 0.4, while the bound is under 0.01 on most pixels.
    assert np.median(KD * ID * (dn + dl)) < 0.01
