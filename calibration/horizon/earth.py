"""The WGS84 Earth: geodetic ↔ Earth-centred coordinates, the tangent altitude of a ray, ray–Earth hits (seed 004
§1-3-3, §2-4-1: eqs. 1.2, 2.9–2.10, 2.21).

Positions are Cartesian in km in any Earth-centred frame whose z axis is the polar axis (ECEF, or ICRF for a
non-rotating snapshot: the ellipsoid is symmetric about z). Every function is vectorised over leading axes: a
position or direction is an array of shape (…, 3) and the results have shape (…).

Heights are **signed distances to the ellipsoid**: outside it the distance to the nearest surface point, which is
exactly the geodetic height; inside it minus the distance to the nearest surface point (the geodetic height, with
its sign, wherever the point is less deep than ~6300 km, i.e. outside the 43-km evolute around the centre). The
signed distance is a convex function of position (the ellipsoid is convex), so along a ray it has a single minimum:
:func:`tangent_altitude_km` returns it — the geodetic altitude of the ray's lowest point when the ray misses the
Earth, minus the depth of its deepest point (measured the same way) when it goes through.

The nearest surface point is found from the meridian ellipse (semi-axes a, c) by the root of
``F(t) = (a ρ/(t + a²))² + (c z/(t + c²))² − 1`` (Eberly, "Distance from a point to an ellipse"; solved in
t + c²), by Newton steps started on the root's left where F is convex and decreasing (monotone convergence),
bisection where that creeps: exact to rounding.
"""

from __future__ import annotations

import numpy as np

from .scan import EQUATORIAL_RADIUS_KM, FLATTENING, POLAR_RADIUS_KM

__all__ = [
    "EQUATORIAL_RADIUS_KM", "FLATTENING", "POLAR_RADIUS_KM",
    "geocentric_latitude_deg", "geodetic_latitude_deg", "surface_radius_km",
    "geodetic_to_ecef_km", "ecef_to_geodetic", "geodetic_height_km", "nearest_surface_point_km",
    "surface_normal", "tangent_altitude_km", "tangent_point_km", "ray_hits_earth",
    "tangent_altitude_sphere_km", "ray_hits_sphere",
]

_NEWTON_STEPS = 12        # Newton steps on F(t): quadratic once close, 4–6 suffice from the first guess
_RAY_ITERATIONS = 60      # safeguarded secant steps on d(height)/ds along a ray


def _vectors(x, name: str) -> np.ndarray:
    v = np.asarray(x, float)
    if v.shape[-1:] != (3,):
        raise ValueError(f"{name} must have shape (..., 3), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} has non-finite components")
    return v


def _unit(x, name: str) -> np.ndarray:
    v = _vectors(x, name)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise ValueError(f"{name} has a zero vector (no direction)")
    return v / norm


def _axes(a_km, c_km) -> tuple[float, float]:
    a, c = float(a_km), float(c_km)
    if not (a > 0 and c > 0 and c <= a):
        raise ValueError(f"an oblate Earth needs 0 < polar radius ≤ equatorial radius, got a={a}, c={c}")
    return a, c


def geocentric_latitude_deg(geodetic_lat_deg, flattening=FLATTENING) -> np.ndarray:
    """Geocentric latitude L_C [°] of a point **on the surface** at geodetic latitude L_D [°]:
    ``tan L_C = (1 − f)² tan L_D`` (seed 004 eq. 1.2). Longitudes are the same in both systems."""
    ld = np.radians(np.asarray(geodetic_lat_deg, float))
    return np.degrees(np.arctan2((1.0 - flattening) ** 2 * np.sin(ld), np.cos(ld)))


def geodetic_latitude_deg(geocentric_lat_deg, flattening=FLATTENING) -> np.ndarray:
    """Geodetic latitude [°] of the surface point at geocentric latitude L_C [°] — seed 004 eq. 1.2 inverted."""
    lc = np.radians(np.asarray(geocentric_lat_deg, float))
    return np.degrees(np.arctan2(np.sin(lc), (1.0 - flattening) ** 2 * np.cos(lc)))


def surface_radius_km(geocentric_lat_deg, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING) -> np.ndarray:
    """The ellipsoid's radius [km] at geocentric latitude λ: ``R = a (1 − f) / √(1 − f (2 − f) cos² λ)``
    (seed 004 eq. 2.21): a at the equator, c = a (1 − f) at the poles."""
    lam = np.radians(np.asarray(geocentric_lat_deg, float))
    return a_km * (1.0 - flattening) / np.sqrt(1.0 - flattening * (2.0 - flattening) * np.cos(lam) ** 2)


def geodetic_to_ecef_km(lat_deg, lon_deg, height_km=0.0, a_km=EQUATORIAL_RADIUS_KM,
                        flattening=FLATTENING) -> np.ndarray:
    """Earth-centred Cartesian position [km], shape (…, 3), of geodetic latitude, longitude [°] and height [km]
    above the WGS84 ellipsoid (seed 004 eqs. 1.2, 2.9: the surface point plus the height along its normal)."""
    lat, lon = np.radians(np.asarray(lat_deg, float)), np.radians(np.asarray(lon_deg, float))
    lat, lon, h = np.broadcast_arrays(lat, lon, np.asarray(height_km, float))
    e2 = flattening * (2.0 - flattening)
    n = a_km / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)  # prime-vertical radius of curvature
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - e2) + h) * np.sin(lat)], axis=-1)


def _meridian_nearest(rho, z, a, c):
    """Nearest point (x_rho, x_z) on the meridian ellipse x²/a² + z²/c² = 1 to (rho ≥ 0, z) and the signed
    distance (negative inside). Vectorised.

    Solved in q = t + c² > 0 (no cancellation near F's pole): ``G(q) = (aρ/(q + e))² + (c|z|/q)² − 1``,
    e = a² − c²; G is convex and decreasing for q > 0 and its root gives the nearest point
    (a²ρ/(q + e), c²|z|/q).
    """
    az = np.abs(z)
    e = a * a - c * c
    # G ≥ 0 at q_left (one of its terms is 1 there) and G ≤ 0 at q_right (Eberly's bounds).
    q_left = np.maximum(a * rho - e, c * az)
    q_right = np.hypot(a * rho, c * az)
    r = np.hypot(rho, z)
    lam = np.arctan2(az, rho)
    radius = a * c / np.sqrt((c * np.cos(lam)) ** 2 + (a * np.sin(lam)) ** 2)
    q = np.clip((r - radius) * radius + c * c, q_left, q_right)  # a sphere's t = h·R: a close first guess
    with np.errstate(invalid="ignore", divide="ignore"):
        for i in range(_NEWTON_STEPS):
            u, v = a * rho / (q + e), c * az / q
            g = u * u + v * v - 1.0
            dg = -2.0 * (u * u / (q + e) + v * v / q)
            q_new = q - np.where(dg < 0, g / dg, 0.0)
            # The first step from a guess right of the root may overshoot below q_left: clip; from there on the
            # iterates increase monotonically to the root (G convex and decreasing).
            q = np.maximum(q_new, q_left) if i == 0 else np.where(np.isfinite(q_new), q_new, q)
        # Deep inside, near the axis, the root can sit far from a start close to G's pole where Newton creeps
        # (×1.5 a step): finish those by bisection on [q_left, q_right].
        u, v = a * rho / (q + e), c * az / q
        slow = ~(np.abs(u * u + v * v - 1.0) < 1e-13) & (q_left > 0)
        if np.any(slow):
            shape = q.shape
            lo, hi = np.broadcast_to(q_left, shape)[slow], np.broadcast_to(q_right, shape)[slow]
            rs, zs = np.broadcast_to(rho, shape)[slow], np.broadcast_to(az, shape)[slow]
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                g = (a * rs / (mid + e)) ** 2 + (c * zs / mid) ** 2 - 1.0
                lo, hi = np.where(g > 0, mid, lo), np.where(g > 0, hi, mid)
            q = np.array(q, copy=True)
            q[slow] = 0.5 * (lo + hi)
        x_rho = a * a * rho / (q + e)
        x_z = c * c * az / q
        # On the equatorial plane deep inside (ρ < e/a) the nearest points are off the plane (Eberly).
        medial = (az == 0) & (a * rho < e)
        x_rho_m = a * a * rho / e
        x_z_m = c * np.sqrt(np.clip(1.0 - (x_rho_m / a) ** 2, 0.0, None))
    x_rho = np.where(medial, x_rho_m, x_rho)
    x_z = np.where(medial, x_z_m, x_z)
    inside = (rho / a) ** 2 + (z / c) ** 2 < 1.0
    dist = np.hypot(rho - x_rho, az - x_z)
    return x_rho, np.copysign(x_z, z), np.where(inside, -dist, dist)


def nearest_surface_point_km(position_km, a_km=EQUATORIAL_RADIUS_KM, c_km=POLAR_RADIUS_KM):
    """The nearest point on the ellipsoid of semi-axes a (equatorial), c (polar) [km] to `position_km` (…, 3), and the
    signed distance to it [km] (negative inside): ``(point (…, 3), distance (…))`` — seed 004 eq. 2.10's surface.
    Outside the ellipsoid the distance is the geodetic height and the point the foot of the normal through it."""
    p = _vectors(position_km, "position_km")
    a, c = _axes(a_km, c_km)
    rho = np.hypot(p[..., 0], p[..., 1])
    x_rho, x_z, dist = _meridian_nearest(rho, p[..., 2], a, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(rho > 0, x_rho / rho, 0.0)
    return np.stack([p[..., 0] * scale, p[..., 1] * scale, x_z], axis=-1), dist


def surface_normal(surface_point_km, a_km=EQUATORIAL_RADIUS_KM, c_km=POLAR_RADIUS_KM) -> np.ndarray:
    """The outward unit normal of the ellipsoid at a surface point (…, 3): along (x/a², y/a², z/c²)
    (seed 004 eq. 2.11, normalised exactly where the printed normalisation is not)."""
    p = _vectors(surface_point_km, "surface_point_km")
    a, c = _axes(a_km, c_km)
    n = p / np.array([a * a, a * a, c * c])
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def ecef_to_geodetic(position_km, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING):
    """Geodetic latitude [°], longitude [°] and height [km] of Earth-centred positions (…, 3) [km] (seed 004 eqs.
    1.2, 2.9): the latitude is that of the surface normal at the nearest surface point, the height the signed distance
    to it. Exact to rounding at any height (no series); the inverse of :func:`geodetic_to_ecef_km`."""
    p = _vectors(position_km, "position_km")
    a = float(a_km)
    c = a * (1.0 - flattening)
    point, height = nearest_surface_point_km(p, a, c)
    n = point / np.array([a * a, a * a, c * c])
    lat = np.degrees(np.arctan2(n[..., 2], np.hypot(n[..., 0], n[..., 1])))
    lon = np.degrees(np.arctan2(p[..., 1], p[..., 0]))
    return lat, lon, height


def geodetic_height_km(position_km, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING) -> np.ndarray:
    """Geodetic height [km] above the WGS84 ellipsoid (signed distance, negative inside) of positions (…, 3)
    (seed 004 eq. 2.10's surface)."""
    a = float(a_km)
    return nearest_surface_point_km(position_km, a, a * (1.0 - flattening))[1]


def _height_and_slope(p, u, s, a, c):
    q = p + s[..., None] * u
    point, height = nearest_surface_point_km(q, a, c)
    return height, np.sum(u * surface_normal(point, a, c), axis=-1)


def _ray_lowest(position_km, direction, a_km, c_km):
    """(s*, height at s*) of the lowest point of P + s·u, s ≥ 0, over the ellipsoid (a, c)."""
    p = _vectors(position_km, "position_km")
    u = _unit(direction, "direction")
    p, u = np.broadcast_arrays(p, u)
    a, c = _axes(a_km, c_km)
    # The height's slope along the ray is u·N(nearest point): monotone in s (convexity). For a sphere the lowest
    # point is the closest approach to the centre, s0 = −P·u; the ellipsoid moves it by less than ~(a − c)·2.
    s0 = -np.sum(p * u, axis=-1)
    margin = 10.0 * (a - c) + 50.0
    lo = np.maximum(s0 - margin, 0.0)
    hi = np.maximum(s0 + margin, 0.0)
    _, g_lo = _height_and_slope(p, u, lo, a, c)
    back = (g_lo >= 0) & (lo > 0)  # the bracket started right of the minimum: start it at the ray's origin
    lo = np.where(back, 0.0, lo)
    _, g_lo = _height_and_slope(p, u, lo, a, c)
    _, g_hi = _height_and_slope(p, u, hi, a, c)
    for _ in range(40):  # widen a bracket that does not yet hold the sign change (never needed in practice)
        short = (g_hi <= 0) & (g_lo < 0)
        if not short.any():
            break
        hi = np.where(short, hi + 2.0 * (hi - lo) + margin, hi)
        _, g_hi = _height_and_slope(p, u, hi, a, c)
    at_start = g_lo >= 0  # the ray climbs from its start: the start is the lowest point
    # Illinois (safeguarded regula falsi) on the slope: superlinear, and the bracket always holds the root.
    s = lo.copy()
    side = np.zeros_like(s)
    for _ in range(_RAY_ITERATIONS):
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(g_hi != g_lo, (lo * g_hi - hi * g_lo) / (g_hi - g_lo), 0.5 * (lo + hi))
        s = np.clip(s, lo, hi)
        _, g = _height_and_slope(p, u, s, a, c)
        left = g < 0
        lo, g_lo_new = np.where(left, s, lo), np.where(left, g, g_lo)
        hi, g_hi_new = np.where(left, hi, s), np.where(left, g_hi, g)
        # Illinois: halve the slope kept at the end that did not move twice in a row
        g_hi_new = np.where(left & (side == 1), 0.5 * g_hi_new, g_hi_new)
        g_lo_new = np.where(~left & (side == -1), 0.5 * g_lo_new, g_lo_new)
        g_lo, g_hi = g_lo_new, g_hi_new
        side = np.where(left, 1, -1)
        if np.all((hi - lo < 1e-7) | at_start | (g == 0)):
            break
    s = np.where(at_start, 0.0, s)
    height, _ = _height_and_slope(p, u, s, a, c)
    return s, height


def tangent_altitude_km(position_km, direction, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING) -> np.ndarray:
    """The tangent altitude [km] of the ray P + s·u (s ≥ 0) over the WGS84 ellipsoid: the geodetic altitude of its
    lowest point when it misses the Earth; minus the depth of its deepest point (the signed distance to the surface,
    the same measure) when it goes through; the start's own height when the ray climbs from P. Vectorised over
    (…, 3); exact to ~1e-9 km (seed 004 §2-4-1, the grazing altitude of STK's "Boresight grazing" report, App. 1)."""
    a = float(a_km)
    return _ray_lowest(position_km, direction, a, a * (1.0 - flattening))[1]


def tangent_point_km(position_km, direction, a_km=EQUATORIAL_RADIUS_KM, flattening=FLATTENING):
    """The lowest point of the ray P + s·u (s ≥ 0) and its range: ``(point (…, 3) [km], s (…) [km])`` — the ray's
    tangent point for :func:`tangent_altitude_km` (seed 004 App. 1, "Boresight grazing LLA")."""
    a = float(a_km)
    p, u = _vectors(position_km, "position_km"), _unit(direction, "direction")
    s = _ray_lowest(p, u, a, a * (1.0 - flattening))[0]
    p, u = np.broadcast_arrays(p, u)
    return p + s[..., None] * u, s


def ray_hits_earth(position_km, direction, height_km=0.0, a_km=EQUATORIAL_RADIUS_KM,
                   flattening=FLATTENING) -> np.ndarray:
    """True where the ray P + s·u (s ≥ 0) meets the Earth grown by `height_km`, i.e. the surface of geodetic height
    `height_km` (an emitting layer: seed 004 eq. 2.3's H_eq): where its tangent altitude is ≤ `height_km`."""
    return tangent_altitude_km(position_km, direction, a_km, flattening) <= np.asarray(height_km, float)


def tangent_altitude_sphere_km(position_km, direction, radius_km=EQUATORIAL_RADIUS_KM) -> np.ndarray:
    """The tangent altitude [km] of the ray P + s·u (s ≥ 0) over a sphere of `radius_km` centred on the origin:
    |P + s₀u| − R at s₀ = max(0, −P·u) (negative: minus the depth of the chord's deepest point) — seed 004 eq. 2.3's
    spherical Earth."""
    p = _vectors(position_km, "position_km")
    u = _unit(direction, "direction")
    p, u = np.broadcast_arrays(p, u)
    s0 = np.maximum(-np.sum(p * u, axis=-1), 0.0)
    return np.linalg.norm(p + s0[..., None] * u, axis=-1) - radius_km


def ray_hits_sphere(position_km, direction, radius_km=EQUATORIAL_RADIUS_KM, height_km=0.0) -> np.ndarray:
    """True where the ray P + s·u (s ≥ 0) meets the sphere of radius R + `height_km` (seed 004 eq. 2.3)."""
    return tangent_altitude_sphere_km(position_km, direction, radius_km) <= np.asarray(height_km, float)
