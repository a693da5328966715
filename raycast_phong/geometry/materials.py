"""Rows of the kernels' material table from coefficient arrays: the one writer of the row order, for the
scene's materials (renderer/pack.py) and a mesh file's (file_materials.py).

The order is k_a, k_d, k_s, k_e (r, g, b each), then f, then the texture rows of the k_a, k_d, k_e maps: the
columns codes.py names (KA, KD, KS, KE, SHININESS, KA_MAP, KD_MAP, KE_MAP), which renderer/kernels/layout.py
reads too. Pure numpy, so geometry needs no renderer import.
"""

from __future__ import annotations

import numpy as np

from .. import codes
from ..codes import ALPHA, ALPHA_CUTOFF, ALPHA_MAP, KA, KA_MAP, KD, KE, KE_MAP, KS, MATERIAL_TABLE_WIDTH, SHININESS


def material_rows(ka, kd, ks, ke, shininess, maps=None) -> np.ndarray:
    """(M, MATERIAL_TABLE_WIDTH) float64 rows of the material table from (M, 3) coefficients, (M,) or (M, 1)
    f, and (M, 3) texture rows of the ka, kd and ke maps (-1: none; all -1 when `maps` is None); opaque."""
    table = np.zeros((len(ka), MATERIAL_TABLE_WIDTH))
    table[:, KA:KA + 3], table[:, KD:KD + 3], table[:, KS:KS + 3], table[:, KE:KE + 3] = ka, kd, ks, ke
    table[:, SHININESS] = np.reshape(shininess, -1)
    table[:, KA_MAP:KE_MAP + 1] = -1 if maps is None else np.reshape(maps, (-1, 3))
    table[:, ALPHA_CUTOFF], table[:, ALPHA], table[:, ALPHA_MAP] = -1.0, 1.0, -1.0  # opaque (FileRows sets a mask)
    return table


def rows_of(materials, maps=None) -> np.ndarray:
    """material_rows of material records (the scene's Materials, a mesh file's FileMaterials): their ka, kd, ks,
    ke and shininess (codes.MATERIAL_COLUMNS)."""
    return material_rows(*(np.array([getattr(m, key) for m in materials], np.float64).reshape(len(materials), -1)
                           for key in codes.MATERIAL_COLUMNS), maps)
