"""Angular response laws of a coarse sun sensor's detectors (seed 000 §3.2, §5.2; Basilisk's Kelly curve).

Every law is a small pure function of the incidence angle γ from the detector normal [°] (or of cos γ where
the law is naturally written so), vectorised over numpy arrays, equal to 1 at normal incidence (Kelly: see
:func:`kelly_response`) and 0 at and beyond 90°. Angles are taken by absolute value: responses are symmetric.

==============================  ==========================================================================
law                             where it comes from
==============================  ==========================================================================
:func:`cosine_response`         ideal flat detector (Lambert)
:func:`power_law_response`      cos^p, a one-parameter widening/narrowing of the cosine
:func:`kelly_response`          γ·(1 − exp(−γ²/κ)), γ = cos incidence (Basilisk ``CoarseSunSensor``)
:func:`thesis_fov_response`     seed 000's pchip through (0, 1), (20, 0.95), (40, 0.5), (60, 0.05),
                                (80, 0.005), (90, 0): the TPS 230 field-of-view points of listings D.2–D.4,
                                which also equal Table C.1's Sun/0° ratios (digest §3.5)
:func:`albedo_mean_response`    S_mean(φ) of eq. 3.2: Table C.1's albedo/0° column, interpolated
:func:`hard_fov_cutoff`,        a field-of-view edge: a step, or a raised-cosine edge of stated width
:func:`smooth_fov_cutoff`       (differentiable, for fitting)
==============================  ==========================================================================
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator

from .detectors import TABLE_C1_ANGLE_DEG, table_c1_current_a

#: The field-of-view points of listings D.2–D.4 (incidence [°], relative sensitivity), one side.
THESIS_FOV_ANGLES_DEG: tuple[float, ...] = (0.0, 20.0, 40.0, 60.0, 80.0, 90.0)
THESIS_FOV_SENSITIVITY: tuple[float, ...] = (1.0, 0.95, 0.5, 0.05, 0.005, 0.0)


def cos_incidence(angle_deg) -> np.ndarray:
    """cos γ of incidence angle(s) γ [°]."""
    return np.cos(np.radians(np.asarray(angle_deg, float)))


def incidence_deg(cos_gamma) -> np.ndarray:
    """Incidence angle [°] of cos γ (clipped to [−1, 1])."""
    return np.degrees(np.arccos(np.clip(np.asarray(cos_gamma, float), -1.0, 1.0)))


def cosine_response(angle_deg) -> np.ndarray:
    """Ideal cosine response max(cos γ, 0) at incidence `angle_deg` [°]; exactly 0 at and beyond 90°."""
    a = np.abs(np.asarray(angle_deg, float))
    return np.where(a < 90.0, np.clip(cos_incidence(a), 0.0, None), 0.0)


def power_law_response(angle_deg, exponent) -> np.ndarray:
    """cos^p γ for cos γ > 0, else 0 (p > 0; p = 1 is the cosine, p > 1 narrower, p < 1 wider)."""
    p = np.asarray(exponent, float)
    if np.any(p <= 0):
        raise ValueError(f"the power-law exponent must be positive, got {exponent!r}")
    return cosine_response(angle_deg) ** p


def kelly_response(cos_gamma, kappa, *, normalize: bool = False) -> np.ndarray:
    """Kelly-curve response f = γ·(1 − exp(−γ²/κ)) with γ = cos incidence, 0 for γ ≤ 0.

    This is Basilisk's ``CoarseSunSensor`` form (its ``kellyFactor`` is κ > 0): a cosine whose tail is
    suppressed at grazing incidence (Fresnel reflection, package shadowing). At normal incidence f = 1 − e^(−1/κ),
    which is 1 within e^(−1/κ) for the small κ used in practice; `normalize` divides by it so that f(1) = 1.
    """
    gamma = np.clip(np.asarray(cos_gamma, float), 0.0, None)
    kappa = np.asarray(kappa, float)
    if np.any(kappa <= 0):
        raise ValueError(f"the Kelly factor κ must be positive, got {kappa!r}")
    f = gamma * -np.expm1(-(gamma**2) / kappa)
    if normalize:
        f = f / -np.expm1(-1.0 / kappa)
    return f


def thesis_fov_curve() -> PchipInterpolator:
    """The pchip curve of listings D.2–D.4 over −90 … 90° (MATLAB ``interp1(..., 'pchip')``), seed 000 §5.2.

    Built from the symmetric knot set (−90, 0), (−80, 0.005), … (0, 1), … (90, 0) exactly as the listings do.
    """
    one_side = np.asarray(THESIS_FOV_ANGLES_DEG[1:])
    angles = np.concatenate([-one_side[::-1], [0.0], one_side])
    values = np.concatenate([np.asarray(THESIS_FOV_SENSITIVITY[1:])[::-1], [1.0], THESIS_FOV_SENSITIVITY[1:]])
    return PchipInterpolator(angles, values, extrapolate=False)


_FOV = thesis_fov_curve()


def thesis_fov_response(angle_deg) -> np.ndarray:
    """Relative sensitivity of the thesis' field-of-view curve at incidence `angle_deg` [°]; 0 beyond 90°.

    The TPS 230 field of view (seed 000 listings D.2–D.4); the digest found that it also equals Table C.1's
    Sun/0° ratio of both photodiodes (digest §3.5 finding 1), i.e. it is Kandimala's S_rel(φ) of eq. 3.1.
    """
    a = np.abs(np.asarray(angle_deg, float))
    out = np.where(a < 90.0, _FOV(np.minimum(a, 90.0)), 0.0)
    return np.clip(out, 0.0, None)  # pchip gives −4e−19 at ±90°


def thesis_fov_integral(lower_deg, upper_deg) -> np.ndarray:
    """∫ S(θ) dθ of the thesis' curve between signed angles `lower_deg` and `upper_deg` [°·1], clipped to ±90°.

    Exact integral of the piecewise cubic; the weights of the thermopile's "seen temperature" (eq. 3.3).
    """
    lo = np.clip(np.asarray(lower_deg, float), -90.0, 90.0)
    hi = np.clip(np.asarray(upper_deg, float), -90.0, 90.0)
    lo, hi = np.broadcast_arrays(lo, hi)
    antiderivative = _FOV.antiderivative()
    return np.where(hi > lo, antiderivative(hi) - antiderivative(lo), 0.0)


def albedo_mean_response(angle_deg, detector: str = "uv") -> np.ndarray:
    """S_mean(φ) of eq. 3.2: Table C.1's albedo column of `detector` divided by its 0° value.

    Monotone cubic (pchip) through the 5° points; 0.288 (``uv``) / 0.289 (``vis``) at 90°, where part of the
    Earth is still in view. Table C.1 stops at 90°, so this returns NaN beyond 90° rather than guess the tail.
    The two detectors' columns agree within about 0.5 % (digest §3.5); the digest tabulates the ``uv`` one.
    The derivation of S_mean (ref. [4], Kandimala 2012) is not in seed 000.
    """
    column = table_c1_current_a(detector, "albedo")
    curve = PchipInterpolator(TABLE_C1_ANGLE_DEG, column / column[0], extrapolate=False)
    return curve(np.abs(np.asarray(angle_deg, float)))


def hard_fov_cutoff(angle_deg, half_angle_deg) -> np.ndarray:
    """1 where the incidence |γ| ≤ `half_angle_deg`, else 0 (a hard field-of-view edge)."""
    return (np.abs(np.asarray(angle_deg, float)) <= np.asarray(half_angle_deg, float)).astype(float)


def smooth_fov_cutoff(angle_deg, half_angle_deg, width_deg) -> np.ndarray:
    """Field-of-view edge with a raised-cosine roll-off of full width `width_deg` centred on `half_angle_deg`.

    1 for |γ| ≤ h − w/2, 0 for |γ| ≥ h + w/2, ½(1 + cos(π(|γ| − h + w/2)/w)) between: 0.5 at the half angle,
    continuous with a continuous first derivative, so a fit can move h and w. w → 0 gives :func:`hard_fov_cutoff`.
    """
    a = np.abs(np.asarray(angle_deg, float))
    h = np.asarray(half_angle_deg, float)
    w = np.asarray(width_deg, float)
    if np.any(w < 0):
        raise ValueError(f"the edge width must be non-negative, got {width_deg!r}")
    safe_w = np.where(w > 0, w, 1.0)
    u = np.clip((a - (h - w / 2.0)) / safe_w, 0.0, 1.0)
    ramp = 0.5 * (1.0 + np.cos(np.pi * u))
    return np.where(w > 0, ramp, (a <= h).astype(float))
