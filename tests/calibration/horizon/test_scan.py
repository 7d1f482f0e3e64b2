"""The cone scan's closed form on a spherical Earth (calibration.horizon.scan): against a brute-force phase search on
S_k(δ)·n = cos ρ, seed 004 eq. 2.7 as corrected (and why the printed form cannot hold), and the digest's check."""

import numpy as np
import pytest

from calibration.horizon.attitude import solve_spherical
from calibration.horizon.scan import (
    crossing_phases,
    earth_angular_radius_deg,
    nadir_in_body,
    phase_to_time_s,
    roll_pitch_of_nadir,
    scan_vector,
)


def test_closed_form_against_a_brute_force_phase_search():
    # 1e-6° steps around a 0.01° coarse search: the brute force is good to ~1e-6°, the bar here.
    rng = np.random.default_rng(0)
    fine = np.arange(-0.02, 0.02, 1e-6)
    for roll, pitch, alt, cone in zip(rng.uniform(-33, 33, 6), rng.uniform(-17, 17, 6), rng.uniform(300, 1500, 6),
                                      (1, 2, 1, 2, 1, 2)):
        rho = earth_angular_radius_deg(alt)
        f = scan_vector(np.arange(0, 360, 0.01), 70.0, cone) @ nadir_in_body(roll, pitch) - np.cos(np.radians(rho))
        changes = np.flatnonzero(np.sign(f[1:]) != np.sign(f[:-1])) * 0.01
        assert changes.size == 2
        out, inn = crossing_phases(roll, pitch, rho, 70.0, cone)
        for coarse in changes:
            g = scan_vector(coarse + fine, 70.0, cone) @ nadir_in_body(roll, pitch) - np.cos(np.radians(rho))
            brute = coarse + fine[np.argmin(np.abs(g))]
            assert min(abs(brute - out), abs(brute - inn)) < 2e-6
        # out leaves the Earth with increasing phase, in comes back onto it
        on_earth = scan_vector([out - 0.01, inn + 0.01], 70.0, cone) @ nadir_in_body(roll, pitch)
        assert (on_earth > np.cos(np.radians(rho))).all()


def test_eq_2_7_corrected_holds_at_the_crossings_and_the_printed_form_has_no_crossing():
    roll, pitch, rho, gamma = 1.3, -0.7, earth_angular_radius_deg(504.652), 70.0
    phi, theta, g = np.radians(roll), np.radians(pitch), np.radians(gamma)
    for cone, s in ((1, 1.0), (2, -1.0)):
        for delta in np.radians(crossing_phases(roll, pitch, rho, gamma, cone)):
            corrected = (-np.sin(theta) * np.sin(g) * np.sin(delta) + s * np.sin(phi) * np.cos(theta) * np.cos(g)
                         + np.cos(phi) * np.cos(theta) * np.sin(g) * np.cos(delta))
            assert corrected == pytest.approx(np.cos(np.radians(rho)), abs=1e-14)
    # as printed (cos γ in the last term), zero attitude at 504.652 km needs cos δ = cos ρ / cos γ = 1.099 > 1
    assert np.cos(np.radians(rho)) / np.cos(g) == pytest.approx(1.099, abs=5e-4)


def test_zero_attitude_crossing_time_is_the_digests():
    rho = earth_angular_radius_deg(504.652)
    assert rho == pytest.approx(67.923, abs=5e-4)
    out, inn = crossing_phases(0.0, 0.0, rho)
    assert out == pytest.approx(66.423, abs=5e-4)
    assert phase_to_time_s(out) == pytest.approx(0.18451, abs=5e-6)
    assert out + inn == pytest.approx(360.0, abs=1e-12)  # the chord is centred on δ = 0 at zero attitude


def test_roll_pitch_of_nadir_keeps_the_sign_of_a_negative_roll():
    for roll, pitch in ((-12.0, 5.0), (30.0, -16.0), (-33.0, -17.0)):
        assert np.allclose(roll_pitch_of_nadir(nadir_in_body(roll, pitch)), (roll, pitch), atol=1e-12)


def test_digest_check_least_squares_recovers_roll_pitch_and_rho():
    # digest §2.5: φ = 1.3°, θ = −0.7°, h = 504.652 km, 4 crossings → roll/pitch to 1e-9°, ρ to 1e-7°
    rho = earth_angular_radius_deg(504.652)
    (o1, i1), (o2, i2) = crossing_phases(1.3, -0.7, rho, 70.0, 1), crossing_phases(1.3, -0.7, rho, 70.0, 2)
    sol = solve_spherical((o1, o2), (i1, i2), initial=(0.0, 0.0, 68.0))  # from afar, not the closed form
    assert sol.roll_deg == pytest.approx(1.3, abs=1e-9) and sol.pitch_deg == pytest.approx(-0.7, abs=1e-9)
    assert sol.rho_deg == pytest.approx(rho, abs=1e-7)
    assert sol.altitude_km == pytest.approx(504.652, abs=1e-6)
    # the chord-width identity (cos w2 − cos w1)/(cos w2 + cos w1) = sin φ cos θ cos γ / cos ρ
    w1, w2 = np.radians((o1 - i1) % 360 / 2), np.radians((o2 - i2) % 360 / 2)
    lhs = (np.cos(w2) - np.cos(w1)) / (np.cos(w2) + np.cos(w1))
    rhs = np.sin(np.radians(1.3)) * np.cos(np.radians(0.7)) * np.cos(np.radians(70)) / np.cos(np.radians(rho))
    assert lhs == pytest.approx(rhs, abs=1e-14)
