"""The horizon of the WGS84 (oblate) Earth and a cone scan's crossings of it (seed 004 §2-4-1, eqs. 2.8–2.24).

Positions are Earth-centred Cartesian [km] with z along the polar axis (ECEF, or an inertial frame momentarily
aligned with it: the ellipsoid is symmetric about z, so the geometry of a snapshot is the same). The local frame
at the satellite P is the one in which seed 004 eq. 2.22 holds exactly (digest §3.2, checked here in the tests):

* n̂ = −P/|P|, the **geocentric** nadir;
* Ê = ẑ × P̂ / |ẑ × P̂| (local East) and N̂ = P̂ × Ê (local North), so Ψ runs from East towards North;
* a horizon direction at azimuth Ψ is ``cos ρ n̂ + sin ρ (cos Ψ Ê + sin Ψ N̂)``.

An emitting layer (seed 004 eq. 2.3's H_eq) is modelled as the ellipsoid grown by H on both axes (a + H, c + H):
the closed forms of eqs. 2.17 and 2.22 stay exact for it. The surface of constant geodetic height H (what
:func:`calibration.horizon.earth.tangent_altitude_km` measures) differs from it by 0.06 m at H = 40 km (measured in
tests/calibration/horizon/test_oblate.py), i.e. ~1e-6° of ρ: the two are interchangeable here.
"""

from __future__ import annotations

import numpy as np

from .earth import EQUATORIAL_RADIUS_KM, FLATTENING, surface_radius_km
from .scan import THESIS_GAMMA_DEG, crossing_phases_for_nadir

__all__ = [
    "ellipsoid_axes_km", "horizon_plane", "local_horizon_frame", "angular_radius_deg", "tangent_angle_deg",
    "horizon_direction", "spherical_equivalent_radius_deg", "crossing_phases_oblate", "crossing_condition",
]


def _positions(position_km) -> np.ndarray:
    p = np.asarray(position_km, float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"position_km must have shape (..., 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("position_km has non-finite components")
    return p


def ellipsoid_axes_km(a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING, emitting_height_km=0.0):
    """Equatorial and polar semi-axes [km] and flattening of the Earth grown by an emitting layer H:
    ``(a + H, a(1 − f) + H, f')`` with f' = 1 − (c + H)/(a + H) (seed 004 eqs. 2.8, 2.3's H_eq)."""
    a = float(a_km) + float(emitting_height_km)
    c = float(a_km) * (1.0 - float(flattening)) + float(emitting_height_km)
    if not (c > 0 and a > 0):
        raise ValueError(f"the emitting height {emitting_height_km} km leaves no Earth")
    return a, c, 1.0 - c / a


def _check_outside(p, a, c):
    inside = (p[..., 0] ** 2 + p[..., 1] ** 2) / a ** 2 + p[..., 2] ** 2 / c ** 2 <= 1.0
    if np.any(inside):
        raise ValueError("the observer must be above the Earth (outside the ellipsoid, emitting layer included)")


def horizon_plane(position_km, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING, emitting_height_km=0.0):
    """The plane holding the whole horizon seen from P = (u, v, w): ``x u + y v + z w/(1 − f)² = a²`` (seed 004
    eq. 2.17). Returns ``(unit normal (…, 3), distance (…) [km])`` with the plane = {X : normal·X = distance}; the
    normal is along (u, v, w/(1 − f)²) and does not depend on the observer's distance (seed 004 §2-4-1)."""
    p = _positions(position_km)
    a, c, f = ellipsoid_axes_km(a_km, flattening, emitting_height_km)
    _check_outside(p, a, c)
    normal = p * np.array([1.0, 1.0, 1.0 / (1.0 - f) ** 2])
    norm = np.linalg.norm(normal, axis=-1)
    return normal / norm[..., None], a * a / norm


def local_horizon_frame(position_km):
    """The geocentric nadir n̂, local East Ê and North N̂ at P, each (…, 3) (seed 004 eq. 2.22's tangent frame;
    on the polar axis East is taken along +y)."""
    p = _positions(position_km)
    up = p / np.linalg.norm(p, axis=-1, keepdims=True)
    east = np.stack([-up[..., 1], up[..., 0], np.zeros_like(up[..., 0])], axis=-1)
    norm = np.linalg.norm(east, axis=-1, keepdims=True)
    on_axis = norm[..., 0] < 1e-15
    east = np.where(on_axis[..., None], np.array([0.0, 1.0, 0.0]), east / np.where(norm > 0, norm, 1.0))
    north = np.cross(up, east)
    return -up, east, north


def angular_radius_deg(position_km, azimuth_deg, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING,
                       emitting_height_km=0.0) -> np.ndarray:
    """The oblate Earth's angular radius ρ(Ψ) [°] seen from P at horizon azimuth Ψ [°] (from East towards North):

        ρ = acot{ √[((d² − R²)/a²) (1 + (2 − f) f R² cos²λ / ((1 − f)² a²) · sin²Ψ)]
                  + (2 − f) f R² sin 2λ / (2 (1 − f)² a²) · sin Ψ }

    with d = |P|, λ its geocentric latitude and R the surface radius there (eq. 2.21) — seed 004 eq. 2.22 (Wertz
    1978). Exact (not a first-order form): it equals :func:`tangent_angle_deg` to ~1e-11°. Broadcasts P (…, 3)
    against Ψ (…).
    """
    p = _positions(position_km)
    a, c, f = ellipsoid_axes_km(a_km, flattening, emitting_height_km)
    _check_outside(p, a, c)
    d = np.linalg.norm(p, axis=-1)
    lam = np.arctan2(p[..., 2], np.hypot(p[..., 0], p[..., 1]))
    r = surface_radius_km(np.degrees(lam), a, f)
    psi = np.radians(np.asarray(azimuth_deg, float))
    k = (2.0 - f) * f * r * r / ((1.0 - f) ** 2 * a * a)
    cot_rho = (np.sqrt((d * d - r * r) / (a * a) * (1.0 + k * np.cos(lam) ** 2 * np.sin(psi) ** 2))
               + 0.5 * k * np.sin(2.0 * lam) * np.sin(psi))
    return np.degrees(np.arctan2(1.0, cot_rho))


def tangent_angle_deg(position_km, azimuth_deg, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING,
                      emitting_height_km=0.0) -> np.ndarray:
    """ρ(Ψ) [°] computed directly, without eq. 2.22: the ray P + s·u(ρ, Ψ) is tangent to the ellipsoid where, in
    coordinates scaled to make it a sphere of radius a (z → z·a/c), its distance to the centre is a; in the plane
    (n̂, cos Ψ Ê + sin Ψ N̂) that is a quadratic in tan ρ, solved here (seed 004 eqs. 2.13–2.16: N̂·H = 0)."""
    p = _positions(position_km)
    a, c, _ = ellipsoid_axes_km(a_km, flattening, emitting_height_km)
    _check_outside(p, a, c)
    nadir, east, north = local_horizon_frame(p)
    psi = np.radians(np.asarray(azimuth_deg, float))[..., None]
    side = np.cos(psi) * east + np.sin(psi) * north
    scale = np.array([1.0, 1.0, a / c])
    ps, ns, ts = p * scale, nadir * scale, side * scale
    # |P'|²|u'|² − (P'·u')² − a²|u'|² = 0 with u' = cos ρ n' + sin ρ t': A cos² + 2B cos sin + C sin² = 0
    pp = np.sum(ps * ps, -1)
    pn, pt = np.sum(ps * ns, -1), np.sum(ps * ts, -1)
    nn, nt, tt = np.sum(ns * ns, -1), np.sum(ns * ts, -1), np.sum(ts * ts, -1)
    q = pp - a * a
    qa = q * nn - pn * pn
    qb = q * nt - pn * pt
    qc = q * tt - pt * pt
    # C τ² + 2B τ + A = 0, τ = tan ρ; A < 0 (the nadir ray hits), C > 0 (the ray ⟂ nadir misses): one positive root
    tau = (-qb + np.sqrt(qb * qb - qa * qc)) / qc
    return np.degrees(np.arctan(tau))


def horizon_direction(position_km, azimuth_deg, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING,
                      emitting_height_km=0.0) -> np.ndarray:
    """The unit direction (…, 3), in the Earth-centred frame, from P to the horizon at azimuth Ψ [°]:
    ``cos ρ n̂ + sin ρ (cos Ψ Ê + sin Ψ N̂)`` with ρ = ρ(Ψ) of seed 004 eq. 2.22."""
    rho = np.radians(angular_radius_deg(position_km, azimuth_deg, a_km, flattening, emitting_height_km))[..., None]
    nadir, east, north = local_horizon_frame(position_km)
    psi = np.radians(np.asarray(azimuth_deg, float))[..., None]
    return np.cos(rho) * nadir + np.sin(rho) * (np.cos(psi) * east + np.sin(psi) * north)


def spherical_equivalent_radius_deg(position_km, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING,
                                    emitting_height_km=0.0) -> np.ndarray:
    """ρ [°] of the sphere through the sub-satellite point: asin((R(λ) + H)/|P|), R of seed 004 eq. 2.21 at the
    satellite's geocentric latitude — the start of :func:`crossing_phases_oblate`."""
    p = _positions(position_km)
    lam = np.degrees(np.arctan2(p[..., 2], np.hypot(p[..., 0], p[..., 1])))
    r = surface_radius_km(lam, a_km, flattening) + emitting_height_km
    return np.degrees(np.arcsin(np.clip(r / np.linalg.norm(p, axis=-1), -1.0, 1.0)))


def crossing_condition(position_km, direction, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING,
                       emitting_height_km=0.0) -> np.ndarray:
    """sin²α' − (a/|P'|)² for a direction u from P, in coordinates scaled to make the (grown) ellipsoid a sphere of
    radius a (α' the angle between u' and −P'): negative where the ray's line meets the Earth, zero on the horizon
    (seed 004 eqs. 2.13–2.17: the tangency condition), positive where it misses. Smooth in u."""
    p = _positions(position_km)
    u = np.asarray(direction, float)
    a, c, _ = ellipsoid_axes_km(a_km, flattening, emitting_height_km)
    scale = np.array([1.0, 1.0, a / c])
    ps, us = p * scale, u * scale
    pp, uu = np.sum(ps * ps, -1), np.sum(us * us, -1)
    pu = np.sum(ps * us, -1)
    return np.where(pu < 0, 1.0 - pu * pu / (pp * uu), 1.0) - a * a / pp


def crossing_phases_oblate(position_km, body_to_frame, gamma_deg=THESIS_GAMMA_DEG, cone=1,
                           a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING, emitting_height_km=0.0,
                           tolerance_deg=1e-10, max_iterations=60):
    """The phases [°, in [0, 360)] where cone `cone` crosses the horizon of the WGS84 ellipsoid (grown by
    `emitting_height_km`), seen from P (…, 3) [km] with the body frame given by `body_to_frame` (…, 3, 3), the
    rotation taking body vectors to the Earth-centred frame: ``(phase_out, phase_in)`` (leaving the Earth, coming
    back onto it), the conventions of :mod:`calibration.horizon`. P, the rotation, γ and the cone broadcast.

    Seed 004 eqs. 2.10, 2.17 and 2.23 solved together: the scan direction S_k(δ) (eq. 2.5) is tangent to the
    ellipsoid. The tangency condition (:func:`crossing_condition`, a smooth trigonometric function of δ here) is
    solved by Newton steps from the spherical closed form
    (:func:`calibration.horizon.scan.crossing_phases_for_nadir`) with the sphere through the sub-satellite point,
    with a bracketed fallback; exact to `tolerance_deg`. NaN where the cone does not cross the horizon.
    """
    p = _positions(position_km)
    rot = np.asarray(body_to_frame, float)
    if rot.shape[-2:] != (3, 3):
        raise ValueError(f"body_to_frame must have shape (..., 3, 3), got {rot.shape}")
    a, c, _ = ellipsoid_axes_km(a_km, flattening, emitting_height_km)
    _check_outside(p, a, c)
    sign = np.where(np.asarray(cone) == 1, 1.0, -1.0)
    if not np.isin(np.asarray(cone), (1, 2)).all():
        raise ValueError(f"a cone is 1 or 2, got {cone!r}")
    gamma = np.radians(np.asarray(gamma_deg, float))
    nadir_frame = -p / np.linalg.norm(p, axis=-1, keepdims=True)
    nadir_body = np.einsum("...ji,...j->...i", rot, nadir_frame)
    rho0 = spherical_equivalent_radius_deg(p, a_km, flattening, emitting_height_km)
    start_out, start_in = crossing_phases_for_nadir(nadir_body, rho0, gamma_deg, cone)

    # u'(δ) = sin δ·A + cos δ·B + C in coordinates scaled to make the ellipsoid a sphere of radius a
    scale = np.array([1.0, 1.0, a / c])
    ps = p * scale
    axes = rot * scale[:, None]  # the body axes' images, scaled (columns)
    big_a = np.sin(gamma)[..., None] * axes[..., :, 0]
    big_b = np.sin(gamma)[..., None] * axes[..., :, 2]
    big_c = (sign * np.cos(gamma))[..., None] * axes[..., :, 1]
    pp = np.sum(ps * ps, -1)
    pa, pb, pc = (np.sum(ps * v, -1) for v in (big_a, big_b, big_c))
    aa, bb, cc = (np.sum(v * v, -1) for v in (big_a, big_b, big_c))
    ab, ac, bc = np.sum(big_a * big_b, -1), np.sum(big_a * big_c, -1), np.sum(big_b * big_c, -1)
    limit = a * a / pp

    def condition_and_slope(delta_deg):
        d = np.radians(delta_deg)
        sd, cd = np.sin(d), np.cos(d)
        n = pa * sd + pb * cd + pc
        dn = pa * cd - pb * sd
        q = aa * sd * sd + bb * cd * cd + cc + 2.0 * ab * sd * cd + 2.0 * ac * sd + 2.0 * bc * cd
        dq = 2.0 * (aa - bb) * sd * cd + 2.0 * ab * (cd * cd - sd * sd) + 2.0 * ac * cd - 2.0 * bc * sd
        g = np.where(n < 0, 1.0 - n * n / (pp * q), 1.0) - limit
        dg = np.where(n < 0, -(2.0 * n * dn * q - n * n * dq) / (pp * q * q), 0.0)
        return g, np.radians(1.0) * dg  # slope per degree

    return (_solve_phase(condition_and_slope, start_out, +1.0, tolerance_deg, max_iterations),
            _solve_phase(condition_and_slope, start_in, -1.0, tolerance_deg, max_iterations))


def _solve_phase(condition_and_slope, start_deg, rising: float, tolerance_deg: float, max_iterations: int):
    """The root near `start_deg` of the condition that rises (+1: Earth → space) or falls (−1) with δ: Newton steps
    (limited to 2° each), then a bracketed Illinois search where Newton did not settle on a root of the right slope.
    """
    start = np.asarray(start_deg, float)
    ok = np.isfinite(start)
    x = np.where(ok, start, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        for _ in range(12):
            g, dg = condition_and_slope(x)
            step = np.clip(np.where(dg != 0, g / dg, 0.0), -2.0, 2.0)
            x = x - np.where(np.isfinite(step), step, 0.0)
            if np.all(np.abs(step[ok]) < tolerance_deg * 1e-3) if ok.any() else True:
                break
        g, dg = condition_and_slope(x)
        settled = ok & (np.abs(step) < tolerance_deg) & (rising * dg > 0)
    if np.all(settled | ~ok):
        return np.where(ok, np.mod(x, 360.0), np.nan)
    # Fallback: bracket from the start outwards, then Illinois (regula falsi halving a stale end).
    def cond(v):
        return rising * condition_and_slope(v)[0]

    redo = ok & ~settled
    y = np.where(ok, start, 0.0)
    lo, hi = y - 0.5, y + 0.5
    g_lo, g_hi = cond(lo), cond(hi)
    for _ in range(30):
        bad = redo & ~((g_lo <= 0) & (g_hi >= 0))
        if not bad.any():
            break
        lo = np.where(bad & (g_lo > 0), lo - (hi - lo), lo)
        hi = np.where(bad & (g_hi < 0), hi + (hi - lo), hi)
        g_lo, g_hi = cond(lo), cond(hi)
    found = redo & (g_lo <= 0) & (g_hi >= 0)
    side = np.zeros_like(y)
    for _ in range(max_iterations):
        with np.errstate(invalid="ignore", divide="ignore"):
            y = np.where(g_hi != g_lo, (lo * g_hi - hi * g_lo) / (g_hi - g_lo), 0.5 * (lo + hi))
        y = np.clip(y, lo, hi)
        gy = cond(y)
        left = gy < 0
        lo, hi = np.where(left, y, lo), np.where(left, hi, y)
        new_lo, new_hi = np.where(left, gy, g_lo), np.where(left, g_hi, gy)
        new_hi = np.where(left & (side == 1), 0.5 * new_hi, new_hi)
        new_lo = np.where(~left & (side == -1), 0.5 * new_lo, new_lo)
        g_lo, g_hi, side = new_lo, new_hi, np.where(left, 1.0, -1.0)
        if np.all(~found | (hi - lo < tolerance_deg) | (gy == 0)):
            break
    x = np.where(settled, x, np.where(found, y, np.nan))
    return np.where(ok, np.mod(x, 360.0), np.nan)
