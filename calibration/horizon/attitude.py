"""Roll and pitch from a dual-cone scan's horizon crossings, for a spherical and for the WGS84 Earth (seed 004
§2-3, eqs. 2.3–2.7 corrected; §2-4-1, eqs. 2.22–2.26).

Inputs are each cone's crossing phases ``phase_out_deg = (out₁, out₂)``, ``phase_in_deg = (in₁, in₂)`` [°] in the
package's conventions (:mod:`calibration.horizon`); a missing crossing (Sun/Moon blanking, no edge) is NaN.

Spherical Earth (:func:`solve_spherical`): the thesis writes eq. 2.7 (corrected: ``sin γ`` in its last term) once per
crossing, ``S_k(δ_i)·n(φ, θ) = cos ρ``, and solves it numerically — 2 crossings with ρ known, 3 or 4 with ρ solved
too. Here: Gauss–Newton/Levenberg–Marquardt (``scipy.optimize.least_squares``) started from the exact closed form
(digest §2.5: chord centre ``tan c = −tan θ / cos φ`` and the chord-width identity); or the thesis' steepest descent
with an Armijo line search (``method="steepest-descent"``; the thesis gives no step rule; a fixed unit step does not
converge, digest §2.5).

Oblate Earth: (i) the thesis' Â method (:func:`spin_axis_from_crossings`, eqs. 2.23–2.24, and
:func:`roll_pitch_from_spin_axis`, eqs. 2.25–2.26 with atan2); (ii) :func:`attitude_from_crossing_vectors`, the same
crossing vectors paired with their body directions (a Wahba problem), which also gives pitch; (iii)
:func:`solve_oblate`, the correction for the thesis' case — measured phases, the satellite's position known, the
spherical model replaced by the exact WGS84 crossings of :func:`calibration.horizon.oblate.crossing_phases_oblate`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .oblate import crossing_phases_oblate, spherical_equivalent_radius_deg
from .scan import (
    EQUATORIAL_RADIUS_KM,
    FLATTENING,
    THESIS_GAMMA_DEG,
    altitude_for_radius_km,
    body_to_orbit,
    nadir_in_body,
    roll_pitch_of_nadir,
    scan_vector,
)

__all__ = [
    "AttitudeSolution", "spherical_closed_form", "spherical_residuals", "solve_spherical",
    "spin_axis_from_crossings", "roll_pitch_from_spin_axis", "attitude_from_crossing_vectors", "solve_oblate",
]

#: Above this condition number of the Jacobian a solution is reported as ill-conditioned.
ILL_CONDITIONED = 1e8


@dataclass(frozen=True)
class AttitudeSolution:
    """A roll/pitch solution: the angles [°], ρ [°] (solved or given; None where the model has none), the altitude
    [km] it implies (spherical, eq. 2.3 with R_e = a), the residuals at the solution (eq. 2.7's in cos units, or phase
    residuals [°] for :func:`solve_oblate`), iterations, the Jacobian's condition number, and warnings in words."""

    roll_deg: float
    pitch_deg: float
    rho_deg: float | None
    altitude_km: float | None
    residuals: np.ndarray
    iterations: int
    condition_number: float
    converged: bool
    method: str
    n_crossings: int
    warnings: tuple[str, ...] = field(default=())


def _pairs(phase_out_deg, phase_in_deg, gamma_deg):
    out = np.asarray(phase_out_deg, float).reshape(-1)
    inn = np.asarray(phase_in_deg, float).reshape(-1)
    if out.shape != (2,) or inn.shape != (2,):
        raise ValueError("give one out and one in phase per cone: phase_out_deg=(out1, out2), phase_in_deg=(in1, in2)")
    gamma = np.broadcast_to(np.asarray(gamma_deg, float), (2,)).copy()
    if np.any((gamma <= 0) | (gamma >= 90)):
        raise ValueError(f"a half-cone γ is in (0°, 90°), got {gamma.tolist()}")
    return out, inn, gamma


def _crossing_list(out, inn, gamma):
    """(phases, cone signs, γ per crossing, cones) of the crossings present."""
    phases = np.array([out[0], inn[0], out[1], inn[1]])
    cones = np.array([1, 1, 2, 2])
    keep = np.isfinite(phases)
    return phases[keep], np.where(cones[keep] == 1, 1.0, -1.0), gamma[cones[keep] - 1], cones[keep]


def _wrap180(x):
    return (np.asarray(x, float) + 180.0) % 360.0 - 180.0


def spherical_closed_form(phase_out_deg, phase_in_deg, gamma_deg=THESIS_GAMMA_DEG, rho_deg=None):
    """Roll, pitch [°] and ρ [°] from the crossings without iterating (digest §2.5, from seed 004 eq. 2.7 corrected).

    Each cone k gives its chord's centre c_k = (out + in)/2 and half-width w_k = (out − in)/2: the nadir in the body
    frame is n = (M sin c, n_y, M cos c), M = √(1 − n_y²) (so ``tan c = −tan θ / cos φ``), and
    ``cos w_k sin γ_k M + s_k n_y cos γ_k = cos ρ``. Both cones: n_y/M = (cos w₂ sin γ₂ − cos w₁ sin γ₁)/(cos γ₁ +
    cos γ₂) (the chord-width identity) and ρ follows. One cone with ρ known: n_y solves the same equation.
    Exact for noise-free crossings. Returns ``(roll, pitch, rho)``; raises when the crossings do not suffice.
    """
    out, inn, gamma = _pairs(phase_out_deg, phase_in_deg, gamma_deg)
    full = np.isfinite(out) & np.isfinite(inn)
    half_width = np.radians(np.mod(out - inn, 360.0) / 2.0)
    centre = np.radians(np.mod(inn, 360.0)) + half_width
    g = np.radians(gamma)
    if full.all():
        c = np.arctan2(np.sin(centre).sum(), np.cos(centre).sum())  # the cones share the centre
        ratio = (np.cos(half_width[1]) * np.sin(g[1]) - np.cos(half_width[0]) * np.sin(g[0])) / (np.cos(g[0])
                                                                                                  + np.cos(g[1]))
        n_y = ratio / np.sqrt(1.0 + ratio ** 2)
        m = np.sqrt(1.0 - n_y ** 2)
        cos_rho = np.cos(half_width[0]) * np.sin(g[0]) * m + n_y * np.cos(g[0])
        rho = np.degrees(np.arccos(np.clip(cos_rho, -1.0, 1.0))) if rho_deg is None else float(rho_deg)
    elif full.any() and rho_deg is not None:
        k = int(np.flatnonzero(full)[0])
        s = 1.0 if k == 0 else -1.0
        c = centre[k]
        a_, b_ = np.cos(half_width[k]) * np.sin(g[k]), s * np.cos(g[k])
        amp = np.hypot(a_, b_)
        cos_arg = np.cos(np.radians(rho_deg)) / amp
        if abs(cos_arg) > 1.0:
            raise ValueError("the crossings are inconsistent with the given ρ (no roll fits the chord's width)")
        base, spread = np.arctan2(b_, a_), np.arccos(cos_arg)
        beta = min(base + spread, base - spread, key=abs)  # the smaller tilt: the sensor's ±33° roll range
        n_y, m = np.sin(beta), np.cos(beta)
        rho = float(rho_deg)
    else:
        raise ValueError("the closed form needs both crossings of both cones, or both of one cone and ρ")
    roll, pitch = roll_pitch_of_nadir(np.array([m * np.sin(c), n_y, m * np.cos(c)]))
    return float(roll), float(pitch), float(rho)


def spherical_residuals(roll_deg, pitch_deg, rho_deg, phases_deg, cones, gamma_deg=THESIS_GAMMA_DEG) -> np.ndarray:
    """Eq. 2.7 (corrected) per crossing: ``S_k(δ_i)·n(φ, θ) − cos ρ`` (seed 004 eqs. 2.5–2.7): zero on the
    horizon; for cone k, −sin θ sin γ sin δ + s_k sin φ cos θ cos γ + cos φ cos θ sin γ cos δ − cos ρ."""
    s = scan_vector(phases_deg, gamma_deg, cones)
    return s @ nadir_in_body(roll_deg, pitch_deg) - np.cos(np.radians(rho_deg))


def _residual_and_jacobian(x, phases, signs, gammas, rho_known):
    phi, theta = x[0], x[1]
    rho = x[2] if rho_known is None else np.radians(rho_known)
    d, g = np.radians(phases), np.radians(gammas)
    sv = np.stack([np.sin(d) * np.sin(g), signs * np.cos(g), np.cos(d) * np.sin(g)], -1)
    n = np.array([-np.sin(theta), np.sin(phi) * np.cos(theta), np.cos(phi) * np.cos(theta)])
    dn_phi = np.array([0.0, np.cos(phi) * np.cos(theta), -np.sin(phi) * np.cos(theta)])
    dn_theta = np.array([-np.cos(theta), -np.sin(phi) * np.sin(theta), -np.cos(phi) * np.sin(theta)])
    r = sv @ n - np.cos(rho)
    cols = [sv @ dn_phi, sv @ dn_theta]
    if rho_known is None:
        cols.append(np.full_like(r, np.sin(rho)))
    return r, np.stack(cols, -1)


def _steepest_descent(x0, fun, gtol=1e-13, max_iterations=20000):
    """Steepest descent on ½|r|² with an Armijo backtracking line search (c₁ = 1e-4, step halving; the step grows
    ×2 after an accepted one): the thesis' method (seed 004 §2-3) with the step control it does not state."""
    x = np.array(x0, float)
    r, jac = fun(x)
    f = 0.5 * r @ r
    step, it = 1.0, 0
    for it in range(1, max_iterations + 1):
        grad = jac.T @ r
        gg = grad @ grad
        if np.sqrt(gg) < gtol or f == 0.0:
            return x, it - 1, True
        while True:
            trial = x - step * grad
            r_t, jac_t = fun(trial)
            f_t = 0.5 * r_t @ r_t
            if f_t <= f - 1e-4 * step * gg or step < 1e-30:
                break
            step *= 0.5
        if step < 1e-30:
            return x, it, False
        x, r, jac, f = trial, r_t, jac_t, f_t
        step *= 2.0
    return x, max_iterations, False


def solve_spherical(phase_out_deg, phase_in_deg, gamma_deg=THESIS_GAMMA_DEG, rho_deg=None,
                    method: str = "least-squares", initial=None, radius_km=EQUATORIAL_RADIUS_KM) -> AttitudeSolution:
    """Roll, pitch (and ρ when `rho_deg` is None) from 2–4 crossings on a spherical Earth (seed 004 eq. 2.7
    corrected, §2-3): ``method="least-squares"`` (Gauss–Newton/LM) or ``"steepest-descent"`` (the thesis' method,
    Armijo line search). Starts from :func:`spherical_closed_form` where the crossings allow it (else from
    `initial` = (roll, pitch[, ρ]) [°] or zero attitude). `gamma_deg` is one γ or (γ₁, γ₂). ρ known: 2 crossings
    suffice; ρ solved: 3 or 4 (the altitude follows from eq. 2.3 with `radius_km`)."""
    out, inn, gamma = _pairs(phase_out_deg, phase_in_deg, gamma_deg)
    phases, signs, gammas, cones = _crossing_list(out, inn, gamma)
    n_unknown = 2 if rho_deg is not None else 3
    if phases.size < n_unknown:
        raise ValueError(f"{phases.size} crossing(s) cannot give {n_unknown} unknowns: roll, pitch"
                         + ("" if rho_deg is not None else " and ρ (give rho_deg, or 3–4 crossings)"))
    if method not in ("least-squares", "steepest-descent"):
        raise ValueError(f"method is 'least-squares' or 'steepest-descent', got {method!r}")
    warnings = []
    if initial is not None:
        guess = [float(v) for v in initial]
    else:
        try:
            guess = list(spherical_closed_form(out, inn, gamma, rho_deg))
        except ValueError:
            full = np.isfinite(out) & np.isfinite(inn)
            if full.any():  # a whole chord: ρ from its width with the nadir in the scan's plane of symmetry
                k = int(np.flatnonzero(full)[0])
                w = np.radians(np.mod(out[k] - inn[k], 360.0) / 2.0)
                guess = [0.0, -float(_wrap180(np.mod(inn[k], 360.0) + np.degrees(w))),
                         float(np.degrees(np.arccos(np.cos(w) * np.sin(np.radians(gamma[k])))))]
            else:
                guess = [0.0, 0.0, 68.0]
                warnings.append("no whole chord: started from zero attitude and ρ = 68°")
    x0 = np.radians(guess[:n_unknown])

    def fun(x):
        return _residual_and_jacobian(x, phases, signs, gammas, rho_deg)

    if method == "least-squares":
        result = least_squares(lambda x: fun(x)[0], x0, jac=lambda x: fun(x)[1], method="lm",
                               xtol=1e-15, ftol=1e-15, gtol=1e-15)
        x, iterations, converged = result.x, int(result.nfev), bool(result.status > 0)
    else:
        x, iterations, converged = _steepest_descent(x0, fun)
    r, jac = fun(x)
    cond = float(np.linalg.cond(jac))
    if not converged:
        warnings.append(f"{method} did not converge")
    if cond > ILL_CONDITIONED:
        warnings.append(f"ill-conditioned: the Jacobian's condition number is {cond:.3g}")
    if np.max(np.abs(r)) > 1e-6:
        warnings.append(f"the crossings do not fit one attitude: largest eq. 2.7 residual {np.max(np.abs(r)):.3g}")
    rho = float(np.degrees(x[2])) if rho_deg is None else float(rho_deg)
    roll, pitch = (float(v) for v in np.degrees(x[:2]))
    return AttitudeSolution(roll, pitch, rho, float(altitude_for_radius_km(rho, radius_km)), r, iterations, cond,
                            converged, method, int(phases.size), tuple(warnings))


def spin_axis_from_crossings(h_vectors, cones, gamma_deg=THESIS_GAMMA_DEG):
    """The scan's spin axis Â (cone 1's, +Y_s) from crossing unit vectors Ĥ_i (n, 3) in any frame: ``Â·Ĥ_i = ±cos γ``
    (+ for cone 1, − for cone 2, whose axis is −Â), seed 004 eqs. 2.23–2.24 — linear in Â for 3 crossings, least
    squares for 4; then normalised. Returns ``(Â, condition number of the system, residuals)``."""
    h = np.asarray(h_vectors, float)
    if h.ndim != 2 or h.shape[1] != 3 or h.shape[0] < 3:
        raise ValueError(f"Â needs at least 3 crossing vectors of shape (n, 3), got {h.shape}")
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    signs = np.where(np.asarray(cones).reshape(-1) == 1, 1.0, -1.0)
    if signs.size != h.shape[0]:
        raise ValueError("one cone per crossing vector")
    rhs = signs * np.cos(np.radians(np.broadcast_to(np.asarray(gamma_deg, float), signs.shape)))
    axis, *_ = np.linalg.lstsq(h, rhs, rcond=None)
    cond = float(np.linalg.cond(h))
    axis = axis / np.linalg.norm(axis)
    return axis, cond, h @ axis - rhs


def roll_pitch_from_spin_axis(axis_orbit):
    """Roll and pitch [°] from the spin axis Â = (a₁, a₂, a₃) in the orbit frame (seed 004 eqs. 2.25–2.26, with
    atan2 and in this package's frames): Â = R_y(−θ)R_x(−φ)ŷ = (sin θ sin φ, cos φ, cos θ sin φ), so
    φ = atan2(±√(a₁² + a₃²), a₂) and θ = atan(a₁/a₃).

    Pitch turns the scan about its own axis, so Â carries pitch only through roll's tilt: θ's sensitivity to Â is
    1/sin φ, and at zero roll pitch is not observable from Â at all (the thesis' eq. 2.26 reads its ICRF YPR321 pitch
    off Â, which needs STK's frames). Use :func:`attitude_from_crossing_vectors` for pitch."""
    a = np.asarray(axis_orbit, float)
    a = a / np.linalg.norm(a)
    sign = 1.0 if a[2] >= 0 else -1.0
    roll = np.degrees(np.arctan2(sign * np.hypot(a[0], a[2]), a[1]))
    pitch = np.degrees(np.arctan2(sign * a[0], sign * a[2])) if np.hypot(a[0], a[2]) > 0 else 0.0
    return float(roll), float(pitch)


def attitude_from_crossing_vectors(h_vectors_orbit, phases_deg, cones, gamma_deg=THESIS_GAMMA_DEG):
    """Roll, pitch and yaw [°] from crossing vectors Ĥ_i in the orbit frame paired with their body directions
    S_k(δ_i) (seed 004 eqs. 2.5, 2.23 — the Â method completed with the measured phases): the rotation R (body →
    orbit) minimising Σ|Ĥ_i − R S_i|² (Wahba's problem, by SVD); roll and pitch from the nadir Rᵀẑ (eqs. 2.25–2.26
    with atan2), yaw as the remaining turn about it. Returns ``(roll, pitch, yaw)``."""
    h = np.asarray(h_vectors_orbit, float)
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    s = scan_vector(phases_deg, gamma_deg, cones)
    if h.shape != s.shape or h.shape[0] < 2:
        raise ValueError("give at least 2 crossing vectors, one per phase")
    u, _, vt = np.linalg.svd(h.T @ s)
    d = np.sign(np.linalg.det(u @ vt))
    rot = u @ np.diag([1.0, 1.0, d]) @ vt
    roll, pitch = roll_pitch_of_nadir(rot.T @ np.array([0.0, 0.0, 1.0]))
    # rot = R_z(ψ) · R_y(−θ)R_x(−φ): yaw from the body x axis after removing roll and pitch
    rest = rot @ body_to_orbit(roll, pitch).T
    yaw = np.degrees(np.arctan2(rest[1, 0], rest[0, 0]))
    return float(roll), float(pitch), float(yaw)


def solve_oblate(phase_out_deg, phase_in_deg, position_km, orbit_frame, gamma_deg=THESIS_GAMMA_DEG,
                 emitting_height_km=0.0, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING, initial=None,
                 tolerance_deg=1e-10) -> AttitudeSolution:
    """Roll and pitch [°] from measured crossing phases with the satellite's position known, on the WGS84 Earth:
    least squares on the phase residuals of the exact oblate forward model
    (:func:`calibration.horizon.oblate.crossing_phases_oblate`: seed 004 eqs. 2.10, 2.17, 2.22–2.23 solved for the
    crossings) — the correction of the thesis' case B, whose spherical model (eq. 2.7) leaves ~0.05–0.1°.

    `position_km` (3,) is the satellite in an Earth-centred frame (z polar), `orbit_frame` (3, 3) the orbit frame's
    axes as columns in it (:func:`calibration.horizon.orbit.orbit_frame`); yaw is taken as 0. Started from the
    spherical solution with the sphere through the sub-satellite point (or `initial` = (roll, pitch)). The residuals
    are phases [°]; iterations count model evaluations."""
    out, inn, gamma = _pairs(phase_out_deg, phase_in_deg, gamma_deg)
    measured = np.array([out[0], inn[0], out[1], inn[1]])
    keep = np.isfinite(measured)
    if keep.sum() < 2:
        raise ValueError(f"{int(keep.sum())} crossing(s) cannot give roll and pitch")
    frame = np.asarray(orbit_frame, float)
    if frame.shape != (3, 3):
        raise ValueError(f"orbit_frame must be a (3, 3) rotation, got {frame.shape}")
    p = np.asarray(position_km, float)
    warnings = []
    if initial is None:
        rho0 = float(spherical_equivalent_radius_deg(p, a_km, flattening, emitting_height_km))
        start = solve_spherical(out, inn, gamma, rho_deg=rho0)
        initial = (start.roll_deg, start.pitch_deg)

    gammas, cones = np.repeat(gamma, 2), np.array([1, 1, 2, 2])

    def model(x):
        rot = frame @ body_to_orbit(np.degrees(x[0]), np.degrees(x[1]))
        o, i = crossing_phases_oblate(p, rot, gammas, cones, a_km, flattening, emitting_height_km,
                                      tolerance_deg=tolerance_deg)
        return np.where([True, False, True, False], o, i)

    def residual(x):
        r = _wrap180(model(x)[keep] - measured[keep])
        return np.where(np.isfinite(r), r, 180.0)  # a crossing the model loses: a large, finite residual

    def jacobian(x, step=1e-6):  # central differences with an absolute step [rad]: scipy's relative step
        cols = []                  # vanishes at the zero attitude the thesis' cases sit at
        for j in range(2):
            dx = np.zeros(2)
            dx[j] = step
            cols.append(_wrap180(model(x + dx)[keep] - model(x - dx)[keep]) / (2.0 * step))
        return np.stack(cols, -1)

    result = least_squares(residual, np.radians(np.asarray(initial, float)), jac=jacobian, method="lm",
                           xtol=1e-15, ftol=1e-15, gtol=1e-15)
    jac = result.jac
    cond = float(np.linalg.cond(jac))
    if not result.success:
        warnings.append("least squares did not converge")
    if cond > ILL_CONDITIONED:
        warnings.append(f"ill-conditioned: the Jacobian's condition number is {cond:.3g}")
    if np.max(np.abs(result.fun)) > 1e-4:
        warnings.append(f"the phases do not fit one attitude: largest residual {np.max(np.abs(result.fun)):.3g}°")
    roll, pitch = (float(v) for v in np.degrees(result.x))
    return AttitudeSolution(roll, pitch, None, None, np.asarray(result.fun), int(result.nfev), cond,
                            bool(result.success), "oblate-least-squares", int(keep.sum()), tuple(warnings))
