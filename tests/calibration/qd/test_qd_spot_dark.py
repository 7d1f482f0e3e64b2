"""Eq. 2.1 (spot from four currents) and the dark current against temperature (seed 002 §2.1)."""

import numpy as np
import pytest
from qd_simulation import SIGNS, Sensor, separable_currents

from calibration.errors import InsufficientDataError
from calibration.qd.dark import DarkFit, fit_dark, fit_dark_linear, subtract_dark
from calibration.qd.design import CYCLIC_LAYOUT, quadrant_layout
from calibration.qd.spot import QdSignalError, quadrant_fractions, spot_position, spot_ratios


def test_eq21_recovers_the_spot_of_currents_built_for_it():
    rng = np.random.default_rng(0)
    length = 3e-3
    xc, yc = rng.uniform(-1.2e-3, 1.2e-3, (2, 50))
    got_x, got_y = spot_position(separable_currents(xc, yc, length), length)
    np.testing.assert_allclose(got_x, xc, atol=1e-15)
    np.testing.assert_allclose(got_y, yc, atol=1e-15)


def test_eq21_as_printed_uses_the_diagonal_numbering():
    # (I2 − I1) + (I3 − I4) and (I2 − I1) + (I4 − I3), literally
    i = np.array([[1.0, 4.0, 2.0, 3.0]])
    u, v = spot_ratios(i)
    assert u[0] == pytest.approx(((4 - 1) + (2 - 3)) / 10)
    assert v[0] == pytest.approx(((4 - 1) + (3 - 2)) / 10)


def test_another_numbering_is_only_another_table_of_signs():
    rng = np.random.default_rng(1)
    currents = separable_currents(*rng.uniform(-1e-3, 1e-3, (2, 20)), 3e-3)
    # the same four diodes wired as the cyclic numbering: find, for each cyclic channel, the thesis quadrant
    order = [next(k for k in range(4) if tuple(SIGNS[k]) == tuple(s)) for s in CYCLIC_LAYOUT]
    cyclic = currents[:, order]
    np.testing.assert_allclose(np.stack(spot_ratios(cyclic, CYCLIC_LAYOUT)), np.stack(spot_ratios(currents)))


def test_no_light_is_a_typed_error_naming_the_row():
    currents = np.array([[1.0, 1.0, 1.0, 1.0], [0.2, -0.1, -0.05, -0.05], [1.0, 2.0, 3.0, 4.0]]) * 1e-6
    with pytest.raises(QdSignalError) as info:
        spot_ratios(currents)
    assert info.value.row == 1
    u, v = spot_ratios(currents, invalid="nan")
    assert np.isnan(u[1]) and np.isnan(v[1]) and np.isfinite(u[[0, 2]]).all()
    assert np.isnan(quadrant_fractions(currents, invalid="nan")[1]).all()


@pytest.mark.parametrize("layout", [((1, 1), (1, 1), (-1, -1), (1, -1)), ((1, 2), (1, 1), (-1, -1), (1, -1)), "ccw"])
def test_a_layout_must_name_each_quadrant_once(layout):
    with pytest.raises(ValueError):
        quadrant_layout(layout)


def _linear_dark(rng, n=15, sigma=0.03e-9):
    t = np.linspace(-40.0, 45.0, n)
    id0 = np.array([0.8, 1.1, 0.9, 1.3]) * 1e-9
    kd = np.array([12.0, 9.0, 15.0, 11.0]) * 1e-12  # A/°C
    return t, id0, kd, id0 + kd * t[:, None] + rng.normal(0.0, sigma, (n, 4))


def test_linear_dark_current_recovered_within_its_uncertainty_over_many_draws():
    z = []
    for seed in range(40):
        t, id0, kd, cur = _linear_dark(np.random.default_rng(seed))
        model = fit_dark_linear(t, cur)
        sd = model.sd
        z.append((model.parameters[:, 0] - id0) / sd[:, 0])
        z.append((model.parameters[:, 1] - kd) / sd[:, 1])
        assert np.all(np.abs(z[-1]) < 5) and np.all(np.abs(z[-2]) < 5)
    z = np.concatenate(z)
    # t with 13 dof: RMS √(13/11) ≈ 1.09, 95 % within 2.16
    assert 0.8 < np.sqrt(np.mean(z**2)) < 1.35
    assert np.mean(np.abs(z) < 2.2) > 0.9


def test_the_thesis_line_is_kept_for_linear_dark_current():
    t, *_, cur = _linear_dark(np.random.default_rng(3))
    fit = fit_dark(t, cur)
    assert fit.kind == "linear" and "exponential" in fit.candidates
    assert "kept" in fit.note


def test_an_exponential_dark_current_is_recognised_and_subtracted():
    sensor = Sensor()
    rng = np.random.default_rng(4)
    t = np.repeat(np.linspace(-10.0, 50.0, 13), 3)
    truth = sensor.dark(t)
    cur = truth + rng.normal(0.0, 0.02e-9, truth.shape)
    fit = fit_dark(t, cur)
    assert fit.kind == "exponential", fit.note
    # subtracting leaves the noise, where the thesis' line leaves a bow of tenths of nA
    t_test = np.linspace(-5.0, 45.0, 30)
    light = np.full((t_test.size, 4), 1e-6)
    left = subtract_dark(light + sensor.dark(t_test), t_test, fit) - light
    line = subtract_dark(light + sensor.dark(t_test), t_test, fit.candidates["linear"]) - light
    assert np.abs(left).max() < 0.05e-9
    assert np.abs(line).max() > 5 * np.abs(left).max()
    # the exponential's parameters and their 1σ are finite, and the rule is stated
    assert np.all(np.isfinite(fit.model.parameters)) and np.all(np.isfinite(fit.model.sd))
    assert "AICc" in fit.note


def test_one_temperature_gives_a_constant_and_says_so():
    cur = np.full((5, 4), 1e-9) + np.random.default_rng(5).normal(0, 1e-12, (5, 4))
    fit = fit_dark(np.full(5, 21.0), cur)
    assert fit.kind == "constant" and "one temperature" in fit.note
    np.testing.assert_allclose(fit.current([0.0, 40.0]), np.repeat(cur.mean(0)[None], 2, 0))


def test_dark_model_survives_its_document():
    t, *_, cur = _linear_dark(np.random.default_rng(6))
    fit = fit_dark(t, cur)
    back = DarkFit.from_dict(fit.to_dict())
    np.testing.assert_allclose(back.current(t), fit.current(t), rtol=1e-15)


def test_dark_fit_refuses_ragged_data():
    with pytest.raises(InsufficientDataError):
        fit_dark(np.arange(3.0), np.zeros((4, 4)))


def test_the_exponential_dark_rate_has_an_honest_uncertainty():
    """The rate b's 1σ covers its truth over noise draws (a, c in amperes and b in 1/°C span 16 decades in JᵀJ:
    an unscaled pseudo-inverse once reported σ_b ≈ 1e-20)."""
    from calibration.qd.dark import fit_dark_exponential

    t = np.repeat([10.0, 20.0, 30.0, 40.0], 8)
    z = []
    for seed in range(30):
        rng = np.random.default_rng(seed)
        currents = np.stack([1e-9 * 2 ** ((t - 25) / 9) + rng.normal(0, 2e-12, t.size) for _ in range(4)], axis=1)
        b = fit_dark_exponential(t, currents).to_dict()["quadrants"][0]["b_per_c"]
        z.append((b["value"] - np.log(2) / 9) / b["sd"])
    assert 0.6 < np.std(z) < 1.5 and abs(np.mean(z)) < 0.6
