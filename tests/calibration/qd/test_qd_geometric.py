"""Eq. 2.2 and its six-parameter fit, on data made with the thesis' own parameters (seed 002 §5.2)."""

import numpy as np
import pytest
from qd_simulation import THESIS, grid, separable_currents, thesis_spots

from calibration.errors import InsufficientDataError
from calibration.qd.geometric import (
    GEOMETRIC_PARAMETERS,
    GeometricParameters,
    angles_from_spot,
    fit_geometric,
    initial_geometric,
    spot_from_angles,
)
from calibration.qd.reference import THESIS_GEOMETRIC
from calibration.qd.spot import spot_position

LENGTH = 3e-3  # an L large enough for the thesis' spot travel (±0.69 mm around y0 = 0.52 mm)
TRUTH = GeometricParameters(**THESIS)


def _bench(seed, noise_a=1e-10, step=5.0):
    """Currents at a ±40° grid from the vector-geometry sensor, with current noise; eq. 2.1 gives the spots."""
    a, b = grid(40.0, step)
    currents = separable_currents(*thesis_spots(a, b), LENGTH, total_a=1e-6)
    currents = currents + np.random.default_rng(seed).normal(0.0, noise_a, currents.shape)
    return a, b, *spot_position(currents, LENGTH)


def test_the_reference_constants_are_the_thesis_values_typed_in_by_the_tests():
    assert THESIS_GEOMETRIC == TRUTH


def test_inverse_model_agrees_with_vector_geometry_and_round_trips():
    a, b = grid(40.0, 2.5)
    x_vec, y_vec = thesis_spots(a, b)
    x, y = spot_from_angles(a, b, TRUTH)
    np.testing.assert_allclose(x, x_vec, atol=1e-15)
    np.testing.assert_allclose(y, y_vec, atol=1e-15)
    a2, b2 = angles_from_spot(x, y, TRUTH)
    np.testing.assert_allclose(a2, a, atol=1e-10)
    np.testing.assert_allclose(b2, b, atol=1e-10)


def test_initial_guess_is_exact_without_angular_offsets():
    truth = GeometricParameters(x0_m=-5e-5, y0_m=5e-4, phi0_deg=2.0, d_m=8e-4)
    a, b = grid(40.0, 10.0)
    start = initial_geometric(*spot_from_angles(a, b, truth), a, b)
    for name in ("x0_m", "y0_m", "d_m"):
        assert getattr(start, name) == pytest.approx(getattr(truth, name), rel=1e-9)
    assert start.phi0_deg == pytest.approx(truth.phi0_deg, abs=1e-9)


def test_thesis_parameters_fitted_back_within_three_sigma_with_the_predicted_correlations():
    a, b, x, y = _bench(seed=0)
    fit = fit_geometric(x, y, a, b)
    for name in GEOMETRIC_PARAMETERS:
        est, true, sd = getattr(fit.parameters, name), getattr(TRUTH, name), fit.sd[name]
        assert sd > 0 and abs(est - true) < 3 * sd, f"{name}: {est} vs {true} ± {sd}"
    # x0/d and α0, y0/d and β0: nearly the same offset (digest §2.5); reported and stated
    for pair in (("x0_m", "alpha0_deg"), ("y0_m", "beta0_deg")):
        r = fit.correlation_of(*pair)
        assert -0.995 < r < -0.95, (pair, r)
        assert any(pair[0] in s and pair[1] in s for s in fit.statements)
    assert len(fit.statements) == 2  # nothing else is nearly degenerate
    print(f"\ngeometric fit of the thesis' sensor: corr(x0, α0) = {fit.correlation_of('x0_m', 'alpha0_deg'):+.3f}, "
          f"corr(y0, β0) = {fit.correlation_of('y0_m', 'beta0_deg'):+.3f}, residual RMS {fit.rms_deg:.4f}°")


def test_reported_uncertainties_cover_the_truth_over_noise_draws():
    z = []
    for seed in range(1, 31):
        a, b, x, y = _bench(seed)
        fit = fit_geometric(x, y, a, b)
        z.append([(getattr(fit.parameters, n) - getattr(TRUTH, n)) / fit.sd[n] for n in GEOMETRIC_PARAMETERS])
    z = np.array(z)
    assert 0.7 < np.sqrt(np.mean(z**2)) < 1.4, np.sqrt(np.mean(z**2, axis=0))
    assert np.mean(np.abs(z) < 2) > 0.85
    assert np.all(np.abs(z) < 4.5)


def test_fixed_parameters_stay_where_they_were_put():
    a, b, x, y = _bench(seed=2)
    fit = fit_geometric(x, y, a, b, fixed={"alpha0_deg": 0.0086, "phi0_deg": 0.0})
    assert fit.free == ("x0_m", "y0_m", "beta0_deg", "d_m")
    assert fit.parameters.alpha0_deg == 0.0086 and fit.parameters.phi0_deg == 0.0
    assert fit.covariance.shape == (4, 4)
    # with α0 fixed, x0 is no longer entangled with it and is far better determined
    free = fit_geometric(x, y, a, b)
    assert fit.sd["x0_m"] < 0.5 * free.sd["x0_m"]
    with pytest.raises(ValueError):
        fit_geometric(x, y, a, b, fixed=["x0"])


def test_too_few_points_refused():
    with pytest.raises(InsufficientDataError):
        fit_geometric([0.0, 1e-4, 2e-4], [0.0, 0.0, 1e-4], [0.0, 5.0, 10.0], [0.0, 0.0, 5.0])
