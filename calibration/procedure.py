"""The numerics of seed 003's bench procedure: its measurement grid and what its tilt stage estimates.

* The grid (§4.2): 8 azimuths 45° apart, zenith-stage angles 0–60° in 10° steps. :data:`SEED003_AZIMUTHS_DEG`
  and :data:`SEED003_ZENITH_STAGE_DEG` are its one definition; campaigns, plans and synthetic data take it
  from here.
* The tilt stage of the revised procedure (§4.4–4.5): along each azimuth the zenith-stage angle that brings the
  spot back onto the normal-incidence centre (:func:`centre_crossing_deg`), and the first harmonic of those
  angles over azimuth (:func:`tilt_harmonic_deg`): its mean is the bench's non-parallelism, its cosine and
  sine terms the tilt seen along azimuth 0° and 90° (eq. 15).

All functions are pure and vectorised; angles in degrees.

References
----------
seed 003, §4.2 (procedure and grid), §4.4–4.5 and Fig. 4.12 (tilt stage; 0.47° non-parallelism found),
eqs. 14–15 (tilt along azimuth).
"""

from __future__ import annotations

import numpy as np

#: Azimuth step of seed 003's grid [°] (§4.2: 8 azimuths).
SEED003_AZIMUTH_STEP_DEG = 45.0
#: Largest zenith-stage angle of seed 003's grid [°] (§4.2; the sensor's 60° half field of view).
SEED003_ZENITH_MAX_DEG = 60.0
#: Zenith-stage step of seed 003's grid [°] (§4.2).
SEED003_ZENITH_STEP_DEG = 10.0


def grid_azimuths_deg(azimuth_step_deg: float = SEED003_AZIMUTH_STEP_DEG) -> np.ndarray:
    """Azimuths of a full turn from 0° in steps of `azimuth_step_deg`, 360° excluded [°].

    Parameters
    ----------
    azimuth_step_deg : float
        Step [°], positive (seed 003: 45°).

    Returns
    -------
    azimuth_deg : ndarray
        0, step, 2·step … below 360 [°].

    References
    ----------
    seed 003, §4.2 (8 azimuths, 45° apart).
    """
    if not azimuth_step_deg > 0:
        raise ValueError(f"`azimuth_step_deg` must be positive, got {azimuth_step_deg}")
    return np.arange(0.0, 360.0 - 1e-9, float(azimuth_step_deg))


def grid_zeniths_deg(zenith_max_deg: float = SEED003_ZENITH_MAX_DEG,
                     zenith_step_deg: float = SEED003_ZENITH_STEP_DEG) -> np.ndarray:
    """Zenith-stage angles from 0° to `zenith_max_deg` (included) in steps of `zenith_step_deg` [°].

    References
    ----------
    seed 003, §4.2 (0–60° in 10° steps).
    """
    if not zenith_step_deg > 0:
        raise ValueError(f"`zenith_step_deg` must be positive, got {zenith_step_deg}")
    if not zenith_max_deg >= 0:
        raise ValueError(f"`zenith_max_deg` must be >= 0, got {zenith_max_deg}")
    return np.arange(0.0, float(zenith_max_deg) + 1e-9, float(zenith_step_deg))


#: Frames per direction of seed 003's grid stage (§4.2: 4) and of its centre stage (§4.2: 5).
SEED003_REPEATS = 4
SEED003_CENTRE_REPEATS = 5

#: Seed 003's 8 azimuths [°]: 0, 45 … 315.
SEED003_AZIMUTHS_DEG: tuple[float, ...] = tuple(float(a) for a in grid_azimuths_deg())
#: Seed 003's 7 zenith-stage angles [°]: 0, 10 … 60 (a 6th-order θ(r) needs at least 7).
SEED003_ZENITH_STAGE_DEG: tuple[float, ...] = tuple(float(z) for z in grid_zeniths_deg())


def centre_crossing_deg(spot_minus_px, spot_plus_px, centre_px, probe_deg: float) -> np.ndarray:
    """Zenith-stage angle at which the spot crosses the normal-incidence centre along one azimuth.

    .. math:: t = \\frac{(c − s_−) \\cdot (s_+ − s_−)}{|s_+ − s_−|^2}, \\qquad Ω_c = −p + 2 p t

    Parameters
    ----------
    spot_minus_px, spot_plus_px : array_like, shape (..., 2)
        Mean spot centres (x, y) at zenith-stage angles −`probe_deg` and +`probe_deg` [px].
    centre_px : array_like, shape (2,) or (..., 2)
        The normal-incidence centre (x0, y0) found by the centre stage [px].
    probe_deg : float
        Probe angle p [°], positive.

    Returns
    -------
    omega_deg : ndarray, shape (...)
        Ω_c [°]: where the projection of the centre onto the spot's line of motion falls, interpolated
        linearly between the two probes. NaN where the spot did not move or a spot is NaN.

    Notes
    -----
    Over a probe of a degree or so the spot moves along a straight line at a constant rate (eq. 9 is smooth
    near r = 0), so a linear interpolation is enough; the thesis measures the same angle by hand (Fig. 4.12).
    Ω_c is the tilt between the sensor and the bench along this azimuth.

    References
    ----------
    seed 003, §4.4–4.5 and Fig. 4.12 (the tilt stage of the revised procedure).
    """
    if not probe_deg > 0:
        raise ValueError(f"`probe_deg` must be positive, got {probe_deg}")
    minus = np.asarray(spot_minus_px, dtype=float)
    motion = np.asarray(spot_plus_px, dtype=float) - minus
    length2 = np.sum(motion * motion, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):  # a spot that did not move has no crossing: NaN
        t = np.sum((np.asarray(centre_px, dtype=float) - minus) * motion, axis=-1) / length2
    return np.where(length2 > 0, -probe_deg + 2.0 * probe_deg * t, np.nan)


def tilt_harmonic_deg(azimuth_deg, offset_deg) -> tuple[float, float, float]:
    """The first harmonic of the tilt stage's offsets over azimuth: non-parallelism and tilt (α, β).

    .. math:: Ω_c(φ) = m + α \\cos φ + β \\sin φ

    fitted by linear least squares.

    Parameters
    ----------
    azimuth_deg : array_like, shape (n,)
        Azimuths φ of the tilt stage [°]; at least 3 distinct ones.
    offset_deg : array_like, shape (n,)
        Zenith-stage angle Ω_c that brought the spot back onto the centre at each azimuth [°]
        (:func:`centre_crossing_deg`).

    Returns
    -------
    mean_offset_deg : float
        m, the bench's non-parallelism common to every azimuth [°] (seed 003 found 0.47°).
    tilt_x_deg : float
        α, the tilt seen along azimuth 0° [°].
    tilt_y_deg : float
        β, the tilt seen along azimuth 90° [°].

    Notes
    -----
    Eq. 15, sin θ* = sin θ' cos(φ − φ'), is for small tilts θ* ≈ θ' cos φ' cos φ + θ' sin φ' sin φ, and by
    eq. 14 θ' cos φ' ≈ α and θ' sin φ' ≈ β: the cosine and sine terms are α and β (the digest's reading of
    which axis α turns about, [ambiguous] in the thesis). The constant term takes what every azimuth shares.

    References
    ----------
    seed 003, eqs. 14–15, §4.4–4.5 (tilt stage; 0.47° non-parallelism).
    """
    azimuth = np.radians(np.asarray(azimuth_deg, dtype=float))
    offset = np.asarray(offset_deg, dtype=float)
    if azimuth.shape != offset.shape or azimuth.ndim != 1:
        raise ValueError("`azimuth_deg` and `offset_deg` must be 1-D arrays of one length")
    if np.unique(np.round(np.mod(np.degrees(azimuth), 360.0), 6)).size < 3:
        raise ValueError("`azimuth_deg` must hold at least 3 distinct azimuths")
    design = np.column_stack([np.ones(azimuth.size), np.cos(azimuth), np.sin(azimuth)])
    (mean, alpha, beta), *_ = np.linalg.lstsq(design, offset, rcond=None)
    return float(mean), float(alpha), float(beta)
