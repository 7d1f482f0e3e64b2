"""The CSS family on the bench (seed 000): the css-sweep plan's geometry — every face swept through its field around its
normal, the temperature sweep, the check directions, counts that match the campaign's —, its preflight on the example
bench, and a simulated run end to end through the engine whose fit at the run's end recovers the simulated head."""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest

from bench.benchfile import BenchFile, load_bench_file
from bench.campaign import Campaign, CampaignFileError, CssSweepProcedure, load_campaign_file
from bench.catalogue import Catalogue
from bench.families import family, table_mount
from bench.families.css import CHECK, DARK, DESCRIPTOR, SWEEP, css_sweep_plan, sweep_points, table_poses
from bench.messages import CloseShutter, LampOn, Measure, OpenShutter, SetTemperature, WaitWarm
from bench.preflight import preflight_campaign
from bench.runner import check_campaign, open_session, run_campaign, session_mount
from calibration.css.head import CHANNELS, FACES, NORMALS, sun_vectors
from calibration.mount import ForkMount
from calibration.stage_geometry import StageGeometry, arm_ratio, body_vectors_from_stage

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SMALL = CssSweepProcedure(step_deg=10.0, around=6, repeats=1, temperatures_c=(25.0, 40.0), dark_repeats=4,
                          check_directions=12)


def _messages(procedure, mount=StageGeometry(0.0)):
    """The plan's messages, answered as preflight answers them (a temperature reached, no readings)."""
    plan = css_sweep_plan(procedure, mount=mount)
    out, answer = [], None
    while True:
        try:
            msg = plan.send(answer)
        except StopIteration:
            return out
        out.append(msg)
        answer = msg.temperature_c if isinstance(msg, SetTemperature) else None


def _direction(key: str) -> tuple[float, float]:
    z, a = key.split("_")[-2:]
    return float(z[1:]), float(a[1:])


def _incidence(points, face) -> np.ndarray:
    zenith, azimuth = np.array([_direction(p.key) for p in points]).T
    return np.degrees(np.arccos(np.clip(sun_vectors(zenith, azimuth) @ np.array(NORMALS[face]), -1, 1)))


# --- the plan's geometry ----------------------------------------------------------------------------------------

def test_every_face_is_swept_through_its_field_around_its_normal():
    procedure = CssSweepProcedure()
    points = [p for p in sweep_points(procedure, StageGeometry(0.0)) if p.stage == SWEEP]
    assert len({p.key for p in points}) == len(points)
    rings = list(np.arange(0.0, 88.0, 5.0)) + [88.0]
    for face in FACES:
        incidence = _incidence(points, face)
        assert np.min(incidence) < 1e-3, face  # the normal itself
        for ring in rings:
            on = np.abs(incidence - ring) < 1e-3
            # a ring is `around` directions about the normal, fewer where it is short; one at the centre
            length = 2 * math.pi * math.sin(math.radians(ring)) / math.radians(5)
            expected = 1 if ring == 0 else min(8, max(3, round(length)))
            assert on.sum() >= expected, (face, ring, on.sum())
        assert np.max(incidence[incidence < 89]) == pytest.approx(88.0, abs=1e-3)
    # a direction two faces share is measured once: px's 45° ring toward +y is py's 45° ring toward +x
    zenith, azimuth = np.array([_direction(p.key) for p in points]).T
    both = np.isclose(zenith, 90) & np.isclose(azimuth, 45)
    assert both.sum() == 1
    # every channel is read at every point: the plan's readings are the head's, 18 channels each
    assert DESCRIPTOR.fields[0].name == "signals" and DESCRIPTOR.fields[0].shape == (len(CHANNELS),)


def test_the_sweep_reaches_behind_the_head_and_the_table_sets_it_exactly():
    """Faces other than +z face the source at body zeniths beyond 90°: the azimuth-on-zenith table takes them through
    its closed form (the zenith stage past 90°), the fork through its inverse, and each pose gives back the direction
    it was planned for."""
    procedure = CssSweepProcedure(step_deg=15.0, check_directions=8)
    q = arm_ratio(136.2, 7100.0)
    for mount in (StageGeometry(q), ForkMount(arm_ratio=q)):
        points = [p for p in sweep_points(procedure, mount) if p.stage != DARK]
        zenith, azimuth = np.array([_direction(p.key) for p in points]).T
        assert zenith.max() == pytest.approx(180.0) and (zenith > 90).sum() > len(points) / 3
        first = np.array([p.azimuth_deg for p in points])
        second = np.array([p.zenith_stage_deg for p in points])
        if isinstance(mount, StageGeometry):
            got = body_vectors_from_stage(first, second, mount)
            assert second.max() == pytest.approx(180.0, abs=1e-3) and second.min() >= -1e-9
        else:
            from calibration.mount import fork_vectors
            got = fork_vectors(first, second, mount)
            assert np.abs(first).max() <= 90 + 1e-9 and np.abs(second).max() <= 180 + 1e-9
        want = sun_vectors(zenith, azimuth)
        error = np.degrees(np.arccos(np.clip(np.sum(got * want, axis=1), -1, 1)))
        assert error.max() < 2e-3, error.max()  # the poses are rounded to 1e-4°


def test_table_poses_refuse_what_the_table_cannot_reach():
    from bench.plans import PlanError

    with pytest.raises(PlanError, match="cannot be set on the table"):
        table_poses([30.0], [0.0], StageGeometry(0.0, source_elevation_deg=40.0))


def test_the_order_is_a_serpentine_of_short_moves():
    points = [p for p in sweep_points(CssSweepProcedure(), StageGeometry(0.0)) if p.stage == SWEEP]
    poses = np.array([(p.azimuth_deg, p.zenith_stage_deg) for p in points])
    steps = np.abs(np.diff(poses, axis=0)).max(axis=1)
    assert np.median(steps) <= 45.0
    assert np.all(np.diff(np.floor(poses[:, 1] / 5.0 + 1e-9)) >= 0)  # the zenith stage only goes one way


def test_the_temperature_sweep_dark_readings_and_check_directions():
    messages = _messages(SMALL)
    kinds = [type(m).__name__ for m in messages]
    assert isinstance(messages[1], LampOn) and isinstance(messages[2], WaitWarm)
    temperatures = [m for m in messages if isinstance(m, SetTemperature)]
    assert [t.temperature_c for t in temperatures] == [25.0, 40.0]
    measures = [m.point for m in messages if isinstance(m, Measure)]
    stages = collections.Counter(p.stage for p in measures)
    dark = [p for p in measures if p.stage == DARK]
    assert [p.key for p in dark] == ["dark_t+025.0", "dark_t+040.0"] and all(p.repeats == 4 for p in dark)
    for point in dark:  # each dark point between a closed and an open shutter
        i = next(k for k, m in enumerate(messages) if isinstance(m, Measure) and m.point == point)
        assert isinstance(messages[i - 1], CloseShutter) and isinstance(messages[i + 1], OpenShutter)
    assert isinstance(messages[-1], CloseShutter) and kinds.count("OpenShutter") == 2
    # the full sweep and the check directions at the first temperature, the reduced sweep at the second
    first = [p for p in measures if "_t+025.0_" in p.key]
    second = [p for p in measures if "_t+040.0_" in p.key]
    assert {p.stage for p in first} == {SWEEP, CHECK} and {p.stage for p in second} == {SWEEP}
    assert stages[CHECK] == 12
    for face in FACES:
        incidence = np.round(_incidence(second, face))
        assert set(incidence[incidence < 89]) == {0.0, 30.0, 60.0}
    # a SetTemperature knows its points, so a resumed run does not wait on the plate for recorded readings
    assert set(temperatures[1].for_points) == {p.key for p in second} | {"dark_t+040.0"}
    # the check directions spread over the whole sphere, off every ring
    check = np.array([_direction(p.key) for p in measures if p.stage == CHECK])
    assert check[:, 0].min() < 45 and check[:, 0].max() > 135 and np.ptp(check[:, 1]) > 270


def test_counts_match_the_campaign_and_keys_are_stable():
    for procedure in (SMALL, CssSweepProcedure(), CssSweepProcedure(temperatures_c=(), check_directions=0)):
        campaign = Campaign(name="css", plan="css-sweep", css_sweep=procedure)
        first = preflight_campaign(campaign, check=lambda a, z: None)
        again = preflight_campaign(campaign, check=lambda a, z: None)
        assert [p.key for p in first.points] == [p.key for p in again.points]
        assert len(first.points) == campaign.planned_points() == len({p.key for p in first.points})
    no_plate = preflight_campaign(Campaign(name="css", plan="css-sweep", css_sweep=CssSweepProcedure(
        temperatures_c=(), check_directions=0)), check=lambda a, z: None)
    assert [p.key for p in no_plate.points if p.stage == DARK] == ["dark_tamb"]
    assert family("css").plans == ("css-sweep",) and family("css").sensor_kinds == ("css",)


@pytest.mark.parametrize("fields, words", [
    ({"temperatures_c": [25, 25]}, "listed twice"),
    ({"temperatures_c": [25, 120]}, "−20…70 °C"),
    ({"temperatures_c": [25, -30]}, "−20…70 °C"),
    ({"field_deg": 95}, "less than or equal to 90"),
    ({"step_deg": 0.1}, "greater than or equal to 0.5"),
])
def test_bad_sweeps_are_refused(tmp_path, fields, words):
    import yaml

    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump({"name": "x", "plan": "css-sweep", "css_sweep": fields}))
    with pytest.raises(CampaignFileError, match=words):
        load_campaign_file(path)


def test_the_sweep_is_capped_and_methods_are_the_css_ones():
    with pytest.raises(ValueError, match="limit is 5000"):
        Campaign(name="x", plan="css-sweep", css_sweep=CssSweepProcedure(step_deg=1.0, around=72))
    with pytest.raises(ValueError, match="known for the css-sweep plan"):
        Campaign(name="x", plan="css-sweep", methods=("physical",))
    assert Campaign(name="x", plan="css-sweep", methods=("kelly",)).methods == ("kelly",)
    assert Campaign(name="x", plan="css-sweep", methods=("kelly", "spline")).methods == ("kelly", "spline")


def _outcome(response, held=None, check=None, parameters=8):
    """A stand-in for a CSS calibration outcome: its law, Sun direction figures and fitted parameters."""
    from types import SimpleNamespace

    figure = lambda rms: None if rms is None else SimpleNamespace(rms_deg=rms, n_points=300)  # noqa: E731
    fits = {c: SimpleNamespace(valid=True, free=("p",) * parameters) for c in CHANNELS}
    return SimpleNamespace(response=response, sun_heldout=figure(held), sun_check=figure(check), fits=fits)


def test_the_run_end_fits_kelly_and_spline_and_keeps_the_better_held_out(monkeypatch):
    """DEFAULT_METHODS fits the Kelly law and the spline; rank_css_fits keeps the smaller held-out Sun error, a
    near tie (within 5 %) going to the law with fewer parameters, the check directions' error standing in for a fit
    without held-out figures, and fits with neither last, simplest first. The spline starts from the Kelly fit."""
    from bench import css_datafile
    from bench.families.css import DEFAULT_METHODS

    assert DEFAULT_METHODS == ("kelly", "spline") == css_datafile.DEFAULT_CSS_LAWS
    rank = lambda *o: [x.response for x in css_datafile.rank_css_fits(o)]  # noqa: E731
    kelly, spline = _outcome("kelly", 3.2), _outcome("spline", 0.18, parameters=27)
    assert rank(kelly, spline) == ["spline", "kelly"]
    assert rank(_outcome("kelly", 0.200), _outcome("spline", 0.195, parameters=27)) == ["kelly", "spline"]
    assert rank(_outcome("kelly", 0.200), _outcome("spline", 0.180, parameters=27)) == ["spline", "kelly"]
    assert rank(_outcome("kelly", check=0.9), _outcome("spline", check=0.1, parameters=27)) == ["spline", "kelly"]
    assert rank(_outcome("spline", parameters=27), _outcome("kelly")) == ["kelly", "spline"]
    assert rank(_outcome("spline", parameters=27), _outcome("power", 1.0)) == ["power", "spline"]
    calls = []
    monkeypatch.setattr(css_datafile, "fit_css", lambda data, response, start=None: calls.append(
        (response, start)) or _outcome(response))
    outcomes = css_datafile.fit_css_laws(None, DEFAULT_METHODS)
    assert [o.response for o in outcomes] == ["kelly", "spline"]
    assert calls[0] == ("kelly", None) and calls[1][0] == "spline" and calls[1][1] is outcomes[0]


# --- one reading ---------------------------------------------------------------------------------------------------

class _Head:
    """A head that answers one READ, its channels in another order than the family's."""

    name = "fake-head"

    def __init__(self, channels, saturated=(), under=()):
        from drivers.interfaces import CssHeadReading

        n = len(channels)
        self.reading = CssHeadReading(tuple(channels), tuple(float(i) for i in range(n)),
                                      tuple(1e-6 * (CHANNELS.index(c) + 1) for c in channels),
                                      tuple(c in saturated for c in channels), tuple(c in under for c in channels),
                                      24.5, 16, 160)

    def read(self, average=16):
        assert average == 16  # the thesis' ADC averaging
        return self.reading


def test_a_reading_is_put_in_the_head_order_and_clipped_channels_are_flagged():
    from bench.families.css import clipped_mask, read

    order = list(reversed(CHANNELS))
    reading = read(_Head(order, saturated=("pz_vis",), under=("mx_ir",)), 3, lambda: 12.5)
    assert (reading.repeat, reading.status, reading.t_s) == (3, "ok", 12.5)
    assert reading.values["signals"] == [1e-6 * (k + 1) for k in range(18)]  # by name, not by position
    assert reading.values["saturated"] == 1 << CHANNELS.index("pz_vis")
    assert reading.values["under_range"] == 1 << CHANNELS.index("mx_ir")
    assert DESCRIPTOR.validate(reading.values, ok=True, where="test")["temperature_c"] == 24.5
    mask = clipped_mask(reading.values)
    assert [CHANNELS[k] for k in np.flatnonzero(mask)] == ["mx_ir", "pz_vis"]


def test_a_head_without_the_familys_channels_is_a_device_error():
    from bench.families.css import read
    from drivers.errors import ProtocolError

    with pytest.raises(ProtocolError, match="missing mz_ir"):
        read(_Head(CHANNELS[:-1]), 0, lambda: 0.0)


def test_the_bench_data_leaves_a_clipped_channel_out_of_its_row():
    from bench.descriptor import ReadingRecord
    from bench.families.css import bench_data

    def record(i, stage, saturated=0, under=0):
        values = {"signals": [1e-6] * 18, "temperature_c": 25.0, "saturated": saturated, "under_range": under,
                  "n_samples": 16}
        return ReadingRecord(i, i, 1, f"k{i}", stage, 0.0, 0.0, 0.0 if stage == DARK else 30.0, 45.0, None, 0, "ok",
                             0.0, None, values)

    class Catalogue:
        def readings(self, run_ids):
            return [record(1, DARK), record(2, SWEEP, saturated=1 << 4), record(3, CHECK, under=1 << 17),
                    record(4, SWEEP, saturated=(1 << 18) - 1)]  # every channel clipped: no reading left

    data = bench_data(Catalogue(), [1], sensor_id="CSS-9")
    assert data.row_id.tolist() == [1, 2, 3] and data.sensor_id == "CSS-9"
    assert data.dark.tolist() == [True, False, False] and data.check.tolist() == [False, False, True]
    assert np.isnan(data.zenith_deg[0]) and data.zenith_deg[1] == 30.0
    assert np.flatnonzero(np.isnan(data.signals[1])).tolist() == [4]
    assert np.flatnonzero(np.isnan(data.signals[2])).tolist() == [17]


# --- preflight on the example files -------------------------------------------------------------------------------

@pytest.fixture
def css_session(tmp_path):
    bench = load_bench_file(EXAMPLES / "bench-sim-css.yaml")
    with Catalogue(tmp_path / "catalogue.sqlite") as catalogue:
        session = open_session(bench, catalogue, time_scale=0.0)
        try:
            yield session
        finally:
            session.close()


def test_the_example_campaign_passes_its_preflight_on_the_example_bench(css_session):
    campaign = load_campaign_file(EXAMPLES / "css-sweep.yaml")
    report = check_campaign(campaign, css_session)
    assert report.ok, report.violations
    assert len(report.points) == campaign.planned_points() == 753
    zenith_stage = [p.zenith_stage_deg for p in report.points]
    assert max(zenith_stage) == pytest.approx(180.0, abs=1e-3)  # the bottom face, right round


def test_a_table_that_cannot_reach_is_named_by_preflight(tmp_path):
    """The same bench with the zenith stage's usual soft limits (−10…70°): preflight lists every pose beyond them."""
    import yaml

    document = yaml.safe_load((EXAMPLES / "bench-sim-css.yaml").read_text())
    document["devices"]["table"]["zenith"]["limits_deg"] = [-10.0, 70.0]
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(BenchFile.model_validate(document), catalogue, time_scale=0.0)
        try:
            report = check_campaign(Campaign(name="css", plan="css-sweep", css_sweep=SMALL), session)
        finally:
            session.close()
    assert not report.ok and len(report.violations) > 10
    assert "zenith stage 180" in " ".join(report.violations)


def test_the_engine_records_the_planned_direction_behind_the_head(css_session):
    """The plan sets directions through the table's kinematics and the engine records the direction the same
    kinematics give; the simulated world, with its own kinematics, puts the source there too."""
    points = [p for p in sweep_points(CssSweepProcedure(step_deg=45.0, around=4, check_directions=4),
                                      session_mount(css_session)) if p.stage != DARK]
    assert isinstance(session_mount(css_session), StageGeometry)
    table = css_session.devices.table
    for point in points:
        want = sun_vectors(*_direction(point.key))
        recorded = sun_vectors(*css_session.engine.body_direction(point))
        assert np.degrees(np.arccos(min(1.0, float(want @ recorded)))) < 2e-3, point
        table.move_to(point.azimuth_deg, point.zenith_stage_deg)
        true = sun_vectors(*css_session.devices.sim.world.sun_direction_body())
        assert np.degrees(np.arccos(min(1.0, float(want @ true)))) < 0.02, point
    assert table_mount("azimuth-on-zenith", css_session.engine.geometry).arm_ratio > 0


# --- a simulated run end to end -----------------------------------------------------------------------------------

#: A head whose detectors follow the Kelly law the fit models (as the QD tests use the ideal module), on a table
#: homed to its true zeros, so the fitted normals can be held to their stated uncertainty
MODEL_TRUE_BENCH = {"css": {"response": "kelly"}, "azimuth_axis": {"home_switch_true_deg": 0.0},
                    "zenith_axis": {"home_switch_true_deg": 0.0, "hard_limits_deg": [-190.0, 190.0]}}
RUN_SWEEP = CssSweepProcedure(step_deg=10.0, around=6, repeats=2, temperatures_c=(25.0, 40.0), dark_repeats=6,
                              check_directions=16)


def test_a_css_campaign_is_recorded_fitted_and_recovers_the_simulated_head(tmp_path):
    import yaml

    document = yaml.safe_load((EXAMPLES / "bench-sim-css.yaml").read_text())
    for key, value in MODEL_TRUE_BENCH.items():
        document["simulation"][key] = {**document["simulation"].get(key, {}), **value}
    campaign = Campaign(name="css", plan="css-sweep", sensors=("CSS-0001",), css_sweep=RUN_SWEEP, methods=("kelly",))
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(BenchFile.model_validate(document), catalogue, time_scale=0.0)
        try:
            (run_id,) = run_campaign(campaign, session)
            truth = session.devices.sim.devices["sensor"].truth
        finally:
            session.close()
        run = catalogue.run(run_id)
        assert run["status"] == "completed", run["exit_reason"]
        assert run["family"] == "css" and catalogue.descriptor(run_id) == DESCRIPTOR
        assert run["n_points_recorded"] == campaign.planned_points()
        readings = catalogue.readings(run_id)
        assert all(len(r.values["signals"]) == 18 for r in readings)
        dark = [r for r in readings if r.stage == DARK]
        assert {round(r.values["temperature_c"]) for r in dark} == {25, 40}  # the plate swept the head
        # the top face's visible photodiode: lit at its normal, dark behind the shutter
        top = CHANNELS.index("pz_vis")
        lit = max(r.values["signals"][top] for r in readings if r.stage == SWEEP)
        assert lit > 1000 * max(abs(r.values["signals"][top]) for r in dark)

        (calibration,) = catalogue.calibrations(run_id)
        assert calibration["chosen"] and calibration["method"] == "kelly"
        doc = calibration["document"]
        assert doc["family"] == "css" and doc["source"] == f"run {run_id}"
        # every detector's normal within 3× its stated 1σ of the simulator's truth, or 0.02° (the table's encoder
        # and the poses' rounding)
        misses = []
        for channel in CHANNELS:
            entry = doc["diodes"][channel]
            assert entry["valid"], (channel, entry.get("fault"))
            normal = entry["normal"]
            fitted = sun_vectors(normal["zenith_deg"], normal["azimuth_deg"])
            error = np.degrees(np.arccos(min(1.0, float(fitted @ truth.diode(channel).normal))))
            if error > max(3 * normal["sd_deg"], 0.02):
                misses.append((channel, round(error, 4), normal["sd_deg"]))
        assert not misses, misses
        # the held-out figure of the Sun's direction is reported: in the metrics, the document and the journal
        held = calibration["metrics"]["held_out"]
        assert held["n_points"] > 100 and math.isfinite(held["rms_deg"]) and held["max_deg"] >= held["rms_deg"]
        assert doc["heldout"]["sun"]["heldout"] == held
        assert calibration["metrics"]["check"]["n_points"] + calibration["metrics"]["check"]["n_degenerate"] > 0
        fit_lines = [e["message"] for e in catalogue.events(run_id) if e["kind"] == "fit"]
        assert any("the Sun's direction held out: RMS" in line for line in fit_lines), fit_lines
        print(f"\n{run['n_points_recorded']} points, {len(readings)} readings; {fit_lines[0]}")
