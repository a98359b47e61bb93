"""Spherical harmonics in numpy, in lightlink's one convention (docs/sh.md).

Real orthonormal SH, index i = l*l + l + m (l = 0..bands-1, m = -l..l); band 1 is (y, z, x).
Coefficients are projections of *incident radiance*; irradiance on a surface with unit normal n
is E(n) = max(0, sum_i A_l(i) * L_i * Y_i(n)) with the clamped-cosine factors
A = (pi, 2pi/3, pi/4, 0). Every function works on arrays of any leading shape: a lightmap
(H, W, 3, nc) evaluated at per-texel normals (H, W, 3) gives (H, W, 3) at once, no Python loops.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["basis", "evaluate", "irradiance", "dominant_direction", "IRRADIANCE_BAND_FACTORS"]

# Normalisation constants (core/sh/sh.h, docs/sh.md).
_Y00 = 0.282094791773878
_Y1 = 0.488602511902920
_Y2_CROSS = 1.092548430592079
_Y20 = 0.315391565252520
_Y22 = 0.546274215296040
_Y33 = 0.590043589926644
_Y3_XYZ = 2.890611442640554
_Y31 = 0.457045799464466
_Y30 = 0.373176332590115
_Y32 = 1.445305721320277

IRRADIANCE_BAND_FACTORS = np.array([math.pi, 2.0 * math.pi / 3.0, math.pi / 4.0, 0.0], dtype=np.float64)


def _bands_of(nc: int) -> int:
    bands = int(round(math.sqrt(nc)))
    if bands * bands != nc or not 1 <= bands <= 4:
        raise ValueError(f"sh: {nc} coefficients is not 1, 4, 9 or 16")
    return bands


def basis(directions: np.ndarray, bands: int) -> np.ndarray:
    """Y_i(d) for unit directions of shape (..., 3) -> (..., bands*bands), float32."""
    if not 1 <= bands <= 4:
        raise ValueError(f"sh: bands {bands} is out of range (1..4)")
    d = np.asarray(directions, dtype=np.float32)
    if d.shape[-1] != 3:
        raise ValueError(f"sh: directions have shape {d.shape}, expected (..., 3)")
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = np.empty(d.shape[:-1] + (bands * bands,), dtype=np.float32)
    out[..., 0] = _Y00
    if bands >= 2:
        out[..., 1] = _Y1 * y
        out[..., 2] = _Y1 * z
        out[..., 3] = _Y1 * x
    if bands >= 3:
        xx, yy, zz = x * x, y * y, z * z
        out[..., 4] = _Y2_CROSS * x * y
        out[..., 5] = _Y2_CROSS * y * z
        out[..., 6] = _Y20 * (3.0 * zz - 1.0)
        out[..., 7] = _Y2_CROSS * x * z
        out[..., 8] = _Y22 * (xx - yy)
        if bands >= 4:
            out[..., 9] = _Y33 * y * (3.0 * xx - yy)
            out[..., 10] = _Y3_XYZ * x * y * z
            out[..., 11] = _Y31 * y * (5.0 * zz - 1.0)
            out[..., 12] = _Y30 * z * (5.0 * zz - 3.0)
            out[..., 13] = _Y31 * x * (5.0 * zz - 1.0)
            out[..., 14] = _Y32 * z * (xx - yy)
            out[..., 15] = _Y33 * x * (xx - 3.0 * yy)
    return out


def _band_factors(nc: int) -> np.ndarray:
    bands = _bands_of(nc)
    return np.repeat(IRRADIANCE_BAND_FACTORS[:bands], [2 * l + 1 for l in range(bands)]).astype(np.float32)


def evaluate(coeffs: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Radiance sum_i c_i Y_i(d): coeffs (..., 3, nc), directions (..., 3) -> (..., 3)."""
    c = np.asarray(coeffs, dtype=np.float32)
    y = basis(directions, _bands_of(c.shape[-1]))
    return np.einsum("...ci,...i->...c", c, y)


def irradiance(coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance E(n) = max(0, sum A_l L_i Y_i(n)): coeffs (..., 3, nc), normals (..., 3) -> (..., 3)."""
    c = np.asarray(coeffs, dtype=np.float32)
    y = basis(normals, _bands_of(c.shape[-1])) * _band_factors(c.shape[-1])
    return np.maximum(np.einsum("...ci,...i->...c", c, y), 0.0)


def dominant_direction(coeffs: np.ndarray) -> np.ndarray:
    """The direction most light comes from, from the linear band summed over RGB: (..., 3, nc) -> (..., 3).

    The wire carries no surface normals; lightlink's previews (`lightlink pull`, the C++
    client's previewCachesOf) evaluate each texel along this direction, (0, 0, 1) where the
    linear band is zero or absent.
    """
    c = np.asarray(coeffs, dtype=np.float32)
    if c.shape[-1] < 4:
        out = np.zeros(c.shape[:-2] + (3,), dtype=np.float32)
        out[..., 2] = 1.0
        return out
    s = c[..., :, 1:4].sum(axis=-2)  # (y, z, x)
    v = s[..., [2, 0, 1]]
    n = np.sqrt((v * v).sum(axis=-1, keepdims=True))
    ok = n > 0
    return np.where(ok, v / np.where(ok, n, 1.0), np.array([0.0, 0.0, 1.0], dtype=np.float32)).astype(np.float32)
