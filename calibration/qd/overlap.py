"""Exact areas of a round spot on each quadrant of a QD with a cross-shaped dead gap, and their derivatives.

A thin circular diaphragm of radius r at height d above a parallel detector casts a spot that is a circle of
the same radius, moved by d·tan of the incidence (a translated copy, whatever the incidence). Quadrant k
with signs (s_x, s_y) is the region s_x x > g/2, s_y y > g/2 (the gap of width g is dead), so its share of a
spot centred at (c_x, c_y) is the area of a disc in a quarter-plane,

.. math:: A_k = G(g/2 - s_x c_x,\\; g/2 - s_y c_y),

where G(a, b) is the area of the disc of radius r centred at the origin with x > a and y > b. For b ≥ 0,
with w = √(r² − b²) and H(x) = ½ (x√(r² − x²) + r² asin(x/r)) the antiderivative of the half chord,

.. math:: G(a, b) = H(w) - H(\\ell) - b (w - \\ell), \\qquad \\ell = \\mathrm{clip}(a, -w, w),

and for b < 0, G(a, b) = S(a) − G(a, −b) with S(a) = 2 (H(r) − H(clip(a, −r, r))) the disc's part with x > a.
The partial derivatives are minus the chord lengths along the region's edges:
∂G/∂a = −max(0, h(a) − max(b, −h(a))) with h(a) = √(max(r² − a², 0)), and ∂G/∂b the same with a
and b swapped.

The Sun's disc (0.53°) blurs the spot's edge over d·0.0093/cos²θ (0.3 µm for d = 30 µm at 50°); a symmetric
blur changes these areas only at second order in its width (relative 10⁻⁵ for a 50 µm spot), so the spot
is taken as sharp with an effective radius. The detector is taken as larger than the spot's reach (no outer
edge).

References
----------
seed 002, §1.2.3 and eq. 2.1 (a QD: four photodiodes round the centre, the spot's position from their
currents); §1.3 (the pinhole diaphragm that limits the spot).
"""

from __future__ import annotations

import numpy as np


def _half_chord_integral(x, r):
    """H(x) = ∫₀ˣ √(r² − t²) dt for |x| ≤ r."""
    x = np.clip(x, -r, r)
    return 0.5 * (x * np.sqrt(np.maximum(r * r - x * x, 0.0)) + r * r * np.arcsin(x / r))


def _corner_nonnegative_b(a, b, r):
    w = np.sqrt(np.maximum(r * r - b * b, 0.0))
    lo = np.clip(a, -w, w)
    return _half_chord_integral(w, r) - _half_chord_integral(lo, r) - b * (w - lo)


def segment_area(a, r) -> np.ndarray:
    """S(a): area of a disc of radius r (centred at 0) with x > a [r's unit squared].

    References
    ----------
    seed 002, §1.3 (round diaphragm); module docstring.
    """
    a = np.asarray(a, dtype=float)
    return 2.0 * (_half_chord_integral(r, r) - _half_chord_integral(a, r))


def corner_area(a, b, r) -> np.ndarray:
    """G(a, b): area of a disc of radius r centred at the origin with x > a and y > b.

    Vectorised over `a` and `b`; exact (closed form, module docstring).

    References
    ----------
    seed 002, eq. 2.1 (the quadrant currents it splits the spot into); module docstring.
    """
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    pos = _corner_nonnegative_b(a, np.abs(b), r)
    return np.where(b >= 0, pos, segment_area(a, r) - pos)


def corner_area_gradient(a, b, r) -> tuple[np.ndarray, np.ndarray]:
    """(∂G/∂a, ∂G/∂b): minus the lengths of the region's edges inside the disc.

    References
    ----------
    seed 002, eq. 2.1 (the quadrant currents); module docstring.
    """
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    ha = np.sqrt(np.maximum(r * r - a * a, 0.0))
    hb = np.sqrt(np.maximum(r * r - b * b, 0.0))
    da = -np.maximum(0.0, ha - np.maximum(b, -ha))
    db = -np.maximum(0.0, hb - np.maximum(a, -hb))
    return da, db


def quadrant_areas(cx, cy, radius, gap, layout_signs) -> np.ndarray:
    """Area of a round spot on each quadrant, shape (..., 4), column k−1 = quadrant k.

    Parameters
    ----------
    cx, cy : numeric
        Spot centre in the detector's axes [m].
    radius : float
        Spot (diaphragm) radius [m].
    gap : float
        Width of the dead cross [m].
    layout_signs : ndarray, shape (4, 2)
        (s_x, s_y) of each quadrant (:func:`calibration.qd.design.quadrant_layout`).

    Returns
    -------
    areas : ndarray [m²]

    References
    ----------
    seed 002, eq. 2.1 (the quadrant layout); module docstring.
    """
    cx = np.asarray(cx, dtype=float)[..., None]
    cy = np.asarray(cy, dtype=float)[..., None]
    sx, sy = layout_signs[:, 0], layout_signs[:, 1]
    return corner_area(0.5 * gap - sx * cx, 0.5 * gap - sy * cy, radius)


def quadrant_areas_jacobian(cx, cy, radius, gap, layout_signs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Areas and their derivatives by the spot centre and by the gap width.

    Returns
    -------
    areas, d_dcx, d_dcy, d_dgap : ndarray, each shape (..., 4)

    References
    ----------
    seed 002, eq. 2.1 (the quadrant currents); module docstring.
    """
    cx = np.asarray(cx, dtype=float)[..., None]
    cy = np.asarray(cy, dtype=float)[..., None]
    sx, sy = layout_signs[:, 0], layout_signs[:, 1]
    a, b = 0.5 * gap - sx * cx, 0.5 * gap - sy * cy
    areas = corner_area(a, b, radius)
    ga, gb = corner_area_gradient(a, b, radius)
    return areas, -sx * ga, -sy * gb, 0.5 * (ga + gb)
