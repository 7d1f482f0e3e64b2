"""The physical plan (issue 9): preflight bounds, its stopping rule driven by readings, a run on the simulated bench,
resume, and the timing estimate from the table's own speeds."""

import threading

import numpy as np
import pytest

from bench.benchfile import BenchFile
from bench.campaign import Campaign, PhysicalProcedure
from bench.catalogue import Catalogue
from bench.families.cmos import DESCRIPTOR as CMOS
from bench.families.cmos import spot_reading
from bench.messages import Capture, CloseShutter, MayStopEarly, Measure, Point, Record, SetExposure
from bench.plans import physical_plan
from bench.preflight import TimingModel, preflight_campaign, timing_from_table
from bench.runner import _provenance, check_campaign, open_session, resume_run, run_campaign, timing_model
from calibration.design import DEFAULT_SENSOR
from calibration.geometry import incidence_from_stage_angle
from calibration.pinhole import spot_from_direction
from calibration.synthetic import EXAMPLE_BUILD
from drivers.interfaces import AxisMotion, Limits
from drivers.sim.bench import SimBenchConfig

PHYSICAL = Campaign(name="physical", plan="physical", frames="none", methods=("physical",))


def _warm(session) -> None:
    """Light the lamp before a run, so the simulated clock then counts the plan's time alone."""
    session.devices.source.lamp_on()
    session.devices.source.wait_until_warm(timeout_s=7200.0, poll_s=0.01)


def test_preflight_expands_every_batch_within_the_limits_in_under_three_minutes(session):
    report = check_campaign(PHYSICAL, session)
    assert report.ok, report.violations
    procedure = PhysicalProcedure()
    assert len(report.points) == procedure.max_points == 16 + 2 * 8 + 8
    assert report.upper_bound and "stops after" in report.upper_bound
    assert report.warmup_s > 0  # the simulated xenon lamp's warm-up, counted apart
    assert report.duration_s - report.warmup_s <= 180.0
    assert {p.stage for p in report.points} == {"physical", "check"}
    assert sum(p.stage == "check" for p in report.points) == 8
    # every pose lies inside the bench file's soft limits, and the keys are stable (resume relies on them)
    again = check_campaign(PHYSICAL, session)
    assert [p.key for p in again.points] == [p.key for p in report.points]
    seed003 = check_campaign(Campaign(name="s"), session)
    assert seed003.upper_bound is None
    assert report.duration_s - report.warmup_s < 0.3 * (seed003.duration_s - seed003.warmup_s)


def _drive(plan, noise_px, seed=0):
    """Run a plan against a perfect bench of EXAMPLE_BUILD (body direction = stage angles) with centroid noise."""
    rng = np.random.default_rng(seed)
    messages, answer = [], None
    while True:
        try:
            msg = plan.send(answer)
        except StopIteration:
            return messages
        messages.append(msg)
        answer = None
        if isinstance(msg, SetExposure):
            answer = msg.exposure_ms
        elif isinstance(msg, Capture):
            answer = [spot_reading(0, 320.0, 240.0, 716.0, 60, 0, "ok")]
        elif isinstance(msg, Measure):
            p = msg.point
            x, y = spot_from_direction(p.zenith_stage_deg, p.azimuth_deg, EXAMPLE_BUILD, DEFAULT_SENSOR.pixel_pitch_mm)
            answer = [spot_reading(i, float(x + rng.normal(0, noise_px)), float(y + rng.normal(0, noise_px)),
                                   700.0, 60, 0, "ok", zenith_deg=p.zenith_stage_deg, azimuth_body_deg=p.azimuth_deg)
                      for i in range(p.repeats)]


def test_the_plan_stops_after_the_first_batch_once_the_targets_are_met():
    messages = _drive(physical_plan(PhysicalProcedure()), noise_px=0.02)
    measured = [m.point for m in messages if isinstance(m, Measure)]
    assert len(measured) == 16 + 8
    assert measured[0].zenith_stage_deg == 0  # normal incidence first: the table is there after auto-exposure
    records = {m.key: m.value for m in messages if isinstance(m, Record)}
    assert records["physical_batch_1"]["stop"] and "physical_batch_2" not in records
    assert records["physical_stop"]["reason"] == "targets met" and records["physical_stop"]["batches_measured"] == 1
    assert records["physical_stop"]["check_rms_deg"] <= 0.02
    assert any(isinstance(m, MayStopEarly) for m in messages) and isinstance(messages[-1], CloseShutter)


def test_the_plan_goes_on_to_its_cap_while_the_targets_are_not_met():
    messages = _drive(physical_plan(PhysicalProcedure()), noise_px=1.0)  # 1 px centroids: far from 0.02°
    measured = [m.point for m in messages if isinstance(m, Measure)]
    assert len(measured) == PhysicalProcedure().max_points
    records = {m.key: m.value for m in messages if isinstance(m, Record)}
    assert [records[f"physical_batch_{k}"]["stop"] for k in (1, 2, 3)] == [False, False, False]
    assert records["physical_stop"]["reason"] == "cap reached" and records["physical_stop"]["reasons"]


def test_physical_campaign_on_the_simulated_bench_stops_early_within_three_minutes(session):
    _warm(session)
    clock = session.devices.sim.world.clock
    t0 = clock.now()
    (run_id,) = run_campaign(PHYSICAL, session)
    bench_s = clock.now() - t0
    catalogue = session.catalogue
    assert catalogue.run(run_id)["status"] == "completed"
    assert bench_s <= 180.0, bench_s
    stop = catalogue.run_value(run_id, "physical_stop")
    assert stop["stop"] and stop["batches_measured"] < 3
    assert len(catalogue.completed_keys([run_id])) < PhysicalProcedure().max_points
    assert stop["check_rms_deg"] <= 0.02  # the check directions, never fitted
    chosen = next(c for c in catalogue.calibrations(run_id) if c["chosen"])
    assert chosen["method"] == "physical" and chosen["metrics"]["heldout"]["rms_vector_deg"] <= 0.02
    logs = [e["message"] for e in catalogue.events(run_id) if e["kind"] == "log"]
    assert any(m.startswith("stopped after batch") for m in logs) and any("may stop early" in m for m in logs)


def test_the_engine_answers_a_point_with_the_body_direction_it_records(session):
    point = Point("p", "test", 30.0, 40.0, 2)
    answers = []

    def plan():
        answers.extend((yield Measure(point)))

    run_id = session.catalogue.create_run(campaign_id=None, sensor_id="SIM-0001", plan_name="test", plan_args={},
                                          provenance=_provenance(session, PHYSICAL, "SIM-0001"), n_points_planned=1,
                                          descriptor=CMOS)
    assert session.engine.execute(plan(), run_id=run_id) == "completed"
    geometry = session.bench_file.bench_geometry()
    zenith = float(incidence_from_stage_angle(40.0, geometry.lever_arm_mm, geometry.source_distance_mm))
    assert [(r.zenith_deg, r.azimuth_body_deg) for r in answers] == [(pytest.approx(zenith), 30.0)] * 2
    row = session.catalogue.readings([run_id])[0]
    assert (row.zenith_deg, row.azimuth_body_deg) == (pytest.approx(zenith), 30.0)


def test_an_interrupted_physical_run_resumes_to_the_same_decision(session):
    engine = session.engine
    fired = threading.Event()
    engine.subscribe(lambda e: e.kind == "point" and e.data["index"] == 10 and not fired.is_set()
                     and (fired.set() or engine.abort()))
    (first,) = run_campaign(PHYSICAL, session)
    catalogue = session.catalogue
    assert catalogue.run(first)["status"] == "aborted"
    engine._listeners.clear()
    second = resume_run(first, session)
    assert catalogue.run(second)["status"] == "completed"
    # the replayed points answered with their recorded body directions, so batch 1 decided as a fresh run does
    stop = catalogue.run_value(second, "physical_stop")
    assert stop["stop"] and stop["batches_measured"] == 1
    lineage = catalogue.lineage(second)
    assert len(catalogue.completed_keys(lineage)) == 16 + 8
    assert len(catalogue.completed_keys([second])) == 16 + 8 - 10


def test_timing_comes_from_the_table_the_bench_connected(session):
    config = SimBenchConfig()
    base = timing_model(session)
    assert base.rates_deg_s == (config.azimuth_axis.max_rate_deg_s, config.zenith_axis.max_rate_deg_s)
    assert base.accels_deg_s2 == pytest.approx((config.azimuth_axis.accel_deg_s2, config.zenith_axis.accel_deg_s2),
                                                rel=1e-3)
    before = check_campaign(PHYSICAL, session).duration_s
    session.devices.table.azimuth.set_velocity_params(2.0, 4.0)  # the stage itself is slowed down
    slow = timing_model(session)
    assert slow.rates_deg_s[0] == pytest.approx(2.0, rel=1e-3) and slow.rates_deg_s[1] == pytest.approx(10.0, rel=1e-3)
    assert check_campaign(PHYSICAL, session).duration_s > before + 60


def test_a_table_that_cannot_tell_keeps_the_default_timing():
    class Silent:
        def expected_motion(self):
            return None, AxisMotion(4.0)

    class Broken:
        def expected_motion(self):
            raise OSError("port gone")

    base = TimingModel(rate_deg_s=10.0, accel_deg_s2=20.0)
    partial = timing_from_table(Silent(), base)
    assert partial.rates_deg_s == (10.0, 4.0) and partial.accels_deg_s2 == (20.0, 20.0)
    assert timing_from_table(Broken(), base) == base


def test_preflight_uses_each_axis_speed():
    az, zen = Limits(-180, 360), Limits(-10, 70)

    def check(a, z):
        az.check("azimuth", a)
        zen.check("zenith", z)

    fast = preflight_campaign(PHYSICAL, check=check, timing=TimingModel())
    slow = preflight_campaign(PHYSICAL, check=check,
                     timing=TimingModel(azimuth_rate_deg_s=2.0, azimuth_accel_deg_s2=4.0))
    assert fast.ok and slow.ok and slow.duration_s > 2 * fast.duration_s


@pytest.mark.parametrize("table", ["smc100", "lx200"])
def test_other_tables_report_what_they_know(tmp_path, table):
    catalogue = Catalogue(tmp_path / "c.sqlite")
    config = SimBenchConfig(time_scale=0.0, table=table, azimuth_axis={"max_rate_deg_s": 6.0})
    s = open_session(BenchFile(simulation=config), catalogue)
    try:
        timing = timing_model(s)
        if table == "smc100":  # VA? answers the speed; the acceleration is not asked, so the bench's stays
            assert timing.rates_deg_s == pytest.approx((6.0, 10.0)) and timing.accels_deg_s2 == (20.0, 20.0)
        else:  # the LX200 protocol cannot be asked: the simulated bench's configuration stands
            assert s.devices.table.expected_motion() == (None, None)
            assert timing.rates_deg_s == (10.0, 10.0)
    finally:
        s.close()
        catalogue.close()


def test_each_procedure_has_its_own_auto_exposure():
    from bench.campaign import AutoExposure
    from bench.plans import procedure_auto_exposure

    procedure = PhysicalProcedure(auto_exposure=AutoExposure(target_peak_fraction=0.5))
    campaign = PHYSICAL.model_copy(update={"physical": procedure})
    assert procedure_auto_exposure(campaign).target_peak_fraction == 0.5
    assert procedure_auto_exposure(Campaign(name="s")).target_peak_fraction == 0.7


def test_an_lx200_reports_its_configured_slew_rate():
    from drivers.meade import LX200Table

    mount = LX200Table(object(), Limits(-180, 360), Limits(-10, 70), name="mount", slew_rate_deg_s=8.0,
                       slew_accel_deg_s2=4.0)  # the constructor sends nothing
    assert mount.expected_motion() == (AxisMotion(8.0, 4.0), AxisMotion(8.0, 4.0))
    timing = timing_from_table(mount, TimingModel())
    assert timing.rates_deg_s == (8.0, 8.0) and timing.accels_deg_s2 == (4.0, 4.0)
