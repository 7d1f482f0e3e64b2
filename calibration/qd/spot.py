"""Spot position on the QD from its four photocurrents (seed 002 eq. 2.1).

.. math::

    x_c = \\frac{L}{2}\\,\\frac{(I_2 - I_1) + (I_3 - I_4)}{\\sum I}, \\qquad
    y_c = \\frac{L}{2}\\,\\frac{(I_2 - I_1) + (I_4 - I_3)}{\\sum I}

in the thesis' numbering. Written with each quadrant's signs (s_x, s_y) (:func:`~calibration.qd.design.quadrant_layout`)
it is x_c = (L/2) Σ s_x,k I_k / Σ I_k and the same in y, so another numbering is only another table of signs.
The currents are photocurrents: the dark current is subtracted first (:func:`calibration.qd.dark.subtract_dark`).

The ratio is the small-displacement reading of a QD. For a round spot of radius r and no gap it is
(2/π)(asin t + t √(1 − t²)) with t = x/r, so it saturates at ±1 once the spot lies on one side
(digest §7 item 3); the geometric and polynomial models absorb the curve, :mod:`calibration.qd.physical`
models it.
"""

from __future__ import annotations

import numpy as np

from ..errors import BenchDataError
from .design import quadrant_layout


class QdSignalError(BenchDataError):
    """Photocurrents whose sum is zero or negative: no light (or a dark current larger than the light)."""


def _currents(currents_a) -> np.ndarray:
    currents = np.asarray(currents_a, dtype=float)
    if currents.shape[-1:] != (4,):
        raise BenchDataError(f"currents must have 4 columns (quadrants 1–4), got shape {currents.shape}",
                             column="currents_a")
    return currents


def spot_ratios(currents_a, layout="thesis", *, invalid: str = "raise") -> tuple[np.ndarray, np.ndarray]:
    """Normalised spot coordinates u = 2 x_c / L and v = 2 y_c / L, each in [−1, 1] for positive currents.

    Parameters
    ----------
    currents_a : array_like, shape (..., 4)
        Photocurrents of quadrants 1–4 (dark current subtracted) [A].
    layout : str or array_like
        Quadrant layout, the thesis' by default (:func:`~calibration.qd.design.quadrant_layout`).
    invalid : {"raise", "nan"}
        What a reading whose sum is ≤ 0 (or not finite) gives: a :class:`QdSignalError` naming its row,
        or NaN.

    Returns
    -------
    u, v : ndarray
        [unitless].

    References
    ----------
    seed 002, eq. 2.1.
    """
    currents = _currents(currents_a)
    signs = quadrant_layout(layout)
    total = currents.sum(axis=-1)
    bad = ~(np.isfinite(total) & (total > 0))
    if bad.any():
        if invalid == "raise":
            row = int(np.flatnonzero(bad.ravel())[0])
            raise QdSignalError(f"the photocurrents of reading {row} sum to {total.ravel()[row]!r} A (≤ 0 or not "
                                "finite): no spot on the detector, or the dark current is larger than the light",
                                row=row, column="currents_a")
        if invalid != "nan":
            raise ValueError(f"`invalid` must be 'raise' or 'nan', got {invalid!r}")
    with np.errstate(divide="ignore", invalid="ignore"):
        u = currents @ signs[:, 0] / total  # seed 002 eq. 2.1, x
        v = currents @ signs[:, 1] / total  # seed 002 eq. 2.1, y
    return np.where(bad, np.nan, u), np.where(bad, np.nan, v)


def spot_position(currents_a, length_m: float, layout="thesis", *,
                  invalid: str = "raise") -> tuple[np.ndarray, np.ndarray]:
    """Spot centre (x_c, y_c) on the QD [m] from its photocurrents.

    Parameters
    ----------
    currents_a : array_like, shape (..., 4)
        Photocurrents of quadrants 1–4 [A].
    length_m : float
        L of eq. 2.1, the "size of the photodiode surface" [m] (the thesis gives no value; see
        :attr:`~calibration.qd.design.QdDesign.eq21_length_m`).
    layout, invalid
        As :func:`spot_ratios`.

    Returns
    -------
    xc_m, yc_m : ndarray
        [m].

    References
    ----------
    seed 002, eq. 2.1.
    """
    if not length_m > 0:
        raise ValueError(f"`length_m` must be positive, got {length_m}")
    u, v = spot_ratios(currents_a, layout, invalid=invalid)
    return 0.5 * length_m * u, 0.5 * length_m * v


def quadrant_fractions(currents_a, *, invalid: str = "raise") -> np.ndarray:
    """Each quadrant's share I_k / Σ I of the photocurrent [unitless], shape (..., 4).

    The cos-of-incidence factor and the lamp's intensity cancel in it, which is why the physical model is
    fitted to these.

    References
    ----------
    seed 002, eq. 2.1 (its normalisation by the sum).
    """
    currents = _currents(currents_a)
    total = currents.sum(axis=-1, keepdims=True)
    bad = ~(np.isfinite(total) & (total > 0))
    if bad.any() and invalid == "raise":
        row = int(np.flatnonzero(bad.ravel())[0])
        raise QdSignalError(f"the photocurrents of reading {row} sum to {total.ravel()[row]!r} A (≤ 0 or not finite)",
                            row=row, column="currents_a")
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(bad, np.nan, currents / total)
