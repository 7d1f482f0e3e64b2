"""The QD family end to end on the simulated bench (issue 12): a campaign runs, records four currents per reading
under the QD descriptor, fits every method when it ends, and reaches the issue's held-out accuracy; the truth the
engine records is right at the field's corners on both kinds of table."""

from __future__ import annotations

import numpy as np
import pytest

from bench.benchfile import BenchFile, load_bench_file
from bench.campaign import Campaign, QdDarkSweep, QdGridProcedure
from bench.catalogue import Catalogue
from bench.families import family
from bench.families.qd import DESCRIPTOR, grid_points
from bench.preflight import preflight_campaign
from bench.runner import open_session, run_campaign, session_mount
from calibration.qd.angles import projection_angles

SMALL = QdGridProcedure(step_deg=10.0, repeats=2, dark=QdDarkSweep(temperatures_c=(15.0, 35.0), repeats=4))


@pytest.fixture
def qd_session(tmp_path):
    bench = load_bench_file("examples/bench-sim-qd.yaml")
    with Catalogue(tmp_path / "catalogue.sqlite") as catalogue:
        session = open_session(bench, catalogue, time_scale=0.0)
        try:
            yield session
        finally:
            session.close()


def test_a_qd_campaign_is_recorded_under_its_descriptor_and_meets_the_issue_accuracy(qd_session):
    campaign = Campaign(name="qd", plan="qd-grid", sensors=("QD-0001",), qd_grid=QdGridProcedure())
    (run_id,) = run_campaign(campaign, qd_session)
    catalogue = qd_session.catalogue
    run = catalogue.run(run_id)
    assert run["status"] == "completed", run["exit_reason"]
    assert run["family"] == "qd" and catalogue.descriptor(run_id) == DESCRIPTOR
    readings = catalogue.readings(run_id)
    dark = [r for r in readings if r.stage == "dark"]
    assert {round(r.values["temperature_c"]) for r in dark} == {10, 20, 30, 40}  # the TEC swept the die
    lit = [r for r in readings if r.stage == "grid"]
    assert min(sum(r.values["currents_a"]) for r in lit) > 10 * max(sum(r.values["currents_a"]) for r in dark)

    calibrations = {c["method"]: c for c in catalogue.calibrations(run_id)}
    assert set(calibrations) == {"geometric", "polynomial", "physical"}
    chosen = next(c for c in calibrations.values() if c["chosen"])
    heldout = chosen["metrics"]["heldout"]
    print({m: (c["metrics"]["heldout"]["max_deg"], c["metrics"]["heldout"]["rms_deg"])
           for m, c in calibrations.items()})
    # the issue: the default method ≤ 0.1° maximum and ≤ 0.03° RMS held out over ±40° (the thesis: 2.5° and 0.7°)
    assert heldout["max_deg"] <= 0.1 and heldout["rms_deg"] <= 0.03
    assert heldout["n_points"] >= 200  # the check points between the nodes are scored, not only the nodes
    assert chosen["document"]["family"] == "qd"

    # the dark model recovers the module's dark current per quadrant (the simulator's truth: its dark current at
    # the die's true temperature, plus its pedestal error in counts, which a dark calibration absorbs)
    from calibration.qd.dark import DarkFit

    dark = DarkFit.from_dict(chosen["document"]["dark"])
    module = qd_session.devices.sim.devices["sensor"]
    per_count = np.array(qd_session.devices.sensor.identify().amperes_per_count)
    for reported_c in (10.0, 20.0, 30.0, 40.0):
        true = (module.optics.dark_current_a(reported_c - module.truth.thermometer_offset_c)
                + np.array(module.truth.pedestal_error_counts) * per_count)
        fitted = dark.current(np.array([reported_c]))[0]
        assert np.all(np.abs(fitted - true) < np.maximum(5e-12, 0.01 * true)), (reported_c, fitted, true)


@pytest.mark.parametrize("table, axis_order", [("apt", "azimuth-on-zenith"), ("lx200", "zenith-on-azimuth")])
def test_the_recorded_truth_is_the_planned_direction_at_the_corners(tmp_path, table, axis_order):
    """The plan sets (α, β) through the table's kinematics and the engine records the direction the same table
    gives; at (±40°, ±40°) naive table angles would be 7.6° off (digest 002 §7 item 9)."""
    # a fork mount's altitude goes below the horizon here: the sensor looks up at a source on the horizon
    limits = {"devices": {"table": {"zenith_limits_deg": [-60, 80]}}} if table == "lx200" else {}
    bench = BenchFile.model_validate({"simulation": {"time_scale": 0, "family": "qd", "table": table,
                                                     "axis_order": axis_order,
                                                     "mount": {"tilt_x_deg": 0, "tilt_y_deg": 0}}, **limits})
    procedure = QdGridProcedure(step_deg=40.0, check_points=False, repeats=1,
                                dark=QdDarkSweep(temperatures_c=()), temperature_c=None)
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(bench, catalogue, time_scale=0.0)
        try:
            points = grid_points(procedure, session_mount(session))
            for point in points:
                wanted_alpha, wanted_beta = (float(point.key.split("_")[i][1:]) for i in (1, 2))
                zenith, azimuth = session.engine.body_direction(point)
                alpha, beta = projection_angles(zenith, azimuth)
                assert (float(alpha), float(beta)) == (pytest.approx(wanted_alpha, abs=1e-3),
                                                       pytest.approx(wanted_beta, abs=1e-3)), point
                # and the simulated world, which has its own kinematics, puts the sun there too
                session.devices.table.move_to(point.azimuth_deg, point.zenith_stage_deg)
                true_zenith, true_azimuth = session.devices.sim.world.sun_direction_body()
                true_alpha, true_beta = projection_angles(true_zenith, true_azimuth)
                assert abs(float(true_alpha) - wanted_alpha) < 0.02 and abs(float(true_beta) - wanted_beta) < 0.02
            corners = [p for p in points if "40.00" in p.key.split("_")[1] and "40.00" in p.key.split("_")[2]]
            assert len(corners) == 4
        finally:
            session.close()


def test_the_qd_plan_expands_to_the_same_keys_and_counts_its_cap():
    campaign = Campaign(name="qd", plan="qd-grid", qd_grid=SMALL)
    first = preflight_campaign(campaign, check=lambda a, z: None)
    again = preflight_campaign(campaign, check=lambda a, z: None)
    assert [p.key for p in first.points] == [p.key for p in again.points]
    assert len(first.points) == campaign.planned_points() == 81 + 64 + 2
    assert first.duration_s > 2 * 180.0  # two temperature set-points are in the estimate
    assert family("qd").plans == ("qd-grid", "qd-physical", "qd-dark")


def test_a_cmos_plan_on_a_qd_bench_is_refused_before_anything_moves(qd_session):
    from bench.runner import PreflightRefused

    with pytest.raises((PreflightRefused, ValueError), match="family|qd|cmos"):
        run_campaign(Campaign(name="wrong"), qd_session)
    assert qd_session.catalogue.runs() == []


QD_CAMPAIGN = """\
name: qd-crash
plan: qd-grid
sensors: [QD-0001]
qd_grid: {field_deg: 40, step_deg: 20, repeats: 2, temperature_c: null,
          dark: {temperatures_c: [20, 30], repeats: 3}}
"""
QD_BENCH = """\
simulation: {time_scale: 40, family: qd, source: led}
"""


def test_a_killed_qd_run_resumes_to_a_complete_lineage_and_is_fitted(tmp_path):
    """Like the CMOS crash test (test_crash_resume.py): a real `sunbench run` SIGKILLed mid-grid, then resumed."""
    import collections
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    sunbench = Path(sys.executable).with_name("sunbench")
    (tmp_path / "c.yaml").write_text(QD_CAMPAIGN)
    (tmp_path / "b.yaml").write_text(QD_BENCH)
    db = tmp_path / "cat.sqlite"
    env = {**os.environ, "NO_COLOR": "1"}
    args = ["--bench", tmp_path / "b.yaml", "--catalogue", db]
    with open(tmp_path / "run.err", "w") as log:
        proc = subprocess.Popen([sunbench, "run", tmp_path / "c.yaml", *args], stdout=log, stderr=log, env=env)
    deadline = time.monotonic() + 60
    while True:  # killed once a few grid points are in, well before the end
        assert proc.poll() is None, (tmp_path / "run.err").read_text()[-2000:]
        assert time.monotonic() < deadline, "no grid points within 60 s"
        try:
            with Catalogue(db, readonly=True) as cat:
                keys = cat.completed_keys(1) if cat.runs() else set()
        except Exception:  # noqa: BLE001 - not created yet
            keys = set()
        if len([k for k in keys if k.startswith("grid")]) >= 5:
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=10)
            break
        time.sleep(0.02)
    resumed = subprocess.run([sunbench, "resume", "1", *args], capture_output=True, text=True, env=env, timeout=120)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    with Catalogue(db, readonly=True) as cat:
        final = cat.runs()[-1]["id"]
        lineage = cat.lineage(final)
        assert lineage == [1, final] and cat.run(1)["status"] == "crashed"
        assert cat.run(final)["status"] == "completed" and cat.run(final)["family"] == "qd"
        planned = {p.key for p in preflight_campaign(Campaign.model_validate(cat.run(1)["plan_args"]),
                                                    check=lambda a, z: None).points}
        counts = collections.Counter(p["key"] for p in cat.points(lineage))
        assert set(counts) == planned and max(counts.values()) == 1  # complete, nothing measured twice
        assert {c["method"] for c in cat.calibrations(final)} == {"geometric", "polynomial", "physical"}


IDEAL_QD = {"diaphragm_thickness_um": 0.0, "wall_reflectance": 0.0, "crosstalk": [0.0, 0.0, 0.0, 0.0]}


@pytest.mark.parametrize("module", ["ideal", "realistic"])
def test_the_physical_short_plan_stops_where_the_models_allow_it(tmp_path, module):
    """The qd-physical plan: nested grids from coarse to fine, the physical model and the polynomial fitted after
    each and the one the run would choose scored on check directions it never fits. A module the physical model
    describes (no mask thickness, stray light or crosstalk) meets the targets on the coarsest grid; the realistic
    default needs the finest (the models do not describe its effects well enough on fewer nodes). Either way the
    calibration at the run's end meets the issue's bar."""
    qd = {"qd": IDEAL_QD} if module == "ideal" else {}
    bench = BenchFile.model_validate({"simulation": {"time_scale": 0, "family": "qd", **qd,
                                                     "mount": {"tilt_x_deg": 0, "tilt_y_deg": 0}}})
    campaign = Campaign(name="qd-short", plan="qd-physical", sensors=("QD-0001",))
    dry = preflight_campaign(campaign, check=lambda a, z: None)
    assert len(dry.points) == campaign.planned_points() == 17 * 17 + 16 + 4 and dry.upper_bound
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(bench, catalogue, time_scale=0.0)
        try:
            (run_id,) = run_campaign(campaign, session)
        finally:
            session.close()
        run = catalogue.run(run_id)
        assert run["status"] == "completed", run["exit_reason"]
        stop = catalogue.run_value(run_id, "qd_physical_stop")
        batches = [k for k in catalogue.run_values(run_id) if k.startswith("qd_physical_batch_")]
        if module == "ideal":
            assert stop["stop"] and stop["check_max_deg"] <= 0.02 and stop["check_rms_deg"] <= 0.01
            assert len(batches) == 1 and run["n_points_recorded"] < len(dry.points) / 4
        else:
            assert len(batches) == 3 and run["n_points_recorded"] == len(dry.points)
        chosen = next(c for c in catalogue.calibrations(run_id) if c["chosen"])
        heldout = chosen["metrics"]["heldout"]
        assert heldout["max_deg"] <= 0.1 and heldout["rms_deg"] <= 0.03
