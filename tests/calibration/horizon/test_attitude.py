"""Roll and pitch from crossings (calibration.horizon.attitude): the spherical closed form and least squares with 2,
3 and 4 crossings, the thesis' steepest descent with an Armijo search, the Â method of seed 004 eqs. 2.23–2.26 and its
limits, the Wahba completion, and the oblate solver with the position known."""

import numpy as np
import pytest

from calibration.horizon.attitude import (
    attitude_from_crossing_vectors,
    roll_pitch_from_spin_axis,
    solve_oblate,
    solve_spherical,
    spherical_closed_form,
    spin_axis_from_crossings,
)
from calibration.horizon.oblate import crossing_phases_oblate
from calibration.horizon.orbit import thesis_window_state
from calibration.horizon.scan import body_to_orbit, crossing_phases, earth_angular_radius_deg, scan_vector

RHO = earth_angular_radius_deg(504.652)


def _phases(roll, pitch, rho=RHO, gamma=(70.0, 70.0)):
    (o1, i1), (o2, i2) = crossing_phases(roll, pitch, rho, gamma[0], 1), crossing_phases(roll, pitch, rho, gamma[1], 2)
    return (o1, o2), (i1, i2)


@pytest.mark.parametrize("roll, pitch", [(1.3, -0.7), (-25.0, 12.0), (30.0, 16.5), (-0.01, 0.002)])
def test_closed_form_is_exact_on_noise_free_crossings(roll, pitch):
    out, inn = _phases(roll, pitch)
    r, p, rho = spherical_closed_form(out, inn)
    assert (r, p, rho) == pytest.approx((roll, pitch, RHO), abs=1e-10)
    # one cone and ρ known
    r, p, _ = spherical_closed_form((out[0], np.nan), (inn[0], np.nan), rho_deg=RHO)
    assert (r, p) == pytest.approx((roll, pitch), abs=1e-10)
    # two cones of different half-angles
    out, inn = _phases(roll, pitch, gamma=(70.03, 69.98))
    assert spherical_closed_form(out, inn, gamma_deg=(70.03, 69.98)) == pytest.approx((roll, pitch, RHO), abs=1e-10)


def test_least_squares_with_2_3_and_4_crossings():
    out, inn = _phases(-4.0, 2.5)
    two = solve_spherical((out[0], np.nan), (inn[0], np.nan), rho_deg=RHO)
    three = solve_spherical(out, (inn[0], np.nan))  # one crossing blanked (Sun/Moon): ρ still solved
    four = solve_spherical(out, inn)
    for sol, n in ((two, 2), (three, 3), (four, 4)):
        assert sol.n_crossings == n and sol.converged and not sol.warnings
        assert (sol.roll_deg, sol.pitch_deg) == pytest.approx((-4.0, 2.5), abs=1e-9)
        assert sol.condition_number < 100
    assert three.rho_deg == pytest.approx(RHO, abs=1e-9)


def test_steepest_descent_with_armijo_converges_and_reports_its_iterations():
    out, inn = _phases(1.3, -0.7)
    sd = solve_spherical(out, inn, method="steepest-descent", initial=(0.0, 0.0, 68.0))
    assert sd.converged and sd.iterations > 10  # the digest's run took 94; it is slow but gets there
    assert (sd.roll_deg, sd.pitch_deg, sd.rho_deg) == pytest.approx((1.3, -0.7, RHO), abs=1e-8)
    lm = solve_spherical(out, inn, initial=(0.0, 0.0, 68.0))
    assert lm.iterations < sd.iterations


def test_inconsistent_crossings_and_too_few_are_reported():
    out, inn = _phases(1.3, -0.7)
    bad = solve_spherical((out[0] + 0.5, out[1]), inn)
    assert any("do not fit" in w for w in bad.warnings)
    with pytest.raises(ValueError, match="cannot give 3 unknowns"):
        solve_spherical((out[0], np.nan), (inn[0], np.nan))
    with pytest.raises(ValueError, match="method"):
        solve_spherical(out, inn, method="newton")
    with pytest.raises(ValueError, match="one out and one in"):
        solve_spherical((1.0, 2.0, 3.0), inn)


def _orbit_crossing_vectors(roll, pitch, rho=RHO):
    """Crossing unit vectors in the orbit frame (where nadir is ẑ) for a spherical Earth."""
    rot = body_to_orbit(roll, pitch)
    phases, cones = [], []
    for cone in (1, 2):
        phases += list(crossing_phases(roll, pitch, rho, 70.0, cone))
        cones += [cone, cone]
    h = np.einsum("ij,nj->ni", rot, scan_vector(np.array(phases), 70.0, np.array(cones)))
    return h, np.array(phases), np.array(cones)


def test_the_a_hat_method_recovers_the_spin_axis_and_roll_but_pitch_only_through_roll():
    h, phases, cones = _orbit_crossing_vectors(-12.0, 4.0)
    assert np.allclose(h @ [0, 0, 1.0], np.cos(np.radians(RHO)), atol=1e-12)  # all on the horizon cone
    axis, cond, resid = spin_axis_from_crossings(h[:3], cones[:3])  # 3 crossings: the thesis' linear system
    assert np.allclose(axis, body_to_orbit(-12.0, 4.0) @ [0, 1.0, 0], atol=1e-12)
    assert roll_pitch_from_spin_axis(axis) == pytest.approx((-12.0, 4.0), abs=1e-9)  # atan2: negative roll kept
    axis4, _, _ = spin_axis_from_crossings(h, cones)
    assert np.allclose(axis4, axis, atol=1e-12)
    # pitch turns the scan about its own axis: at zero roll Â is the same for any pitch
    a0, _, _ = spin_axis_from_crossings(*_orbit_crossing_vectors(0.0, 0.0)[::2])
    a5, _, _ = spin_axis_from_crossings(*_orbit_crossing_vectors(0.0, 5.0)[::2])
    assert np.allclose(a0, a5, atol=1e-12)


def test_crossing_vectors_with_their_phases_give_roll_pitch_and_yaw():
    h, phases, cones = _orbit_crossing_vectors(0.0, 5.0)
    assert attitude_from_crossing_vectors(h, phases, cones) == pytest.approx((0.0, 5.0, 0.0), abs=1e-9)
    h, phases, cones = _orbit_crossing_vectors(-20.0, -9.0)
    assert attitude_from_crossing_vectors(h[:3], phases[:3], cones[:3]) == pytest.approx((-20.0, -9.0, 0.0),
                                                                                         abs=1e-9)


@pytest.mark.parametrize("window, roll, pitch", [(2, 1.3, -0.7), (7, -10.0, 6.0)])
def test_oblate_solver_recovers_an_injected_attitude_with_the_position_known(window, roll, pitch):
    state = thesis_window_state(window)
    rot = state.body_to_frame(roll, pitch)
    (o1, i1), (o2, i2) = (crossing_phases_oblate(state.position_km, rot, 70.0, k) for k in (1, 2))
    sol = solve_oblate((o1, o2), (i1, i2), state.position_km, state.orbit_frame())
    assert sol.converged and not sol.warnings
    assert (sol.roll_deg, sol.pitch_deg) == pytest.approx((roll, pitch), abs=1e-8)
    # three crossings suffice too
    three = solve_oblate((o1, o2), (i1, np.nan), state.position_km, state.orbit_frame())
    assert (three.roll_deg, three.pitch_deg) == pytest.approx((roll, pitch), abs=1e-8)
