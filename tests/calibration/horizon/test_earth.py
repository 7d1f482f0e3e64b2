"""The WGS84 Earth (calibration.horizon.earth): geodetic ↔ Earth-centred coordinates (seed 004 eqs. 1.2, 2.21) and
the tangent altitude of a ray, against a brute-force dense search along the ray."""

import numpy as np
import pytest

from calibration.horizon.earth import (
    EQUATORIAL_RADIUS_KM,
    POLAR_RADIUS_KM,
    ecef_to_geodetic,
    geocentric_latitude_deg,
    geodetic_height_km,
    geodetic_latitude_deg,
    geodetic_to_ecef_km,
    nearest_surface_point_km,
    ray_hits_earth,
    ray_hits_sphere,
    surface_radius_km,
    tangent_altitude_km,
    tangent_altitude_sphere_km,
    tangent_point_km,
)


def _limb_rays(n, seed):
    """Satellites at 300–1500 km anywhere, looking within ±3° of the spherical horizon at a random azimuth."""
    rng = np.random.default_rng(seed)
    p = geodetic_to_ecef_km(rng.uniform(-89, 89, n), rng.uniform(-180, 180, n), rng.uniform(300, 1500, n))
    r = np.linalg.norm(p, axis=1)
    nadir = -p / r[:, None]
    t1 = np.cross(nadir, [0.0, 0.0, 1.0])
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(nadir, t1)
    rho = np.arcsin(6370.0 / r) + np.radians(rng.uniform(-3, 3, n))
    az = rng.uniform(0, 2 * np.pi, n)
    u = np.cos(rho)[:, None] * nadir + np.sin(rho)[:, None] * (np.cos(az)[:, None] * t1 + np.sin(az)[:, None] * t2)
    return p, u


def test_geodetic_round_trip_is_exact_from_below_the_surface_to_geostationary_height():
    # geodetic_to_ecef_km is the textbook closed form; ecef_to_geodetic the nearest-point solution: independent.
    rng = np.random.default_rng(0)
    lat, lon, h = rng.uniform(-90, 90, 2000), rng.uniform(-180, 180, 2000), rng.uniform(-100, 36000, 2000)
    back_lat, back_lon, back_h = ecef_to_geodetic(geodetic_to_ecef_km(lat, lon, h))
    assert np.abs(back_lat - lat).max() < 1e-10
    assert np.abs(back_h - h).max() < 1e-8  # km: 10 µm
    assert np.abs(((back_lon - lon + 180) % 360 - 180)[np.abs(lat) < 89.99]).max() < 1e-10


def test_eq_1_2_and_eq_2_21_describe_the_surface_points():
    lat = np.linspace(-90, 90, 181)
    p = geodetic_to_ecef_km(lat, 30.0, 0.0)
    geocentric = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    assert np.allclose(geocentric_latitude_deg(lat), geocentric, atol=1e-12)  # eq. 1.2
    assert np.allclose(geodetic_latitude_deg(geocentric), lat, atol=1e-12)
    assert np.allclose(surface_radius_km(geocentric), np.linalg.norm(p, axis=1), atol=1e-9)  # eq. 2.21
    assert surface_radius_km(0.0) == pytest.approx(EQUATORIAL_RADIUS_KM, abs=1e-12)
    assert surface_radius_km(90.0) == pytest.approx(POLAR_RADIUS_KM, abs=1e-9)


def test_nearest_point_deep_inside_the_earth_is_the_nearest():
    # Inside the 43-km evolute the nearest point is off the equator (several normals pass through the point).
    pts = np.array([[0, 0, 0], [0, 1e-6, 0], [0, 7e-6, 1e-9], [30, 0, 1e-3], [0, 0, 7000.0]])
    near, dist = nearest_surface_point_km(pts)
    # brute force on the meridian ellipse
    t = np.linspace(0, np.pi / 2, 1_000_001)
    ell = np.stack([EQUATORIAL_RADIUS_KM * np.cos(t), POLAR_RADIUS_KM * np.sin(t)], -1)
    for p, d in zip(pts, dist):
        q = np.array([np.hypot(p[0], p[1]), abs(p[2])])
        assert abs(abs(d) - np.min(np.linalg.norm(ell - q, axis=1))) < 1e-5
    assert dist[0] == pytest.approx(-POLAR_RADIUS_KM, abs=1e-9)
    assert dist[-1] == pytest.approx(7000.0 - POLAR_RADIUS_KM, abs=1e-9)


def test_tangent_altitude_matches_a_dense_search_along_the_ray_to_a_micrometre():
    # The brief's bar is 1 m; the nearest-point solution is exact to rounding, so 1e-6 km is asserted.
    p, u = _limb_rays(24, seed=1)
    ours = tangent_altitude_km(p, u)
    for i in range(len(p)):
        s = np.linspace(0.0, 8000.0, 40_001)  # 200 m steps, then refined around the minimum (convex: one)
        h = geodetic_height_km(p[i] + s[:, None] * u[i])
        j = int(np.argmin(h))
        fine = np.linspace(s[max(j - 1, 0)], s[min(j + 1, s.size - 1)], 4_001)
        brute = geodetic_height_km(p[i] + fine[:, None] * u[i]).min()
        assert abs(ours[i] - brute) < 1e-6, i
    assert ours.min() < -100 and ours.max() > 100  # both hitting and missing rays were covered


def test_tangent_point_is_the_lowest_point_and_the_ray_is_level_there():
    p, u = _limb_rays(20, seed=2)
    point, s = tangent_point_km(p, u)
    near, h = nearest_surface_point_km(point)
    normal = near / np.array([EQUATORIAL_RADIUS_KM, EQUATORIAL_RADIUS_KM, POLAR_RADIUS_KM]) ** 2
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    assert np.abs(np.sum(normal * u, axis=1)).max() < 1e-9  # d(height)/ds = 0 at the tangent point
    assert np.allclose(h, tangent_altitude_km(p, u), atol=1e-12)
    assert (s > 0).all()


def test_rays_that_climb_or_pass_through_the_centre():
    p = geodetic_to_ecef_km(30.0, 10.0, 500.0)
    assert tangent_altitude_km(p, p) == pytest.approx(500.0, abs=1e-9)  # zenith: the start is the lowest point
    # through the centre the deepest point is the centre, at the polar radius from the nearest surface (the poles)
    assert tangent_altitude_km(p, -p) == pytest.approx(-POLAR_RADIUS_KM, abs=1e-6)
    assert tangent_altitude_km([0, 0, 7000.0], [0, 1e-9, -1.0]) == pytest.approx(-POLAR_RADIUS_KM, abs=1e-6)


def test_ray_hits_earth_and_an_emitting_layer():
    p, u = _limb_rays(200, seed=3)
    h = tangent_altitude_km(p, u)
    assert np.array_equal(ray_hits_earth(p, u), h <= 0)
    assert np.array_equal(ray_hits_earth(p, u, height_km=40.0), h <= 40.0)
    assert (ray_hits_earth(p, u, 40.0) >= ray_hits_earth(p, u)).all()


def test_spherical_variants():
    p = np.array([7000.0, 0, 0])
    assert tangent_altitude_sphere_km(p, [-1, 0, 0], 6378.0) == pytest.approx(-6378.0)
    u = np.array([-np.sqrt(1 - (6400 / 7000) ** 2), 6400 / 7000, 0])
    assert tangent_altitude_sphere_km(p, u, 6378.0) == pytest.approx(22.0, abs=1e-9)
    assert ray_hits_sphere(p, u, 6378.0, height_km=22.0 + 1e-9)
    assert not ray_hits_sphere(p, u, 6378.0, height_km=21.9)
    # the WGS84 tangent altitude of an equatorial ray in the equatorial plane is the sphere's of radius a
    assert tangent_altitude_km(p, u) == pytest.approx(tangent_altitude_sphere_km(p, u), abs=1e-9)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\)"):
        tangent_altitude_km([1.0, 2.0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="zero vector"):
        tangent_altitude_km([7000.0, 0, 0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="non-finite"):
        geodetic_height_km([np.nan, 0, 0])
