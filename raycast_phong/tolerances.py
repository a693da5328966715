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
