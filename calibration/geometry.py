"""Directions, angular errors and bench geometry (seed 003 §4.3–4.4).

All public functions take and return degrees and are vectorised over numpy arrays. Radians stay inside
the bodies.

Sensor body frame: +z is the boresight, out of the sensor face; the sun direction is
n = (sin θ cos φ, sin θ sin φ, cos θ) with zenith θ and azimuth φ in degrees (seed 003 eq. 12).
"""

from __future__ import annotations

import numpy as np


def direction_vector(zenith_deg, azimuth_deg) -> np.ndarray:
    """Unit sun-direction vector in the sensor body frame.

    .. math:: n = (\\cos φ \\sin θ, \\sin φ \\sin θ, \\cos θ)

    Parameters
    ----------
    zenith_deg : numeric
        Zenith angle θ from the boresight [°].
    azimuth_deg : numeric
        Azimuth φ in the sensor plane [°].

    Returns
    -------
    n : ndarray, shape (..., 3)
        Unit vectors [unitless].

    References
    ----------
    seed 003, eq. 12.
    """
    th = np.radians(np.asarray(zenith_deg, dtype=float))
    ph = np.radians(np.asarray(azimuth_deg, dtype=float))
    s = np.sin(th)
    return np.stack([np.cos(ph) * s, np.sin(ph) * s, np.cos(th)], axis=-1)


def zenith_azimuth_from_vector(n) -> tuple[np.ndarray, np.ndarray]:
    """Zenith and azimuth of (not necessarily unit) vectors in the body frame, inverse of eq. 12.

    Parameters
    ----------
    n : array_like, shape (..., 3)
        Direction vectors.

    Returns
    -------
    zenith_deg : ndarray
        Zenith from +z [°], in [0, 180].
    azimuth_deg : ndarray
        Azimuth [°] in [0, 360). Where the direction is the boresight the azimuth is 0.

    References
    ----------
    seed 003, eq. 12 (inverted).
    """
    n = np.asarray(n, dtype=float)
    rho = np.hypot(n[..., 0], n[..., 1])
    zenith = np.degrees(np.arctan2(rho, n[..., 2]))
    azimuth = np.mod(np.degrees(np.arctan2(n[..., 1], n[..., 0])), 360.0)
    return zenith, azimuth


def angular_error_deg(zenith_a_deg, azimuth_a_deg, zenith_b_deg, azimuth_b_deg) -> np.ndarray:
    """Angle between two sun directions.

    .. math:: Δ = \\arccos(n \\cdot n')

    Parameters
    ----------
    zenith_a_deg, azimuth_a_deg : numeric
        First direction (for example the true one set on the bench) [°].
    zenith_b_deg, azimuth_b_deg : numeric
        Second direction (for example the one the calibration reports) [°].

    Returns
    -------
    delta_deg : ndarray
        Angular error [°], in [0, 180].

    Notes
    -----
    Computed as atan2(|n × n'|, n · n'), which equals eq. 13 but keeps full precision for the small
    angles that matter here (arccos loses half the digits near 1; clipping it is the other usual fix).

    References
    ----------
    seed 003, eq. 13.
    """
    a = direction_vector(zenith_a_deg, azimuth_a_deg)
    b = direction_vector(zenith_b_deg, azimuth_b_deg)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def wrap_deg(angle_deg) -> np.ndarray:
    """Wrap an angle difference to [−180, 180) [°]."""
    return np.mod(np.asarray(angle_deg, dtype=float) + 180.0, 360.0) - 180.0


def incidence_from_stage_angle(stage_zenith_deg, lever_arm_mm, source_distance_mm) -> np.ndarray:
    """True incidence (zenith) angle on a bench whose zenith rotation axis is offset from the sensor.

    .. math:: θ = 180° − \\arccos\\frac{d − (L + d)\\cos Ω}{\\sqrt{(L + d)^2 + d^2 − 2 (L + d) d \\cos Ω}}

    Parameters
    ----------
    stage_zenith_deg : numeric
        Angle Ω set on the zenith rotation stage [°].
    lever_arm_mm : float
        Distance d from the rotation axis to the sensor [mm] (seed 003: 136.2 mm).
    source_distance_mm : float
        Distance L from the sensor (at Ω = 0) to the sun simulator [mm].

    Returns
    -------
    zenith_deg : ndarray
        Incidence angle θ of the simulator's light in the sensor frame [°]; it has the sign of Ω.

    Notes
    -----
    Geometry: axis at the origin, source at (L + d, 0), sensor at d(cos Ω, sin Ω) facing radially
    outwards. The thesis quotes L = 710 mm at eq. 8 and 710 cm in §4.1 ([ambiguous]); both are only
    parameters here. The arccos argument is clipped to [−1, 1] against rounding.

    References
    ----------
    seed 003, eq. 8 and Fig. 4.5.
    """
    omega = np.radians(np.asarray(stage_zenith_deg, dtype=float))
    d = float(lever_arm_mm)
    big = float(source_distance_mm) + d
    if d < 0 or source_distance_mm <= 0:
        raise ValueError("`lever_arm_mm` must be >= 0 and `source_distance_mm` positive")
    norm = np.sqrt(big**2 + d**2 - 2.0 * big * d * np.cos(omega))
    arg = np.clip((d - big * np.cos(omega)) / norm, -1.0, 1.0)  # seed 003 eq. 8
    theta = 180.0 - np.degrees(np.arccos(arg))
    return np.sign(omega) * theta


def combined_tilt(alpha_deg, beta_deg) -> tuple[np.ndarray, np.ndarray]:
    """Combine the two measured detector tilts into one tilt θ' along azimuth φ'.

    .. math:: \\tan φ' = \\tan β / \\tan α, \\qquad \\tan^2 θ' = \\tan^2 α + \\tan^2 β

    Parameters
    ----------
    alpha_deg : numeric
        Tilt measured along azimuth 0° [°].
    beta_deg : numeric
        Tilt measured along azimuth 90° [°].

    Returns
    -------
    tilt_deg : ndarray
        Magnitude θ' of the combined tilt [°].
    tilt_azimuth_deg : ndarray
        Azimuth φ' along which the combined tilt acts [°], in [0, 360).

    Notes
    -----
    The thesis' figure captions and eqs. 14–15 disagree on which axis α turns about ([ambiguous]); as in
    the digest, α is the tilt seen along φ = 0° and β along φ = 90°, which makes eqs. 14–15 consistent.
    φ' uses atan2 so the quadrant is kept.

    References
    ----------
    seed 003, eq. 14.
    """
    ta = np.tan(np.radians(alpha_deg))
    tb = np.tan(np.radians(beta_deg))
    tilt = np.degrees(np.arctan(np.hypot(ta, tb)))
    tilt_azimuth = np.mod(np.degrees(np.arctan2(tb, ta)), 360.0)
    return tilt, tilt_azimuth


def split_tilt(tilt_deg, tilt_azimuth_deg) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`combined_tilt`: the tilts α (along 0°) and β (along 90°) [°].

    References
    ----------
    seed 003, eq. 14 (inverted).
    """
    t = np.tan(np.radians(tilt_deg))
    pa = np.radians(tilt_azimuth_deg)
    return np.degrees(np.arctan(t * np.cos(pa))), np.degrees(np.arctan(t * np.sin(pa)))


def tilt_along_azimuth(azimuth_deg, tilt_deg, tilt_azimuth_deg) -> np.ndarray:
    """Detector tilt θ* seen along azimuth φ.

    .. math:: \\sin θ^* = \\sin θ' \\cos(φ − φ')

    Parameters
    ----------
    azimuth_deg : numeric
        Azimuth φ [°].
    tilt_deg, tilt_azimuth_deg : numeric
        Combined tilt θ' and its azimuth φ' from eq. 14 [°].

    Returns
    -------
    tilt_seen_deg : ndarray
        θ*(φ) [°], added to the polynomial zenith in eq. 16.

    References
    ----------
    seed 003, eq. 15.
    """
    s = np.sin(np.radians(tilt_deg)) * np.cos(np.radians(np.asarray(azimuth_deg) - tilt_azimuth_deg))
    return np.degrees(np.arcsin(np.clip(s, -1.0, 1.0)))


def spot_radius_px(x_px, y_px, x0_px, y0_px) -> np.ndarray:
    """Radial distance r of the spot from the normal-incidence centre (x0, y0) [px].

    References
    ----------
    seed 003, eq. 7.
    """
    return np.hypot(np.asarray(x_px, dtype=float) - x0_px, np.asarray(y_px, dtype=float) - y0_px)


def azimuth_measured_deg(x_px, y_px, x0_px, y0_px) -> np.ndarray:
    """Raw azimuth φ_meas of the spot around (x0, y0), in [0, 360) [°].

    .. math:: φ_{meas} = \\arctan\\frac{y − y_0}{x − x_0} + 90° \\;(x ≥ x_0), \\; + 270° \\;(x < x_0)

    Notes
    -----
    Implemented as atan2(x − x0, −(y − y0)) mod 360°, identical to eq. 10 on all four quadrants but
    defined at x = x0, where eq. 10 divides by zero (a departure from the thesis' formula, not its value).

    References
    ----------
    seed 003, eq. 10.
    """
    dx = np.asarray(x_px, dtype=float) - x0_px
    dy = np.asarray(y_px, dtype=float) - y0_px
    return np.mod(np.degrees(np.arctan2(dx, -dy)), 360.0)  # seed 003 eq. 10
