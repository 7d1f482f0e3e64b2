"""Plan density against CMOS accuracy (bench/study_cmos.py, `sunbench study cmos-plan`).

The sensors are the simulator's (drivers/sim/world.fleet_sensor builds, the ray trace's own physics), the fits the
library's, and the score is at random directions off the plan. What the study must show, on the same sensors (one
serial per draw at every plan): a denser plan is not worse — the physical model's held-out error falls as the plan
grows from 4 × 4 × 1 through seed 003's 8 × 7 × 4 to 16 × 13 × 4, and no method does worse on the densest plan than
on seed 003's; a plan a method cannot be fitted from says so in words, per sensor.
"""

import json

import numpy as np
import pandas as pd
import pytest
from clitools import invoke

from bench.study_cmos import check_directions, plan_directions, sensor_for_draw, simulate_cmos
from bench.study_engine import StudySpec
from calibration.models import METHODS
from calibration.synthetic import seed003_grid

PLANS = {"sparse": (4, 4, 1), "seed003": (8, 7, 4), "dense": (16, 13, 4)}


@pytest.fixture(scope="module")
def scores():
    seeds = [StudySpec("t", "bench.study_cmos:simulate_cmos", draws=1).draw_seed(d) for d in range(4)]
    return {name: [simulate_cmos({"azimuths": a, "rings": r, "repeats": k}, s) for s in seeds]
            for name, (a, r, k) in PLANS.items()}


def mean_rms(rows, method):
    return float(np.mean([row[f"{method}.rms_deg"] for row in rows]))


def test_seed003_plan_is_the_procedure_of_the_thesis():
    z, a, k = plan_directions(8, 7, 4)
    zt, at, kt = seed003_grid()
    assert np.array_equal(z, zt) and np.array_equal(a, at) and np.array_equal(k, kt)
    assert len(z) == 8 * 5 + 8 * 7 * 4  # seed 003 §4.2: 40 centre frames and 224 on the grid


def test_denser_plans_are_not_worse(scores):
    physical = [mean_rms(scores[p], "physical") for p in ("sparse", "seed003", "dense")]
    assert physical[0] > physical[1] > physical[2], physical
    assert physical[2] < 0.5 * physical[0]  # 24 → 912 frames: the centroid noise averages down
    for method in METHODS:
        assert mean_rms(scores["dense"], method) <= 1.02 * mean_rms(scores["seed003"], method), method
    # the polynomial models are limited by their 6th-order θ(r) between rings: 13 rings help them most
    assert mean_rms(scores["dense"], "seed003") < 0.6 * mean_rms(scores["seed003"], "seed003")
    assert all(row["frames"] == 8 * 5 + 8 * 7 * 4 for row in scores["seed003"])


def test_a_plan_too_sparse_for_a_method_says_why(scores):
    for row in scores["sparse"]:
        for method in ("seed003", "seed003-tilt", "seed003-sector"):
            assert np.isnan(row[f"{method}.rms_deg"])
            assert "needs at least 7 distinct zenith angles" in row[f"{method}.error"]
        assert row["physical.error"] == "" and row["physical.rms_deg"] < 0.02


def test_each_draw_is_one_sensor_at_every_plan():
    assert sensor_for_draw(12345) == sensor_for_draw(12345)
    assert sensor_for_draw(12345).build != sensor_for_draw(54321).build
    z, a = check_directions(2000, 60.0, np.random.default_rng(0))
    assert z.max() <= 60.0 and abs(np.mean(np.cos(np.radians(z))) - (1 + np.cos(np.radians(60))) / 2) < 0.01


def test_cli_runs_the_study_on_a_local_cluster(tmp_path):
    out = tmp_path / "plans.csv"
    r = invoke("study", "cmos-plan", "--azimuths", "4,8", "--rings", "4,7", "--repeats", "2", "--draws", "2",
               "--check-points", "100", "--workers", "1", "--chunk-size", "3", "--out", out)
    assert r.exit_code == 0, r.output
    assert "8 of 8 simulations (8 run now" in r.output and "on 1 worker(s)" in r.output
    table = pd.read_csv(out, keep_default_na=False, na_values=[""])
    assert len(table) == 8 and set(table["azimuths"]) == {4, 8} and set(table["rings"]) == {4, 7}
    for method in METHODS:
        for column in ("rms_deg", "p95_deg", "max_deg", "error"):
            assert f"{method}.{column}" in table.columns
    four_rings = table[table["rings"] == 4]
    assert four_rings["seed003.rms_deg"].isna().all() and four_rings["physical.rms_deg"].notna().all()
    summary = pd.read_csv(out.with_name("plans.summary.csv"))
    assert {"physical.rms_deg", "frames"} <= set(summary["output"])
    assert out.with_name("plans.html").is_file()
    for text in ("Held-out vector error", "4×4×2", "8×7×2", "not fitted"):
        assert text in r.output, text
    # the same study again: every chunk is kept, nothing runs; --json gives the per-plan table alone on stdout
    r = invoke("study", "cmos-plan", "--azimuths", "4,8", "--rings", "4,7", "--repeats", "2", "--draws", "2",
               "--check-points", "100", "--workers", "1", "--chunk-size", "3", "--out", out, "--json")
    assert r.exit_code == 0 and "(0 run now, 8 kept" in r.stderr
    plans = {(p["azimuths"], p["rings"]): p for p in json.loads(r.stdout)}
    assert set(plans) == {(4, 4), (4, 7), (8, 4), (8, 7)}
    assert plans[(4, 4)]["seed003.failed"] == 2 and plans[(8, 7)]["seed003.failed"] == 0
    assert plans[(8, 7)]["frames"] == 8 * 3 + 8 * 7 * 2
    r = invoke("study", "cmos-plan", "--rings", "1", "--out", out)
    assert r.exit_code == 2 and "--rings: 1 lies outside" in r.output
