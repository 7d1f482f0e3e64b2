"""The experiment design of the physical calibration: D-optimal choice, check directions, table tour, stopping rule."""

import dataclasses

import numpy as np
import pytest

from calibration.design import DEFAULT_SENSOR
from calibration.design_of_experiments import (
    candidate_directions,
    check_directions,
    design_experiment,
    greedy_d_optimal,
    log_det_information,
    move_time_s,
    nominal_build,
    order_tour,
    parameter_targets,
    prior_information,
    spot_inside,
    spot_jacobian,
    stopping_decision,
    tour_time_s,
    trapezoid_move_s,
)
from calibration.geometry import angular_error_deg
from calibration.models.physical import FITTED
from calibration.pinhole import direction_from_spot, spot_from_direction
from calibration.synthetic import EXAMPLE_BUILD, synthetic_bench_data

PITCH = DEFAULT_SENSOR.pixel_pitch_mm
# the example sensor with a slightly non-round pinhole, as the simulated bench's
TRUTH = dataclasses.replace(EXAMPLE_BUILD, aperture_c=0.0015, aperture_s=0.0013)


def test_jacobian_matches_a_finite_step_of_the_model():
    build = nominal_build()
    zenith, azimuth = np.array([30.0, 55.0]), np.array([20.0, 250.0])
    jac = spot_jacobian(zenith, azimuth, build, PITCH)
    assert jac.shape == (2, 2, len(FITTED))
    # x0 moves x one for one, y not at all
    np.testing.assert_allclose(jac[:, :, FITTED.index("x0_px")], [[1, 0], [1, 0]], atol=1e-9)
    step = dataclasses.replace(build, gap_mm=build.gap_mm + 1e-3)
    moved = np.subtract(spot_from_direction(zenith, azimuth, step, PITCH),
                        spot_from_direction(zenith, azimuth, build, PITCH))
    np.testing.assert_allclose(jac[:, :, FITTED.index("gap_mm")].T * 1e-3, moved, rtol=1e-4)


def test_d_optimal_choice_beats_random_choices_of_the_same_size():
    build = nominal_build()
    zenith, azimuth = candidate_directions(build)
    jac = spot_jacobian(zenith, azimuth, build, PITCH)
    prior = prior_information()
    n = 16
    chosen = greedy_d_optimal(jac, n, prior=prior, start=(0,))
    assert chosen[0] == 0 and len(set(chosen.tolist())) == n  # normal incidence first, each pose once
    best = log_det_information(jac[chosen], 0.02, prior)
    rng = np.random.default_rng(3)
    random = [log_det_information(jac[rng.choice(len(zenith), n, replace=False)], 0.02, prior) for _ in range(300)]
    assert best > max(random)
    # a greedy prefix is itself a good design: the first 12 beat random sets of 12
    twelve = log_det_information(jac[chosen[:12]], 0.02, prior)
    assert twelve > max(log_det_information(jac[rng.choice(len(zenith), 12, replace=False)], 0.02, prior)
                        for _ in range(300))


def test_candidates_and_checks_stay_inside_the_detector_and_checks_fall_between_the_grid():
    build = nominal_build()
    zenith, azimuth = candidate_directions(build, margin_px=24)
    assert zenith[0] == 0 and zenith.max() == 60 and set(np.round(azimuth % 15, 9)) == {0}
    assert spot_inside(zenith, azimuth, build, margin_px=24).all()
    assert not spot_inside(60.0, 90.0, build, margin_px=24)  # 240 px from the centre along the short side
    cz, ca = check_directions(8, build)
    assert cz.size == 8 and spot_inside(cz, ca, build, margin_px=24).all()
    assert len(set(np.round(ca, 3))) == 8 and not np.any(np.isclose(ca % 15, 0))  # never a grid azimuth
    assert cz.min() < 20 and cz.max() > 45  # spread over the field


def test_design_is_nested_in_batches_with_growing_information():
    design = design_experiment(first_batch=16, batch_size=8, max_batches=3, n_check=8)
    assert design.batches == ((0, 16), (16, 24), (24, 32)) and design.n_fit == 32 and design.n_check == 8
    assert np.all(np.diff(design.log_det) > 0)
    assert design.zenith_deg[0] == 0
    again = design_experiment(first_batch=16, batch_size=8, max_batches=3, n_check=8)
    np.testing.assert_array_equal(design.azimuth_deg, again.azimuth_deg)  # deterministic: resume relies on it


def test_trapezoid_and_move_time():
    assert trapezoid_move_s(90.0, 10.0, 20.0) == pytest.approx(90 / 10 + 10 / 20)  # cruises
    assert trapezoid_move_s(1.0, 10.0, 20.0) == pytest.approx(2 * (1 / 20) ** 0.5)  # triangle
    assert trapezoid_move_s(-1.0, 10.0, 20.0) == trapezoid_move_s(1.0, 10.0, 20.0)
    # both axes at once: the slower sets the time; a slow azimuth axis dominates; no move costs nothing
    assert move_time_s((0, 0), (90, 10), settle_s=0.05) == pytest.approx(9.5 + 0.05)
    assert move_time_s((0, 0), (10, 10), rates_deg_s=(1.0, 10.0), accels_deg_s2=(2.0, 20.0)) == pytest.approx(10.5)
    assert move_time_s((5, 5), (5, 5), settle_s=0.05) == 0


@pytest.mark.parametrize("seed", range(5))
def test_tour_is_never_longer_than_the_naive_order(seed):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(0, 360, 24), rng.uniform(0, 60, 24)])
    speeds = {"rates_deg_s": (10.0, 4.0), "accels_deg_s2": (20.0, 8.0), "settle_s": 0.05}
    order = order_tour(poses, (0.0, 0.0), **speeds)
    assert sorted(order.tolist()) == list(range(24))
    naive = tour_time_s(poses, np.arange(24), (0.0, 0.0), **speeds)
    toured = tour_time_s(poses, order, (0.0, 0.0), **speeds)
    assert toured <= naive
    assert toured < 0.6 * naive  # random poses: the tour is much shorter


def test_tour_of_the_first_batch_is_a_fraction_of_the_design_order():
    design = design_experiment()
    poses = np.vstack([np.column_stack([design.azimuth_deg[:16], design.zenith_deg[:16]]),
                       np.column_stack([design.check_azimuth_deg, design.check_zenith_deg])])
    order = order_tour(poses, (0.0, 0.0), settle_s=0.05)
    toured = tour_time_s(poses, order, (0.0, 0.0), settle_s=0.05)
    assert toured < 0.25 * tour_time_s(poses, np.arange(len(poses)), (0.0, 0.0), settle_s=0.05)
    assert toured < 90  # s: one sweep of the azimuth axis and a little more


def test_parameter_targets_mean_the_budget():
    build = nominal_build()
    targets = parameter_targets(0.01, build)
    assert set(targets) == set(FITTED) and all(t > 0 for t in targets.values())
    # x0 off by its target moves the field by the budget, RMS
    zenith, azimuth = np.meshgrid(np.linspace(5, 60, 12), np.arange(0, 360, 15.0), indexing="ij")
    zenith, azimuth = zenith.ravel(), azimuth.ravel()
    keep = spot_inside(zenith, azimuth, build, margin_px=0)
    x, y = spot_from_direction(zenith[keep], azimuth[keep], build, PITCH)
    wrong = dataclasses.replace(build, x0_px=build.x0_px + targets["x0_px"])
    error = angular_error_deg(zenith[keep], azimuth[keep], *direction_from_spot(x, y, wrong, PITCH))
    assert np.sqrt(np.mean(error**2)) == pytest.approx(0.01, rel=0.02)


def _data(directions, noise_px, seed, build=TRUTH, offset_px=0.0, repeats=4):
    zenith, azimuth = (np.repeat(np.asarray(d, dtype=float), repeats) for d in directions)
    data = synthetic_bench_data(build, zenith_deg=zenith, azimuth_deg=azimuth, noise_px=noise_px, seed=seed)
    return dataclasses.replace(data, x_px=data.x_px + offset_px, repeat=np.tile(np.arange(repeats), len(directions[0])))


def test_stopping_rule_stops_once_the_targets_are_met():
    design = design_experiment()
    fit = _data((design.zenith_deg[:16], design.azimuth_deg[:16]), 0.02, seed=1)
    check = _data((design.check_zenith_deg, design.check_azimuth_deg), 0.02, seed=2)
    decision = stopping_decision(fit, check)
    assert decision.stop and decision.reasons == ()
    assert decision.n_fit_directions == 16 and decision.n_check_directions == 8
    assert decision.check_rms_deg <= 0.02
    assert all(decision.sigmas[n] <= decision.targets[n] for n in decision.targets)
    assert "stop" in decision.summary()
    # the calibration it stopped on is good where it was never measured
    rng = np.random.default_rng(0)
    zenith, azimuth = rng.uniform(0, 55, 300), rng.uniform(0, 360, 300)
    x, y = spot_from_direction(zenith, azimuth, TRUTH, PITCH)
    error = angular_error_deg(zenith, azimuth, *decision.calibration.apply(x, y))
    assert np.sqrt(np.mean(error**2)) <= 0.02


def test_stopping_rule_does_not_stop_before():
    design = design_experiment()
    fit_dirs = (design.zenith_deg[:16], design.azimuth_deg[:16])
    check_dirs = (design.check_zenith_deg, design.check_azimuth_deg)
    good_check = _data(check_dirs, 0.02, seed=2)
    # too few directions for a fit
    few = stopping_decision(_data((design.zenith_deg[:8], design.azimuth_deg[:8]), 0.02, seed=1), good_check)
    assert not few.stop and "no fit yet" in few.reasons[0]
    # noisy centroids: the parameters are not pinned down yet
    noisy = stopping_decision(_data(fit_dirs, 0.5, seed=1), good_check)
    assert not noisy.stop and any(r.startswith("σ(") for r in noisy.reasons)
    # a sound fit that the check directions contradict (they see a shifted spot: a model the fit cannot show)
    biased = stopping_decision(_data(fit_dirs, 0.02, seed=1), _data(check_dirs, 0.02, seed=2, offset_px=0.2))
    assert not biased.stop and biased.check_rms_deg > 0.02
    assert [r for r in biased.reasons if "check RMS" in r] and not [r for r in biased.reasons if r.startswith("σ(")]
    # too few check directions scored
    two = stopping_decision(_data(fit_dirs, 0.02, seed=1), _data((check_dirs[0][:2], check_dirs[1][:2]), 0.02, seed=2))
    assert not two.stop and "check direction" in two.reasons[-1]
    # a tighter target on one parameter holds the run
    strict = stopping_decision(_data(fit_dirs, 0.02, seed=1), good_check, targets={"x0_px": 1e-5})
    assert not strict.stop and strict.reasons[0].startswith("σ(x0_px)")
