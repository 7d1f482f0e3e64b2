"""The WGS84 horizon (calibration.horizon.oblate): seed 004 eq. 2.22 against a direct tangent-ray computation, the
horizon plane of eq. 2.17, the emitting layer, and the cone's crossings of the oblate horizon."""

import numpy as np
import pytest

from calibration.horizon.earth import geodetic_to_ecef_km, tangent_altitude_km
from calibration.horizon.oblate import (
    angular_radius_deg,
    crossing_phases_oblate,
    horizon_direction,
    horizon_plane,
    local_horizon_frame,
    tangent_angle_deg,
)
from calibration.horizon.scan import body_to_orbit, crossing_phases, earth_angular_radius_deg, scan_vector


def _observers(n, seed, low=200.0, high=2000.0):
    rng = np.random.default_rng(seed)
    p = geodetic_to_ecef_km(rng.uniform(-89, 89, n), rng.uniform(-180, 180, n), rng.uniform(low, high, n))
    return p, rng.uniform(0, 360, n)


def _nadir_pointing(p):
    """Body → Earth frame of a body on the geocentric orbit frame flying north (X_r = local North)."""
    nadir, _, north = local_horizon_frame(p)
    return np.stack([north, np.cross(nadir, north), nadir], axis=-1)


def test_eq_2_22_is_exact_against_the_direct_tangent_ray():
    # The digest found 3e-11°; the direct form solves the tangency in scaled coordinates (a quadratic in tan ρ).
    p, psi = _observers(2000, seed=0)
    assert np.abs(angular_radius_deg(p, psi) - tangent_angle_deg(p, psi)).max() < 1e-9
    # and the direction at ρ(Ψ) grazes the ellipsoid: the tangent altitude (an independent nearest-point solver) is 0
    assert np.abs(tangent_altitude_km(p, horizon_direction(p, psi))).max() < 1e-8


def test_digest_table_of_rho_ranges_at_500_km():
    # digest §3.2 [derived]: ρ ranges over Ψ "at h = 500 km", printed to 1e-3°; they are for |P| = a + 500 km at
    # geocentric latitude λ (at a geodetic height of 500 km the 45° range is 67.836–68.167°)
    psi = np.linspace(0, 360, 3601)
    d = 6378.137 + 500.0
    for lat, low, high in ((0.0, 67.952, 68.019), (45.0, 67.617, 67.947), (80.0, 67.569, 67.681)):
        lam = np.radians(lat)
        rho = angular_radius_deg([d * np.cos(lam), 0.0, d * np.sin(lam)], psi)
        assert rho.min() == pytest.approx(low, abs=6e-4) and rho.max() == pytest.approx(high, abs=6e-4)
    assert earth_angular_radius_deg(500.0) == pytest.approx(68.019, abs=5e-4)


def test_horizon_points_lie_on_the_eq_2_17_plane():
    p, psi = _observers(200, seed=1)
    u = horizon_direction(p, psi)
    # the tangent point: along u at the range where the ray grazes (|P|² − a²-ish): find it by projection
    from calibration.horizon.earth import tangent_point_km
    point, _ = tangent_point_km(p, u)
    normal, distance = horizon_plane(p)
    assert np.abs(np.sum(normal * point, axis=1) - distance).max() < 1e-6  # km
    # the normal depends on the direction of P only (seed 004 §2-4-1)
    assert np.allclose(horizon_plane(2.0 * p)[0], normal, atol=1e-15)


def test_a_grown_ellipsoid_is_the_constant_geodetic_height_surface_to_centimetres():
    p, psi = _observers(500, seed=2, low=300.0, high=900.0)
    for height in (20.0, 40.0):
        u = horizon_direction(p, psi, emitting_height_km=height)
        assert np.abs(tangent_altitude_km(p, u) - height).max() < 1e-4  # 10 cm; measured 6 cm at 40 km


def test_crossings_of_a_sphere_equal_the_closed_form():
    p = geodetic_to_ecef_km(40.0, 10.0, 505.0)
    rot = _nadir_pointing(p) @ body_to_orbit(1.3, -0.7)
    r = np.linalg.norm(p)
    rho = np.degrees(np.arcsin(6378.137 / r))
    for cone in (1, 2):
        ours = crossing_phases_oblate(p, rot, 70.0, cone, a_km=6378.137, flattening=0.0)
        closed = crossing_phases(1.3, -0.7, rho, 70.0, cone)
        assert np.allclose(ours, closed, atol=1e-9)


def test_oblate_crossings_graze_the_ellipsoid_and_the_edges_go_the_right_way():
    p, _ = _observers(40, seed=3, low=400.0, high=900.0)
    rng = np.random.default_rng(4)
    roll, pitch = rng.uniform(-10, 10, 40), rng.uniform(-10, 10, 40)
    rot = _nadir_pointing(p) @ body_to_orbit(roll, pitch)
    for cone in (1, 2):
        out, inn = crossing_phases_oblate(p, rot, 70.0, cone)
        for phase, after in ((out, +1), (inn, -1)):
            u = np.einsum("nij,nj->ni", rot, scan_vector(phase, 70.0, cone))
            assert np.abs(tangent_altitude_km(p, u)).max() < 1e-7  # km: the crossings are exact
            later = np.einsum("nij,nj->ni", rot, scan_vector(phase + 0.01, 70.0, cone))
            assert (np.sign(tangent_altitude_km(p, later)) == after).all()  # out: onto space; in: onto the Earth


def test_oblateness_moves_crossings_by_up_to_a_degree():
    p = geodetic_to_ecef_km(45.0, 0.0, 500.0)
    rot = _nadir_pointing(p)
    out, inn = crossing_phases_oblate(p, rot, 70.0, 1)
    sphere_out, sphere_in = crossing_phases(0.0, 0.0, earth_angular_radius_deg(500.0), 70.0, 1)
    assert 0.05 < abs(out - sphere_out) < 1.0 and 0.05 < abs(inn - sphere_in) < 1.0


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="above the Earth"):
        angular_radius_deg([6000.0, 0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="cone is 1 or 2"):
        crossing_phases_oblate(geodetic_to_ecef_km(0, 0, 500), np.eye(3), 70.0, 3)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
        crossing_phases_oblate(geodetic_to_ecef_km(0, 0, 500), np.eye(2), 70.0, 1)
