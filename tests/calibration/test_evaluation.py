"""Table 4.1 metrics and the leave-one-azimuth-out evaluation."""

import dataclasses

import numpy as np
import pytest

from calibration import evaluation
from calibration.data import BenchData
from calibration.evaluation import accuracy_metrics, best_method, compare_methods, holdout_predictions
from calibration.models.seed003 import Seed003Calibration
from calibration.synthetic import synthetic_bench_data


def _data():
    zen = np.array([0.0, 0.0, 20.0, 20.0, 40.0, 40.0])
    az = np.array([0.0, 90.0, 0.0, 90.0, 180.0, 270.0])
    return BenchData(zen, az, np.zeros(6), np.zeros(6))


def test_metrics_of_a_known_zenith_error():
    data = _data()
    m = accuracy_metrics(data, data.zenith_deg + 0.1, data.azimuth_deg)
    assert m.n_points == 6
    assert m.rms_zenith_deg == pytest.approx(0.1)
    assert m.rms_azimuth_deg == pytest.approx(0.0)
    assert m.rms_vector_deg == pytest.approx(0.1)
    assert m.bound95_deg == pytest.approx(0.2)  # the thesis' 95 % bound is 2 × RMS
    assert m.max_vector_deg == pytest.approx(0.1)


def test_azimuth_error_is_wrapped_and_left_out_at_normal_incidence():
    data = _data()
    azimuth = data.azimuth_deg.copy()
    azimuth[:2] += 77.0  # meaningless at normal incidence
    azimuth[2] = 359.0  # 1° away from 0° across the seam
    m = accuracy_metrics(data, data.zenith_deg, azimuth)
    assert m.rms_azimuth_deg == pytest.approx(np.sqrt(1.0 / 4))
    assert m.rms_vector_below40_deg < m.max_vector_deg


def test_every_point_is_predicted_by_a_model_that_never_saw_its_azimuth(monkeypatch):
    data = synthetic_bench_data(noise_px=0.02).direction_means()
    seen = []

    class Spy(Seed003Calibration):
        @classmethod
        def fit(cls, train, design=None):
            seen.append(set(np.unique(train.azimuth_deg[~train.normal_incidence]).tolist()))
            return Seed003Calibration.fit(train)

    monkeypatch.setitem(evaluation.METHODS, "spy", Spy)
    evaluated, zenith, azimuth = holdout_predictions("spy", data)
    assert len(seen) == 8 and all(len(s) == 7 for s in seen)
    assert set.union(*seen) == set(np.arange(0.0, 360.0, 45.0).tolist())
    assert len(evaluated) == int((~data.normal_incidence).sum())
    assert np.all(np.isfinite(zenith)) and np.all(np.isfinite(azimuth))


def test_held_out_is_not_better_than_the_fit_for_a_model_that_fits_its_nodes():
    reports = {r.method: r for r in compare_methods(synthetic_bench_data(noise_px=0.02, seed=4))}
    sector = reports["seed003-sector"]
    assert sector.heldout.rms_vector_deg > sector.fitted.rms_vector_deg
    assert best_method(list(reports.values())).method == "physical"


def test_repeats_are_averaged_per_direction():
    data = synthetic_bench_data(noise_px=0.02)
    means = data.direction_means()
    # the centre stage and the zenith-0 row of the grid share their 8 directions
    assert len(data) == 8 * 5 + 8 * 7 * 4 and len(means) == 8 * 7
    pick = (data.zenith_deg == 30.0) & (data.azimuth_deg == 135.0)
    row = np.flatnonzero((means.zenith_deg == 30.0) & (means.azimuth_deg == 135.0))
    assert means.x_px[row[0]] == pytest.approx(data.x_px[pick].mean())


def test_azimuth_groups_close_the_circle():
    data = BenchData([10, 10, 10, 10, 0], [359.8, 0.1, 90.0, 180.0, 33.0], np.zeros(5), np.zeros(5))
    labels = data.azimuth_groups()
    assert labels[0] == labels[1] != labels[2]
    assert labels[4] == -1


def test_best_method_prefers_held_out_figures():
    reports = compare_methods(synthetic_bench_data(noise_px=0.02, seed=5))
    worse = dataclasses.replace(reports[-1], heldout=dataclasses.replace(reports[-1].heldout, rms_vector_deg=9.0))
    assert best_method(reports[:-1] + [worse]).method != reports[-1].method
