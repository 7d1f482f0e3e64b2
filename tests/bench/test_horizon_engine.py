"""The engine's SetDiscRadius on the simulated horizon bench (examples/bench-sim-horizon.yaml): the iris is started
under the engine's lock and waited for outside it, so an emergency stop or an abort during a long iris move acts at
once (the iris is told to stop where it is); a stuck iris is a typed timeout; a radius off the plan's tolerance is a
fault; a source that is no Earth simulator is refused; a resumed run sets only the radii whose points are missing."""

from __future__ import annotations

import re
import threading
import time

import pytest
import yaml

from bench.benchfile import BenchFile, parse_bench_file
from bench.campaign import Campaign, HorizonGridProcedure
from bench.catalogue import Catalogue
from bench.engine import EngineState
from bench.families import family
from bench.messages import LampOn, SetDiscRadius, WaitWarm
from bench.runner import check_campaign, open_session, resume_run, run_campaign
from calibration.horizon.scan import earth_angular_radius_deg
from drivers.sim.bench import SimBenchConfig

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "bench-sim-horizon.yaml"
# a disc that warms and a cover that travels in a few hundredths of a second, the iris at its example speed (0.5°/s)
FAST_EARTH = {"thermal_tau_s": 0.02, "cover_s": 0.02, "iris_settle_s": 0.02}


def _bench(**earth) -> BenchFile:
    """The example horizon bench, its Earth simulator's model changed by `earth` (simulation.earth fields)."""
    document = yaml.safe_load(EXAMPLE.read_text())
    document["simulation"]["earth"].update(earth)
    return parse_bench_file(document, str(EXAMPLE))


def _one_pose(*radii, tolerance_deg=0.02) -> Campaign:
    """One pose (roll 0, pitch 0) per disc radius, one scan each."""
    return Campaign(name="h", plan="horizon-grid", sensors=("HZ-0001",),
                    horizon_grid=HorizonGridProcedure(disc_radii_deg=radii, roll_range_deg=0, pitch_range_deg=0,
                                                      roll_step_deg=1, pitch_step_deg=1, repeats=1, check_points=0,
                                                      tolerance_deg=tolerance_deg))


def _wait_for(predicate, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.002)


def _safe_end(earth) -> None:
    """The Earth simulator as the engine leaves it: the cover closed, the heater on at the standby setpoint."""
    assert earth.cover_state() == "CLOSED" and not earth.cover_open()
    assert earth.heater_on and earth.setpoint_k == 260.0


@pytest.mark.parametrize("command", ["emergency_stop", "abort"])
def test_a_stop_during_a_long_iris_move_acts_at_once_and_stops_the_iris(tmp_path, command):
    """Real time: the iris goes 68° → 52° at 0.5°/s (32 s). An emergency stop (or an abort) 0.3 s into the move returns
    within 0.2 s, the run ends aborted within a second with the cover closed and the heater at standby, and the iris
    was told to stop where it stood (its target is its position, well short of 52°)."""
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(_bench(**FAST_EARTH), catalogue, time_scale=1.0)
        earth, engine = session.devices.sim.earth, session.engine
        try:
            result = {}
            thread = threading.Thread(target=lambda: result.setdefault(
                "runs", run_campaign(_one_pose(52.0), session, confirm_mount=lambda *a: True)))
            thread.start()
            _wait_for(lambda: earth.iris_target_deg == 52.0 and earth.iris_moving())
            time.sleep(0.3)
            t0 = time.monotonic()
            getattr(engine, command)()
            took = time.monotonic() - t0
            thread.join(timeout=5.0)
            ended = time.monotonic() - t0
            assert not thread.is_alive()
            (run_id,) = result["runs"]
            run = catalogue.run(run_id)
            print(f"\n{command}: returned in {took * 1e3:.0f} ms, the run ended {ended * 1e3:.0f} ms after it; "
                  f"the iris stopped at {earth.iris_deg():.3f}°")
            assert took < 0.2 and ended < 1.0
            assert run["status"] == "aborted"
            reason = "emergency stop" if command == "emergency_stop" else "aborted by the operator"
            assert run["exit_reason"] == reason
            _safe_end(earth)
            stopped = earth.iris_deg()
            assert 60.0 < stopped < 68.0 and earth.iris_target_deg == pytest.approx(stopped)
            time.sleep(0.1)
            assert earth.iris_deg() == stopped and not earth.iris_moving()
            assert catalogue.completed_keys([run_id]) == set()
            assert engine.state is (EngineState.ESTOP if command == "emergency_stop" else EngineState.IDLE)
        finally:
            if engine.state is EngineState.ESTOP:
                engine.acknowledge_estop()
            session.close()


def test_an_emergency_stop_while_the_cover_opens_acts_at_once(tmp_path):
    """The cover is opened by the engine's checkpoint: started under the lock, waited for outside it. With a cover that
    takes 3 s (real time), an emergency stop 0.2 s into its travel returns within 0.2 s plus the cover's way back, and
    the cover ends closed."""
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(_bench(**{**FAST_EARTH, "cover_s": 3.0}), catalogue, time_scale=1.0)
        earth, engine = session.devices.sim.earth, session.engine
        try:
            result = {}
            thread = threading.Thread(target=lambda: result.setdefault(
                "runs", run_campaign(_one_pose(68.0), session, confirm_mount=lambda *a: True)))
            thread.start()
            _wait_for(lambda: earth.cover_state() == "MOVING", timeout_s=20.0)
            time.sleep(0.2)
            t0 = time.monotonic()
            engine.emergency_stop()
            took = time.monotonic() - t0
            thread.join(timeout=5.0)
            assert not thread.is_alive()
            # the e-stop closes the cover itself: it reverses after 0.2 s of travel, so it is back in ~0.2 s
            assert took < 0.2 + 0.2 + 0.15, took
            run = catalogue.run(result["runs"][0])
            assert (run["status"], run["exit_reason"]) == ("aborted", "emergency stop")
            _safe_end(earth)
        finally:
            if engine.state is EngineState.ESTOP:
                engine.acknowledge_estop()
            session.close()


def test_a_stuck_iris_times_out_through_the_engine_and_the_bench_is_made_safe(tmp_path):
    """An iris whose drive slips (it never leaves 68°, the controller keeps reporting a move) at 20× real time: the
    engine waits 1.5 × the driver's expected 7.4 s + 5 s = 16.1 s of bench time (polled every 0.05 s of wall time, 1 s
    of bench time), then fails the run with a DeviceTimeout naming the iris's position, tells the iris to stop, and
    leaves the bench safe."""
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(_bench(**FAST_EARTH), catalogue, time_scale=20.0)
        earth = session.devices.sim.earth
        try:
            earth.stick_iris()
            (run_id,) = run_campaign(_one_pose(64.3), session, confirm_mount=lambda *a: True)
        finally:
            session.close()
        run = catalogue.run(run_id)
    reason = run["exit_reason"]
    print(f"\n{reason}")
    assert run["status"] == "failed" and reason.startswith("DeviceTimeout")
    assert "a move to 64.3000° that should take 7.4 s (timeout 16.1 s" in reason and "it reads 68.0000°" in reason
    waited = float(re.search(r"iris not settled at its target ([0-9.]+) s after", reason).group(1))
    assert 16.1 < waited < 16.1 + 2.0
    _safe_end(earth)
    assert not earth.iris_moving() and earth.iris_target_deg == 68.0  # told to stop where it is


def test_a_radius_off_the_plans_tolerance_faults_the_run(tmp_path):
    """The iris takes its target to 1e-4° (the controller's resolution): a plan that asks 64.30037° within 1e-5° gets
    64.3004° back, and the run fails naming both, with nothing measured and the bench safe."""
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(_bench(), catalogue, time_scale=0.0)
        earth = session.devices.sim.earth
        try:
            (run_id,) = run_campaign(_one_pose(64.30037, tolerance_deg=1e-5), session, confirm_mount=lambda *a: True)
        finally:
            session.close()
        run = catalogue.run(run_id)
        assert catalogue.completed_keys([run_id]) == set()
    assert run["status"] == "failed" and run["exit_reason"].startswith("DeviceFault"), run["exit_reason"]
    assert "64.30040°, not 64.30037 ± 1e-05°" in run["exit_reason"]
    _safe_end(earth)


def test_a_source_that_is_no_earth_simulator_is_refused_by_preflight_and_by_the_engine(tmp_path):
    """A horizon plan on a sun-simulator bench: preflight refuses it before anything moves (not the bench's family,
    and no Earth simulator to set a disc radius on); the engine, handed the message anyway, fails the run with a
    DeviceFault and lights nothing."""
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(BenchFile(simulation=SimBenchConfig(time_scale=0.0, seed=5, source="led")), catalogue)
        try:
            report = check_campaign(_one_pose(68.0), session)
            assert not report.ok
            assert any("not an Earth simulator" in v and "68" in v for v in report.violations), report.violations
            provenance = {"bench_config_hash": "", "software_version": "", "devices": {}, "simulated": True,
                          "operator": "test"}
            run_id = catalogue.create_run(campaign_id=None, sensor_id="SIM-0001", plan_name="disc", plan_args={},
                                          provenance=provenance, descriptor=family("horizon").descriptor)

            def plan():
                yield LampOn()
                yield WaitWarm()
                yield SetDiscRadius(68.0)

            status = session.engine.execute(plan(), run_id=run_id)
            world = session.devices.sim.world
            assert not world.lamp.shutter_open
        finally:
            session.close()
        run = catalogue.run(run_id)
    assert status == "failed" and "DeviceFault" in run["exit_reason"] and "Earth simulator" in run["exit_reason"]


def test_a_resumed_run_sets_only_the_radii_whose_points_are_missing_and_fits_over_its_lineage(tmp_path):
    """Two radii (400 and 700 km), 5 × 3 grid poses each: the run is aborted once the first radius's points are all
    recorded and some of the second's; the resumed run journals the first radius as already recorded, sets only the
    second, measures only its missing points, completes and fits over both runs (both radii in the fit)."""
    procedure = HorizonGridProcedure(altitudes_km=(400.0, 700.0), roll_step_deg=16.5, pitch_step_deg=17.0, repeats=1,
                                     check_points=0)
    campaign = Campaign(name="h", plan="horizon-grid", sensors=("HZ-0001",), horizon_grid=procedure)
    first, second = (round(float(r), 4) for r in earth_angular_radius_deg([400.0, 700.0]))
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        session = open_session(_bench(), catalogue, time_scale=0.0)
        try:
            engine = session.engine
            engine.subscribe(lambda e: e.kind == "point" and e.data["index"] == 18 and engine.abort())
            (run_id,) = run_campaign(campaign, session, confirm_mount=lambda *a: True)
            assert catalogue.run(run_id)["status"] == "aborted"
            engine._listeners.clear()
            assert len(catalogue.completed_keys([run_id])) == 18
            source, asked = session.devices.source, []
            set_radius = source.set_disc_radius_deg
            source.set_disc_radius_deg = lambda radius, **kw: asked.append(radius) or set_radius(radius, **kw)
            new_id = resume_run(run_id, session, confirm_mount=lambda *a: True)
        finally:
            session.close()
        run = catalogue.run(new_id)
        assert run["status"] == "completed", run["exit_reason"]
        assert asked == [pytest.approx(second, abs=1e-4)]  # the first radius was not set again
        logs = [e["message"] for e in catalogue.events(new_id) if e["kind"] == "log"]
        assert f"disc radius {first:.4f}°: already recorded" in logs, logs
        assert f"the disc radius is {second:.4f}°" in logs
        assert len(catalogue.completed_keys([new_id])) == 30 - 18
        assert len(catalogue.completed_keys(catalogue.lineage(new_id))) == 30
        (calibration,) = catalogue.calibrations(new_id)
        doc = calibration["document"]
    assert calibration["chosen"] and doc["fit"]["n_scans"] == 30  # both runs' scans
    left_out = sorted(r["disc_radius_deg"] for r in doc["heldout"]["radius_out"])
    assert left_out == pytest.approx([second, first], abs=1e-3)
