"""A fleet's sensors on the bench (issue 10, items 1 and 2): a simulated sensor is built from its serial alone,
every sensor after the first waits for the operator to confirm its mount, and the serial the module reports
is checked against the one the run is labelled with before anything is measured."""

import threading

import pytest

from bench.benchfile import BenchFile
from bench.campaign import Campaign, Seed003Procedure
from bench.catalogue import Catalogue
from bench.runner import ResumeRefused, open_session, resume_and_continue, resume_run, run_campaign
from drivers.cmos_sensor import CmosSunSensor
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.transport import open_port

FLEET = Campaign(name="fleet", frames="none", sensors=("FM-101", "FM-102", "FM-103"), seed003=Seed003Procedure(
    azimuth_step_deg=90.0, repeats=1, centre_repeats=1, tilt_stage=False))  # 32 points a sensor


def yes(request):
    return True


@pytest.fixture
def catalogue(tmp_path):
    with Catalogue(tmp_path / "catalogue.sqlite") as c:
        yield c


@pytest.fixture
def session(catalogue):
    s = open_session(BenchFile(simulation=SimBenchConfig(time_scale=0.0, seed=5)), catalogue)
    yield s
    s.close()


# -- item 1: a simulated sensor is its serial's ---------------------------------------------------------------
def test_a_serials_sensor_is_the_same_whatever_was_mounted_before():
    fresh = {serial: SimBench(time_scale=0.0).mount_sensor(serial) for serial in ("FM-101", "FM-102", "SIM-0001")}
    bench = SimBench(time_scale=0.0)
    for serial in ("FM-102", "FM-101", "FM-102", "SIM-0001", "FM-101"):
        assert bench.mount_sensor(serial) == fresh[serial]
        assert bench.world.sensor.serial == serial
    # the bench file's own serial is its configured sensor, untouched
    assert fresh["SIM-0001"] == SimBenchConfig().sensor.truth()
    assert fresh["FM-101"].build != fresh["FM-102"].build  # flight sensors have their own build errors


def test_a_hundred_mounts_never_fail_and_stay_near_the_configured_build():
    bench = SimBench(time_scale=0.0)
    base = bench.config.sensor.truth().build
    for i in range(100):
        truth = bench.mount_sensor(f"FM-{i:03d}")
        build = truth.optics  # the ray trace's own checks of the build
        assert abs(build.gap_mm - base.gap_mm) <= 0.09 + 1e-12  # 3σ at most, never a random walk
        assert abs(build.x0_px - base.x0_px) <= 18 + 1e-9 and abs(build.y0_px - base.y0_px) <= 18 + 1e-9


def test_the_simulated_module_reports_the_mounted_serial():
    bench = SimBench(time_scale=0.0)
    urls = bench.register()
    try:
        module = CmosSunSensor(open_port(urls["sensor"], baudrate=921600, timeout_s=0.5))
        assert module.reports_serial and module.identify().serial == "SIM-0001"
        bench.mount_sensor("FM-102")
        assert module.identify().serial == "FM-102"
    finally:
        bench.unregister()


def test_a_fleet_resumed_in_another_process_measures_the_sensor_it_was_measuring(tmp_path):
    """Kill (here: abort) a 3-sensor campaign during its third sensor, resume it with a new session: the
    third sensor is the one it was, not one derived from whatever the new process mounted before."""
    bench_file = BenchFile(simulation=SimBenchConfig(time_scale=0.0, seed=5))
    with Catalogue(tmp_path / "c.sqlite") as catalogue:
        first = open_session(bench_file, catalogue)
        seen = {}

        def on_run(run_id, sensor_id):
            seen[sensor_id] = (run_id, first.devices.sim.world.sensor)

        fired = threading.Event()
        first.engine.subscribe(lambda e: e.kind == "point" and e.data["index"] == 5 and "FM-103" in seen
                               and not fired.is_set() and (fired.set() or first.engine.abort()))
        try:
            runs = run_campaign(FLEET, first, confirm_mount=yes, on_run=on_run)
        finally:
            first.close()
        statuses = [catalogue.run(r)["status"] for r in runs]
        assert statuses == ["completed", "completed", "aborted"]
        (campaign,) = catalogue.campaigns()
        assert campaign["status"] == "aborted"

        second = open_session(bench_file, catalogue)
        try:
            resumed = resume_and_continue(runs[-1], second, confirm_mount=yes)
            assert second.devices.sim.world.sensor == seen["FM-103"][1]
        finally:
            second.close()
        (new_id,) = resumed
        assert catalogue.lineage(new_id) == [runs[-1], new_id]
        assert catalogue.run(new_id)["status"] == "completed"
        assert len(catalogue.completed_keys(catalogue.lineage(new_id))) == 32
        assert catalogue.campaign(campaign["id"])["status"] == "completed"


# -- item 2: mounts are confirmed, serials checked --------------------------------------------------------
def test_each_next_sensor_waits_for_the_operator_and_the_first_is_checked_by_its_serial(session):
    asked = []
    runs = run_campaign(FLEET, session, confirm_mount=lambda r: asked.append(r) or True)
    assert [(r.sensor_id, r.position, r.count) for r in asked] == [("FM-102", 1, 3), ("FM-103", 2, 3)]
    catalogue = session.catalogue
    assert [catalogue.run(r)["provenance"]["devices"]["sensor"] for r in runs] == \
        [f"SB-CMOS-PINHOLE, serial {s}, firmware 1.0.0" for s in FLEET.sensors]


def test_a_mount_nobody_confirms_stops_the_campaign_before_that_sensor(session):
    catalogue = session.catalogue
    (run_id,) = run_campaign(FLEET, session)  # nobody to ask
    campaign_id = catalogue.run(run_id)["campaign_id"]
    assert catalogue.campaign(campaign_id)["status"] == "aborted"
    assert [(e["sensor_id"], e["status"], e["run_id"]) for e in catalogue.fleet(campaign_id)] == \
        [("FM-101", "done", run_id), ("FM-102", "queued", None), ("FM-103", "queued", None)]
    assert any("mount sensor FM-102" in e["message"] and "not confirmed" in e["message"]
               for e in catalogue.events(None))
    # resuming from its last (complete) run goes on with the queued sensors, asking again
    more = resume_and_continue(run_id, session, confirm_mount=yes)
    assert [catalogue.run(r)["sensor_id"] for r in more] == ["FM-102", "FM-103"]
    assert catalogue.campaign(campaign_id)["status"] == "completed"


def test_a_sensor_reporting_another_serial_fails_its_run_before_anything_is_measured(session):
    catalogue, sim = session.catalogue, session.devices.sim

    def wrong_one(request):  # the operator confirms, but mounted the first sensor again
        sim.mount_sensor("FM-101")
        return True

    runs = run_campaign(FLEET, session, confirm_mount=wrong_one)
    assert len(runs) == 2
    run = catalogue.run(runs[1])
    assert (run["sensor_id"], run["status"], run["n_points_recorded"], run["started_utc"]) == \
        ("FM-102", "failed", 0, None)
    assert "FM-101" in run["exit_reason"] and "FM-102" in run["exit_reason"]
    assert catalogue.readings([runs[1]]) == []
    assert catalogue.campaign(run["campaign_id"])["status"] == "failed"
    assert [e["status"] for e in catalogue.fleet(run["campaign_id"])] == ["done", "failed", "queued"]

    # the right sensor mounted, the failed run resumes, and the campaign goes on
    more = resume_and_continue(runs[1], session, confirm_mount=yes)
    assert [catalogue.run(r)["status"] for r in more] == ["completed", "completed"]
    assert catalogue.run(more[0])["parent_run_id"] == runs[1]
    assert catalogue.campaign(run["campaign_id"])["status"] == "completed"


def test_the_first_sensor_of_a_campaign_is_checked_too(session, monkeypatch):
    catalogue = session.catalogue
    # an operator who did not swap the sensor: the bench's own SIM-0001 stays on it
    monkeypatch.setattr(session.devices.sim, "mount_sensor", lambda serial: None)
    (run_id,) = run_campaign(FLEET.model_copy(update={"sensors": ("FM-201",)}), session)
    run = catalogue.run(run_id)
    assert run["status"] == "failed" and run["n_points_recorded"] == 0
    assert "reports serial SIM-0001, not FM-201" in run["exit_reason"]
    monkeypatch.undo()
    child = resume_run(run_id, session)  # now mounted: the first sensor needs no confirmation, only its serial
    assert catalogue.run(child)["status"] == "completed"
    assert catalogue.campaign(run["campaign_id"])["status"] == "completed"


def test_a_resume_the_operator_does_not_confirm_measures_nothing(session):
    catalogue, engine = session.catalogue, session.engine
    started, fired = [], threading.Event()
    engine.subscribe(lambda e: e.kind == "point" and e.data["index"] == 3 and "FM-102" in started
                     and not fired.is_set() and (fired.set() or engine.abort()))
    first, second = run_campaign(FLEET.model_copy(update={"sensors": ("FM-101", "FM-102")}), session,
                                 confirm_mount=yes, on_run=lambda run_id, sensor_id: started.append(sensor_id))
    assert catalogue.run(second)["status"] == "aborted"
    with pytest.raises(ResumeRefused, match="FM-102 was not confirmed mounted"):
        resume_run(second, session, confirm_mount=lambda r: False)
    assert [r["id"] for r in catalogue.runs()] == [first, second]
    assert catalogue.campaign(catalogue.run(second)["campaign_id"])["status"] == "aborted"
