"""Plans as message generators: tested without an engine or any device."""

import pytest

from bench.campaign import Alignment, AutoExposure, Campaign, GridProcedure, Seed003Procedure
from bench.families.cmos import spot_reading
from bench.messages import Capture, CloseShutter, LampOn, Measure, Move, OpenShutter, Record, SetExposure, WaitWarm
from bench.plans import PlanError, alignment_violations, auto_exposure, make_plan, seed003_plan
from bench.preflight import TimingModel, preflight_campaign
from calibration.design import BenchGeometry
from drivers.interfaces import Limits


def drive(plan, answer_for):
    """Run a plan, answering each message with `answer_for(msg)`; returns the messages."""
    messages, answer = [], None
    while True:
        try:
            msg = plan.send(answer)
        except StopIteration as stop:
            return messages, stop.value
        messages.append(msg)
        answer = answer_for(msg)


def dry(msg, peak=716.0):
    if isinstance(msg, Measure):
        return [spot_reading(i, 320.0, 240.0, peak, 60, 0, "ok") for i in range(msg.point.repeats)]
    if isinstance(msg, Capture):
        return [spot_reading(0, 320.0, 240.0, peak, 60, 0, "ok")]
    if isinstance(msg, SetExposure):
        return msg.exposure_ms
    return None


def test_seed003_plan_follows_the_thesis_procedure():
    messages, _ = drive(seed003_plan(Seed003Procedure()), dry)
    kinds = [type(m) for m in messages]
    assert kinds.index(LampOn) < kinds.index(WaitWarm) < kinds.index(OpenShutter) < kinds.index(Measure)
    assert isinstance(messages[-1], CloseShutter)
    points = [m.point for m in messages if isinstance(m, Measure)]
    centre = [p for p in points if p.stage == "centre"]
    tilt = [p for p in points if p.stage == "tilt"]
    grid = [p for p in points if p.stage == "grid"]
    assert len(centre) == 8 and all(p.zenith_stage_deg == 0 and p.repeats == 5 for p in centre)  # 8 × 5 = 40 frames
    assert len(tilt) == 16 and {p.zenith_stage_deg for p in tilt} == {-1.0, 1.0}
    assert len(grid) == 56 and all(p.repeats == 4 for p in grid)
    # zenith is the outer loop: all azimuths at each zenith, as in the thesis
    zeniths = [p.zenith_stage_deg for p in grid]
    assert zeniths == sorted(zeniths) and [p.azimuth_deg for p in grid[:8]] == [0, 45, 90, 135, 180, 225, 270, 315]
    keys = [p.key for p in points]
    assert len(set(keys)) == len(keys)
    again, _ = drive(seed003_plan(Seed003Procedure()), dry)
    assert [m.point.key for m in again if isinstance(m, Measure)] == keys  # stable keys: resume relies on them


def test_tilt_stage_recovers_a_known_offset():
    # the spot moves 2.4 px per degree of stage along +x; it crosses the centre at Ω = +0.3° for azimuth 0
    # and −0.3° for azimuth 180 (a 0.3° tilt along azimuth 0)
    import math

    def answer(msg):
        if isinstance(msg, Measure) and msg.point.stage == "tilt":
            offset = 0.3 * math.cos(math.radians(msg.point.azimuth_deg))
            x = 320.0 + 2.4 * (msg.point.zenith_stage_deg - offset)
            return [spot_reading(i, x, 240.0, 700.0, 60, 0, "ok") for i in range(msg.point.repeats)]
        return dry(msg)

    messages, _ = drive(seed003_plan(Seed003Procedure()), answer)
    tilt = next(m.value for m in messages if isinstance(m, Record) and m.key == "tilt_stage")
    assert tilt["tilt_x_deg"] == pytest.approx(0.3, abs=1e-9)
    assert tilt["tilt_y_deg"] == pytest.approx(0.0, abs=1e-9)
    assert tilt["mean_offset_deg"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("first, expected_steps", [("NoSpotError", 3), ("SaturatedSpotError", 3), ("ok", 1)])
def test_auto_exposure_raises_lowers_and_settles(first, expected_steps):
    spec = AutoExposure(start_ms=4.0, target_peak_fraction=0.7)
    replies = iter([first, "ok", "ok"])
    exposures = []

    def answer(msg):
        if isinstance(msg, SetExposure):
            exposures.append(msg.exposure_ms)
            return msg.exposure_ms
        if not isinstance(msg, Capture):
            return None
        status = next(replies)
        peak = 0.35 * 1023 if status == "ok" and len(exposures) == 2 else 0.7 * 1023
        return [spot_reading(0, 1.0, 1.0, peak, 50, 0, status)]

    messages, exposure = drive(auto_exposure(spec, 1023.0), answer)
    assert len(exposures) == expected_steps
    if first == "NoSpotError":
        assert exposures[1] == pytest.approx(16.0) and exposures[2] == pytest.approx(32.0)
    elif first == "SaturatedSpotError":
        assert exposures[1] == pytest.approx(4.0 / 3) and exposures[2] == pytest.approx(8.0 / 3)
    assert exposure == exposures[-1] and isinstance(messages[-1], Record)


def test_auto_exposure_gives_up_with_a_reason():
    spec = AutoExposure(start_ms=100.0, max_ms=200.0)
    answer = lambda m: m.exposure_ms if isinstance(m, SetExposure) else [spot_reading(0, 0, 0, 0, 0, 0, "NoSpotError")]  # noqa: E731
    with pytest.raises(PlanError, match="no exposure"):
        drive(auto_exposure(spec, 1023.0), answer)


def test_preflight_lists_every_violation_and_estimates_the_run():
    az, zen = Limits(-180, 360), Limits(-10, 45)

    def check(a, z):
        az.check("table azimuth", a)
        zen.check("table zenith", z)

    report = preflight_campaign(Campaign(name="c"), check=check, timing=TimingModel(rate_deg_s=10, accel_deg_s2=20))
    assert not report.ok
    assert len(report.violations) == 16  # zenith 50° and 60° at each of 8 azimuths
    assert all("table zenith" in v for v in report.violations)
    assert len(report.points) == 80 and report.n_frames >= 40 + 48 + 224
    assert report.duration_s > 60
    fine = preflight_campaign(Campaign(name="c"), check=lambda a, z: None)
    assert fine.ok and fine.n_moves > 70


def test_grid_plan_orders():
    outer = Campaign(name="g", plan="grid",
                     grid=GridProcedure(azimuths_deg=(0, 90), zenith_stage_deg=(0, 10), order="azimuth-outer"))
    messages, _ = drive(make_plan(outer), dry)
    poses = [(m.point.azimuth_deg, m.point.zenith_stage_deg) for m in messages if isinstance(m, Measure)]
    assert poses == [(0, 0), (0, 10), (90, 0), (90, 10)]
    assert any(isinstance(m, Move) for m in messages)


def test_alignment_tolerances_of_seed003():
    geometry = BenchGeometry(source_distance_mm=7100.0)
    good = Alignment(l1_mm=100.0, l2_mm=100.3, h1_mm=50.0, h2_mm=50.2, distance_mm=7103.0)
    assert alignment_violations(good, geometry) == []
    bad = Alignment(l1_mm=100.0, l2_mm=101.0, h1_mm=50.0, h2_mm=49.0, distance_mm=7090.0)
    problems = alignment_violations(bad, geometry)
    assert len(problems) == 3
    assert "ΔL = +1.00 mm" in problems[0] and "Δh = -1.00 mm" in problems[1]
