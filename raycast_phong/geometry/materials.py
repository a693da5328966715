"""Rows of the kernels' material table from coefficient arrays: the one writer of the row order, for the
scene's materials (renderer/pack.py) and a mesh file's (build.py).

The order is k_a, k_d, k_s, k_e (r, g, b each), then f: the columns renderer/kernels/layout.py names
(KA, KD, KS, KE, SHININESS; a test pins the two together). Pure numpy, so geometry needs no renderer import.
"""

from __future__ import annotations

import numpy as np


def material_rows(ka, kd, ks, ke, shininess) -> np.ndarray:
    """(M, 13) float64 rows of the material table from (M, 3) coefficients and (M,) or (M, 1) f."""
    table = np.zeros((len(ka), 13))
    table[:, 0:3], table[:, 3:6], table[:, 6:9], table[:, 9:12] = ka, kd, ks, ke
    table[:, 12] = np.reshape(shininess, -1)
    return table
