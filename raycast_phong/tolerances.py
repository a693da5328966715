"""Named tolerances of the model, each with its reason: one home, read by the kernels and by the oracle.

They are part of the model's definition (docs/scene-format.md states them), not of any one stage, so
the analytic reference can share them without importing the code it checks.
"""

# A point light closer to the shaded point than this × the scene's half-extent is head-on (l = n), and
# 1/d² divides by at least its square: at that range the light's direction would be decided by the
# rounding of the hit point (float32 barycentrics are good to ~1e-7 of the extent), so by the CPU.
MIN_DISTANCE = 1e-6

# A mix of unit vertex normals shorter than this points nowhere in particular: Phong shading keeps the
# face normal there. Opposite normals at a knife edge cancel to ~1e-7 in float32, well above any mix a
# real smooth surface makes (≥ cos of half the largest corner angle, ≫ 1e-6).
NO_DIRECTION = 1e-6

# n·l at or below this many units of rounding of the shading's precision (2⁻²⁴ in float32, 2⁻⁵³ in float64) is
# 0: the light lies in the surface's plane to within rounding. There n·l is rounding alone, of either sign, and
# "no specular where l·n ≤ 0" turned the noise into speckled highlights (a light in a tilted plane's plane: 22 %
# of pixels up to +0.34). A dot product of unit vectors that are themselves rounded is good to a few units; 16
# leaves room, and moves the lit side's edge by 1e-4° in float32.
LIT_ROUNDINGS = 16

# The float range a render stays inside (docs/scene-format.md, "Number ranges"). Shading runs in float32 by
# default (largest finite 3.4e38, smallest normal 1.2e-38) and Embree always does, so each bound keeps the
# numbers derived from a valid scene finite there, and their squares finite in float64.
POSITION_LIMIT = 1e18   # |coordinate| of a point, and the largest length: squared distances across the
                        # scene, (2√3 · 1e18)² ≈ 1.2e37, stay below float32's 3.4e38
MIN_EXTENT = 1e-12      # the scene's half-extent: the 1/d² floor, 1e-6 of it, squared is a normal float32,
                        # and the camera in Embree's unit frame stays within 3.5e18 / 1e-12 ≈ 3.5e30
DIRECTION_RANGE = (1e-150, 1e150)  # length of a direction: its square is a normal, finite float64, so
                                   # normalising it by sqrt(v·v) neither underflows to 0/0 nor overflows
INTENSITY_LIMIT = 1e38  # a bound on any channel of a pixel: below float32's 3.4e38 with room for the rounding
                        # of the kernel's sums
