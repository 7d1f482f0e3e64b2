"""The cone scan and a spherical Earth's horizon crossings in closed form (seed 004 §2-3, eqs. 2.3–2.7).

The package's conventions (:mod:`calibration.horizon`) fix the frames, the cones and the phase. Everything here is
vectorised: arguments broadcast against each other.

Seed 004's eq. 2.7 as printed ends in ``cos θ cos φ cos δ1 cos γ``; carrying out its own eq. 2.6 (with the orthogonal
R_x the printed matrix is not) gives ``sin γ`` there (digest §2.5). With the printed form a zero attitude at 505 km
has cos δ = 1.099 (no crossing); the corrected one gives δ = 66.42°, t = 0.18451 s against STK's 0.18443–0.18452 s.
"""

from __future__ import annotations

import numpy as np

#: WGS84 equatorial radius [km] (seed 004 §2-4-1; STK's Earth.cb MajorAxis).
EQUATORIAL_RADIUS_KM = 6378.137
#: WGS84 flattening, 1/298.257223563 (the thesis prints f ≈ 0.00335286 from rounded radii; digest §3.2).
FLATTENING = 1.0 / 298.257223563
#: WGS84 polar radius [km], a·(1 − f) = 6356.752314 (the thesis: 6356.752).
POLAR_RADIUS_KM = EQUATORIAL_RADIUS_KM * (1.0 - FLATTENING)
#: The thesis' sensor: scan half-cone γ [°], the IFOV's half-angle [°], the scan rate [rev/s] (seed 004 §3-5).
THESIS_GAMMA_DEG = 70.0
THESIS_IFOV_HALF_ANGLE_DEG = 2.0
THESIS_SCAN_RATE_HZ = 1.0
#: The cones' spin-axis signs: cone 1 about +Y_s, cone 2 about −Y_s.
CONE_SIGNS = {1: 1.0, 2: -1.0}


def cone_sign(cone) -> np.ndarray:
    """+1 for cone 1 (spin axis +Y_s), −1 for cone 2 (−Y_s); `cone` is 1 or 2 (array-like allowed)."""
    cone = np.asarray(cone)
    if not np.isin(cone, (1, 2)).all():
        raise ValueError(f"a cone is 1 or 2, got {np.unique(cone[~np.isin(cone, (1, 2))]).tolist()}")
    return np.where(cone == 1, 1.0, -1.0)


def earth_angular_radius_deg(altitude_km, radius_km=EQUATORIAL_RADIUS_KM, emitting_height_km=0.0) -> np.ndarray:
    """The Earth's angular radius ρ seen from `altitude_km` above a sphere of `radius_km` [°].

    ρ = asin((R_e + H_eq) / (R_e + h)), seed 004 eq. 2.3; `emitting_height_km` is H_eq, the equivalent height of the
    IR-emitting layer ("usually 40 km"; the thesis sets 0 and models the atmosphere apart).
    """
    ratio = (np.asarray(radius_km, float) + emitting_height_km) / (np.asarray(radius_km, float) + altitude_km)
    if np.any(ratio >= 1.0):
        raise ValueError("the sensor must be above the emitting layer (R_e + H_eq < R_e + h)")
    return np.degrees(np.arcsin(ratio))


def altitude_for_radius_km(rho_deg, radius_km=EQUATORIAL_RADIUS_KM, emitting_height_km=0.0) -> np.ndarray:
    """The altitude [km] at which the Earth's angular radius is `rho_deg` — seed 004 eq. 2.3 inverted."""
    return (np.asarray(radius_km, float) + emitting_height_km) / np.sin(np.radians(rho_deg)) - radius_km


def nadir_in_body(roll_deg, pitch_deg) -> np.ndarray:
    """The nadir (the Earth's centre, or the Earth simulator's disc centre) in the body frame at roll φ, pitch θ:
    ``(−sin θ, sin φ cos θ, cos φ cos θ)`` = (R_y(−θ) R_x(−φ))ᵀ ẑ (seed 004 eq. 2.6, orthogonal R_x). Shape (…, 3)."""
    phi, theta = np.radians(roll_deg), np.radians(pitch_deg)
    phi, theta = np.broadcast_arrays(phi, theta)
    return np.stack([-np.sin(theta), np.sin(phi) * np.cos(theta), np.cos(phi) * np.cos(theta)], axis=-1)


def roll_pitch_of_nadir(nadir_body) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch [°] that put the nadir at `nadir_body` (…, 3) — :func:`nadir_in_body` inverted:
    θ = −asin n_x, φ = atan2(n_y, n_z) (atan2 where seed 004 eq. 2.25 has atan, so a negative roll keeps its sign)."""
    n = np.asarray(nadir_body, float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return np.degrees(np.arctan2(n[..., 1], n[..., 2])), np.degrees(-np.arcsin(np.clip(n[..., 0], -1.0, 1.0)))


def body_to_orbit(roll_deg, pitch_deg) -> np.ndarray:
    """The rotation taking body vectors to the orbit frame, ``R_y(−θ) · R_x(−φ)`` (seed 004 eq. 2.6 with the
    orthogonal R_x), shape (…, 3, 3)."""
    phi, theta = np.broadcast_arrays(np.radians(roll_deg), np.radians(pitch_deg))
    c, s = np.cos(theta), np.sin(theta)
    zero, one = np.zeros_like(c), np.ones_like(c)
    ry = np.stack([np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1), np.stack([-s, zero, c], -1)], -2)
    cp, sp = np.cos(phi), np.sin(phi)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, cp, -sp], -1), np.stack([zero, sp, cp], -1)], -2)
    return ry @ rx


def scan_vector(phase_deg, gamma_deg=THESIS_GAMMA_DEG, cone=1) -> np.ndarray:
    """The scan direction of cone `cone` at phase δ in the body frame, shape (…, 3) (seed 004 eq. 2.5; cone 2 about
    −Y_s)."""
    delta, gamma = np.radians(phase_deg), np.radians(gamma_deg)
    s = cone_sign(cone)
    delta, gamma, s = np.broadcast_arrays(delta, gamma, s)
    return np.stack([np.sin(delta) * np.sin(gamma), s * np.cos(gamma), np.cos(delta) * np.sin(gamma)], axis=-1)


def crossing_phases_for_nadir(nadir_body, rho_deg, gamma_deg=THESIS_GAMMA_DEG, cone=1):
    """The phases [°, in [0, 360)] where cone `cone` crosses a circular horizon of angular radius ρ about the
    direction `nadir_body` (…, 3): ``(phase_out, phase_in)``, leaving the disc and coming back onto it.

    The crossing condition S_k(δ)·n = cos ρ (seed 004 eq. 2.7, corrected) is A sin δ + B cos δ = cos ρ − C with
    A = n_x sin γ, B = n_z sin γ, C = s_k n_y cos γ, so δ = c ± w, c = atan2(A, B), cos w = (cos ρ − C)/√(A² + B²);
    the scan is on the disc for |δ − c| < w. NaN where the cone does not cross the horizon (it stays on the disc or
    off it all round).
    """
    n = np.asarray(nadir_body, float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    gamma = np.radians(gamma_deg)
    a = n[..., 0] * np.sin(gamma)
    b = n[..., 2] * np.sin(gamma)
    c_term = cone_sign(cone) * n[..., 1] * np.cos(gamma)
    amplitude = np.hypot(a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_w = (np.cos(np.radians(rho_deg)) - c_term) / amplitude
    crosses = np.abs(cos_w) < 1.0
    w = np.degrees(np.arccos(np.where(crosses, cos_w, 0.0)))
    centre = np.degrees(np.arctan2(a, b))
    phase_out = np.where(crosses, np.mod(centre + w, 360.0), np.nan)
    phase_in = np.where(crosses, np.mod(centre - w, 360.0), np.nan)
    return phase_out, phase_in


def crossing_phases(roll_deg, pitch_deg, rho_deg, gamma_deg=THESIS_GAMMA_DEG, cone=1):
    """:func:`crossing_phases_for_nadir` at roll φ and pitch θ [°]: for cone k,
    cos ρ = −sin θ sin γ sin δ + s_k sin φ cos θ cos γ + cos φ cos θ sin γ cos δ (seed 004 eq. 2.7 corrected; s_k of
    :func:`cone_sign`)."""
    return crossing_phases_for_nadir(nadir_in_body(roll_deg, pitch_deg), rho_deg, gamma_deg, cone)


def phase_to_time_s(phase_deg, period_s=1.0 / THESIS_SCAN_RATE_HZ) -> np.ndarray:
    """t = δ / 360° × T: the time after the scan's reference at which it reaches phase δ (seed 004 §2-3; the thesis'
    1 rev/s gives δ = 360°·t)."""
    return np.asarray(phase_deg, float) / 360.0 * period_s


def time_to_phase_deg(time_s, period_s=1.0 / THESIS_SCAN_RATE_HZ) -> np.ndarray:
    """δ = 360° × t / T (:func:`phase_to_time_s` inverted)."""
    return 360.0 * np.asarray(time_s, float) / period_s
