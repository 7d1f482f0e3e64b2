"""calibrate_qd on a simulated bench run: dark fit, a glint, every method held out between the nodes."""

import dataclasses
import json

import numpy as np
import pytest
from qd_simulation import GLINT_ROW

from calibration.errors import InsufficientDataError
from calibration.qd.evaluation import (
    CHI2_WARNING,
    METHODS,
    calibrate_qd,
    direction_groups,
    grid_lines,
    heldout_schemes,
    saturated_rows,
)


def test_every_method_scored_and_the_best_held_out_chosen(outcome):
    print("\nmethod      at nodes max/RMS     held out max/RMS/p99 (worst scheme)   χ²/dof")
    for r in outcome.reports:
        print(f"{r.method:<11} {r.at_nodes.max_deg:.4f}/{r.at_nodes.rms_deg:.4f}°    {r.heldout.max_deg:.4f}/"
              f"{r.heldout.rms_deg:.4f}/{r.heldout.p99_deg:.4f}° ({r.heldout_scheme:<7})   {r.chi2_dof:.3g}")
    assert [r.method for r in outcome.reports] == list(METHODS)
    for r in outcome.reports:
        assert r.error is None and set(r.heldout_by_scheme) == {"check", "columns", "rows"}
        assert r.heldout is r.heldout_by_scheme[r.heldout_scheme]
        assert r.heldout.max_deg == max(m.max_deg for m in r.heldout_by_scheme.values())
    assert outcome.chosen.heldout.max_deg == min(r.heldout.max_deg for r in outcome.reports)
    physical = outcome.report("physical")
    assert physical.heldout.max_deg <= 0.1 and physical.heldout.rms_deg <= 0.03
    assert physical.heldout.n_failed == 0
    assert outcome.report("geometric").heldout.max_deg > 0.3  # eq. 2.1's linear reading at the edge of the field


def test_residuals_against_the_repeat_scatter(outcome):
    assert outcome.repeat_scatter_share is not None and outcome.repeat_scatter_share > 0
    assert outcome.report("physical").chi2_dof < CHI2_WARNING
    assert outcome.report("geometric").chi2_dof > 100 * outcome.report("physical").chi2_dof


def test_the_glint_and_only_the_glint_is_rejected_by_name(outcome, bench_data):
    assert [r.row_id for r in outcome.rejected] == [int(bench_data.row_id[GLINT_ROW])]
    assert "glint" in outcome.rejected[0].reason
    assert any(f"row {GLINT_ROW + 1} " in w for w in outcome.warnings)
    # its direction survives through its other reading
    a, b = bench_data.alpha_deg[GLINT_ROW], bench_data.beta_deg[GLINT_ROW]
    i = np.flatnonzero((outcome.directions.alpha_deg == a) & (outcome.directions.beta_deg == b))
    assert i.size == 1 and outcome.directions.members[i[0]].size == 1


def test_dark_current_fitted_from_the_dark_rows(outcome, bench_data):
    assert outcome.dark.kind == "exponential"  # the simulated diodes double every ~9 °C
    assert outcome.dark.n_points == 39 == bench_data.dark.sum()  # every dark row: none was an outlier
    assert not any("dark readings" in w for w in outcome.warnings)


def test_method_details_reported(outcome):
    poly = outcome.report("polynomial")
    assert "held-out RMS" in poly.details["order_rule"] and np.isfinite(poly.details["condition_number"])
    geo = outcome.report("geometric")
    assert any("x0_m" in s and "alpha0_deg" in s for s in geo.details["statements"])
    assert outcome.report("physical").details["offsets"] in ("rotation", "additive")
    json.dumps(outcome.to_dict())


def test_without_dark_rows_it_says_so(bench_data):
    light = bench_data.subset(~bench_data.dark)
    result = calibrate_qd(light, methods=["geometric"])
    assert result.dark.kind == "none"
    assert any("no dark readings" in w for w in result.warnings)


def test_too_little_data_refused(bench_data):
    with pytest.raises(InsufficientDataError):
        calibrate_qd(bench_data.subset(np.flatnonzero(~bench_data.dark)[:5]))


def test_grid_lines_and_schemes_tolerate_readback_jitter():
    rng = np.random.default_rng(0)
    v = np.repeat(np.arange(-40.0, 40.1, 10.0), 9) + rng.uniform(-0.02, 0.02, 81)  # 1′ readbacks
    line = grid_lines(v)
    assert line.max() == 8 and np.all(line >= 0)
    a = v
    b = np.tile(np.arange(-40.0, 40.1, 10.0), 9)
    schemes = heldout_schemes(a, b)
    assert set(schemes) == {"columns", "rows"}
    # the edge lines are never left out: that would score extrapolation
    assert np.all(schemes["columns"][np.abs(np.round(a)) == 40] == -1)
    # scattered directions fall back to a checkerboard of interior cells
    sa, sb = rng.uniform(-40, 40, (2, 200))
    assert set(heldout_schemes(sa, sb)) == {"checkerboard"}


def test_jittered_repeats_still_group_and_saturated_rows_are_named(bench_data):
    rng = np.random.default_rng(9)
    second = bench_data.repeat == 1
    # the second pass read back one table step (1′) off, and three readings clipped at the ADC's top
    zen = bench_data.zenith_deg + np.where(second, rng.choice([-1, 1], bench_data.zenith_deg.size) / 60.0, 0.0)
    cur = bench_data.currents_a.copy()
    clip = [3, 50, 200]
    top = cur[~bench_data.dark, 1].max() * 1.01
    cur[clip, 1] = top
    data = dataclasses.replace(bench_data, zenith_deg=zen, currents_a=cur)
    result = calibrate_qd(data, methods=["physical"])
    named = {r.row_id: r.reason for r in result.rejected}
    for i in clip:
        assert "saturated" in named[int(data.row_id[i])]
    alpha, beta = data.projection_deg
    nodes = ~data.dark & ~data.check
    n_nodes = len(set(zip(np.round(alpha[nodes]), np.round(beta[nodes]))))  # 17 × 17, each read twice
    assert (~result.directions.check).sum() == 289 == n_nodes  # every node direction, its two passes together
    assert result.repeat_scatter_share is not None
    assert result.report("physical").heldout.max_deg < 0.1
    assert saturated_rows(cur, full_scale_a=top).sum() == 3


def test_direction_groups_within_tolerance():
    a = np.array([0.0, 0.01, 5.0, 5.02, 10.0, 0.0])
    b = np.array([0.0, -0.01, 0.0, 0.0, 0.0, 5.0])
    g = direction_groups(a, b)
    assert g[0] == g[1] and g[2] == g[3] and len(set(g.tolist())) == 4


def test_a_model_that_disagrees_with_many_directions_rejects_none(bench_data):
    cur = bench_data.currents_a.copy()
    nodes = np.flatnonzero(~bench_data.dark & ~bench_data.check & (bench_data.repeat == 0))
    spoiled = np.random.default_rng(2).choice(nodes, 45, replace=False)  # 45 of 289 directions: 16 %
    for i in spoiled:
        same = ((bench_data.zenith_deg == bench_data.zenith_deg[i])
                & (bench_data.azimuth_deg == bench_data.azimuth_deg[i]))
        cur[same & ~bench_data.check] *= [1.0, 1.2, 1.0, 1.0]
    result = calibrate_qd(dataclasses.replace(bench_data, currents_a=cur), methods=["geometric"])
    assert not any("physical model" in r.reason for r in result.rejected)
    assert any("not used to reject outliers" in w for w in result.warnings)
