"""Named tolerances of the test suite, each with its reason (after trimesh's `constants.tol`).

Loosen one only with a comment that says what was measured and why it is still strict enough.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ImageTolerance:
    """How far a render may stray from its reference image and still count as the same picture.

    Every pixel is bounded, not only counted: a pixel off an edge may differ by at most `pixel`; a pixel
    on an edge (a silhouette, a flat facet's edge, a crease, a shadow's edge: test_reference_images.
    edge_pixels) may differ by more only within the range of the reference's 3×3 neighbourhood, ± `pixel`,
    and only `share` of the pixels may. Reason: the one legitimate way for a pixel to move more than
    rounding is that its ray lands on the other side of an edge (below), and then it takes a value the
    other side has, which a neighbouring pixel of the reference shows. A wrong highlight, light or
    material inside a surface therefore fails however few pixels it touches (the f = 512 highlight is 4).
    """
    pixel: float   # largest |render − reference| in any of R, G, B (linear) that counts as equal
    share: float   # fraction of the pixels allowed above `pixel`, on edges and within the neighbours' range


# Per-pixel: 1e-3 in linear RGB is a quarter of an 8-bit step (1/255 ≈ 3.9e-3), so any change that could
# show in a PNG fails. Scratch run over every case below at 128 px wide: shading in float32 instead of
# float64 moved no pixel by more than 2.5e-5, and shifting the camera by 1e-5 (≈ 10 float32 ulps of
# these 10-unit scenes, more than two CPUs' Embree and numba rounding differ by) by at most 1.1e-4,
# so this leaves 9× room for other CPUs' FMA/SIMD rounding and the order the kernel sums terms in.
PIXEL = 1e-3
# Share: 0.2 % of the pixels (18 of 128×72, 12 of 128×48) may differ by more. A ray through a
# silhouette or a facet edge can land on either side when Embree rounds differently (SSE vs AVX2 vs
# AVX-512 kernels). In the scratch run a 1e-4 camera shift flipped at most 4 pixels (0.04 %, flat
# facets of attenuation) and a 1e-3 shift up to 1.4 % (its far spheres and the knot's flat facets);
# this allows the first with 4× room and still catches a moved object, light or highlight. With the edge
# rule (ImageTolerance) the same scratch run leaves no off pixel unexcused at a 1e-4 shift in any case,
# so the rule costs no margin; at a 1e-3 shift smooth surfaces move by more than `pixel` off any edge.
SHARE = 0.002

STANDARD = ImageTolerance(pixel=PIXEL, share=SHARE)

# (scene, variant) -> tolerance; one entry per reference image tests/image/references/<scene>-<variant>.exr.
# Variants: "flat" / "gouraud" / "phong" set render.shading; "blinn" is Phong shading with
# render.specular = "blinn"; "authored" renders the scene as written (its objects choose their models).
IMAGE_TOLERANCES: dict[tuple[str, str], ImageTolerance] = {
    ("default", "authored"): STANDARD,         # flat, Gouraud and Phong side by side, set per object
    ("coloured_lights", "flat"): STANDARD,     # no Gouraud case: the smooth full-frame floor makes this
    ("coloured_lights", "phong"): STANDARD,    # scene's references the largest (~95 KB each); 4 others cover it
    ("mesh", "flat"): STANDARD,
    ("mesh", "gouraud"): STANDARD,
    ("mesh", "phong"): STANDARD,
    ("creases", "gouraud"): STANDARD,          # flat shading ignores vertex normals, so crease_angle too
    ("creases", "phong"): STANDARD,
    ("attenuation", "flat"): STANDARD,
    ("attenuation", "gouraud"): STANDARD,
    ("attenuation", "phong"): STANDARD,
    ("specular", "gouraud"): STANDARD,         # Gouraud dims the f = 512 highlight to a faint polygon
    ("specular", "phong"): STANDARD,
    ("specular", "blinn"): STANDARD,
    ("shadows", "authored"): STANDARD,         # global mode: shadow rays and Hanika's terminator fix; shadow
                                               # edges flip like silhouettes, within the same share
    ("textured_sphere", "flat"): STANDARD,     # a colour map, sampled per pixel: the facets keep sharp
    ("textured_sphere", "phong"): STANDARD,    # checker edges; the highlight stays white
}
