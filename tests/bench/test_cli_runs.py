"""The campaign commands of `sunbench`: run, runs, show, resume, export, fleet — their contract on the command line.

`run` is started as a real process (it installs signal handlers and prints the run id on its last line for
scripts); the read-only commands go through typer's CliRunner. Two tests run `run` in-process to look at
the simulated world afterwards (what a separate process would take with it).
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from clitools import (
    ALL_METHODS,
    ENV,
    SUNBENCH,
    assert_user_error_text,
    flat,
    invoke,
    method_rows,
    sunbench_process,
)

import bench.cli_runs as cli_runs
from bench.campaign import load_campaign_file
from bench.catalogue import Catalogue, CatalogueError
from bench.preflight import preflight_campaign
from calibration.centroid import SpotFlag

ROOT = Path(__file__).resolve().parents[2]
SEED003 = ROOT / "examples" / "seed003.yaml"

# seed 003 with fewer points (4 azimuths): 40 points, 73 frames with the auto-exposure probe
SMALL = """\
name: {name}
plan: seed003
operator: test
sensors: {sensors}
seed003:
  azimuth_step_deg: 90
  zenith_stage_deg: [0, 10, 20, 30, 40, 50, 60]
  repeats: 2
  centre_repeats: 2
  tilt_stage: true
  tilt_repeats: 1
"""


def runs_in(db: Path) -> list[dict]:
    with Catalogue(db, readonly=True) as cat:
        return cat.runs()


def good_readings(cat, lineage) -> list:
    unusable = int(SpotFlag.NEAR_EDGE | SpotFlag.ROI_CLIPPED)
    return [r for r in cat.readings(lineage) if r.ok and not int(r.value("flags", 0)) & unusable]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli-runs")


@pytest.fixture(scope="module")
def seed003_run(workdir):
    """`sunbench run examples/seed003.yaml --time-scale 0`, once for the module: (process, catalogue, run id)."""
    db = workdir / "seed003.sqlite"
    proc = sunbench_process("run", SEED003, "--time-scale", 0, "--catalogue", db, cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    return proc, db, int(proc.stdout.strip().splitlines()[-1])


# --- run --------------------------------------------------------------------------------------------------
def test_run_prints_the_preflight_and_the_run_id_on_its_last_line(seed003_run):
    proc, db, run_id = seed003_run
    lines = proc.stdout.strip().splitlines()
    assert re.match(r"preflight: 80 points, 313 frames, \d+ moves per sensor × 1 sensor\(s\); about [\d.]+ min",
                    flat(proc.stdout)), proc.stdout
    assert lines[-1] == str(run_id)  # the id alone, for scripts: RUN=$(sunbench run … | tail -1)
    assert f"run {run_id} (SIM-0001): completed" in proc.stdout
    assert "Traceback" not in proc.stderr
    (run,) = runs_in(db)
    assert ((run["id"], run["status"], run["n_points_recorded"], run["n_points_planned"])
            == (run_id, "completed", 80, 80))


def test_dry_run_runs_nothing(workdir):
    db = workdir / "dry.sqlite"
    proc = sunbench_process("run", SEED003, "--dry-run", "--time-scale", 0, "--catalogue", db, cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    assert flat(proc.stdout).startswith("preflight: 80 points, 313 frames")
    assert not re.search(r"^\d+$", proc.stdout, re.M) and "run 1" not in proc.stdout  # no run id, no summary
    assert not db.exists()  # a dry run writes nothing: it does not even open the catalogue


@pytest.mark.parametrize("campaign, bench, preflight", [
    ("seed003.yaml", None, "preflight: 80 points, 313 frames"),
    ("physical.yaml", None, "preflight: at most 40 points, 161 frames"),
    ("qd-grid.yaml", "bench-sim-qd.yaml", "preflight: 549 points, 1667 frames"),
    ("qd-physical.yaml", "bench-sim-qd.yaml", "preflight: at most 309 points, 642 frames"),
    ("qd-grid.yaml", "bench-sim-qd-lx200.yaml", "preflight: 549 points, 1667 frames"),
])
def test_every_example_campaign_passes_its_preflight(tmp_path, campaign, bench, preflight):
    """The README's example commands: each campaign of examples/ on its bench file, dry run."""
    examples = ROOT / "examples"
    result = invoke("run", examples / campaign, "--dry-run", "--time-scale", 0, "--catalogue", tmp_path / "c.sqlite",
                    *(("--bench", examples / bench) if bench else ()))
    assert result.exit_code == 0, result.output
    assert flat(result.stdout).startswith(preflight), result.stdout


# a real bench (nothing listens there: connecting would fail, but nothing may even try while it is in use)
REAL_BENCH = """\
simulation: null
devices:
  table: {kind: lx200, url: "socket://127.0.0.1:9"}
  source: {kind: led, url: "socket://127.0.0.1:9"}
  sensor: {kind: cmos, url: "socket://127.0.0.1:9"}
"""


def test_a_dry_run_leaves_a_real_bench_alone_while_another_process_drives_it(workdir):
    bench = workdir / "real.yaml"
    bench.write_text(REAL_BENCH)
    db = workdir / "busy.sqlite"
    with Catalogue(db):  # what a server driving the bench holds: its devices are that process's
        proc = sunbench_process("run", SEED003, "--dry-run", "--bench", bench, "--catalogue", db, cwd=workdir)
    assert_user_error_text(proc.stderr, proc.returncode, f"the bench is in use by pid {os.getpid()}",
                           "dry-run the campaign on its dashboard")
    proc = sunbench_process("run", SEED003, "--yes", "--bench", bench, "--catalogue", db, cwd=workdir)
    assert proc.returncode == 2 and "--yes confirms sensor mounts only on a simulated bench" in flat(proc.stderr)


@pytest.mark.parametrize("edit, fragments", [
    ({"seed003": {"repeats": 0}}, ["field seed003.repeats", "greater than or equal to 1"]),
    ({"colour": "red"}, ["field colour", "Extra inputs are not permitted"]),
    ({"methods": ["magic"]}, ["field methods", "magic"]),
], ids=["repeats-0", "unknown-key", "unknown-method"])
def test_a_bad_campaign_file_names_the_file_and_the_field(workdir, edit, fragments):
    import yaml

    document = yaml.safe_load(SEED003.read_text())
    for key, value in edit.items():
        document[key] = {**document[key], **value} if isinstance(value, dict) else value
    path = workdir / f"bad-{next(iter(edit))}.yaml"
    path.write_text(yaml.safe_dump(document))
    db = workdir / "bad-campaign.sqlite"
    proc = sunbench_process("run", path, "--time-scale", 0, "--catalogue", db, cwd=workdir)
    assert_user_error_text(proc.stderr, proc.returncode, str(path), *fragments)
    assert proc.stdout == ""
    assert not db.exists() or runs_in(db) == []


@pytest.mark.parametrize("text, fragments", [
    ("simulation:\n  time_scale: -1\n", ["field simulation.time_scale", "greater than or equal to 0"]),
    ("simulation: {}\ndevices:\n  table:\n    zenith:\n      limits_deg: [45, -10]\n",
     ["field devices.table.zenith.limits_deg", "low must be below high"]),
    ("simulation: {}\ndevices:\n  sensor:\n    kind: webcam\n", ["field devices.sensor.kind", "'webcam'"]),
], ids=["time-scale", "limits", "kind"])
def test_a_bad_bench_file_names_the_file_and_the_field(workdir, text, fragments):
    path = workdir / "bad-bench.yaml"
    path.write_text(text)
    db = workdir / "bad-bench.sqlite"
    proc = sunbench_process("run", SEED003, "--bench", path, "--catalogue", db, cwd=workdir)
    assert_user_error_text(proc.stderr, proc.returncode, str(path), *fragments)
    assert not db.exists() or runs_in(db) == []


LIMITED_BENCH = "simulation: {}\ndevices:\n  table:\n    zenith:\n      limits_deg: [-10, 45]\n"


def test_a_campaign_beyond_the_soft_limits_is_refused_listing_every_violation(workdir):
    bench = workdir / "limited.yaml"
    bench.write_text(LIMITED_BENCH)
    db = workdir / "limited.sqlite"
    proc = sunbench_process("run", SEED003, "--bench", bench, "--time-scale", 0, "--catalogue", db, cwd=workdir)
    message = assert_user_error_text(proc.stderr, proc.returncode, "preflight refused the campaign")
    # every grid point at 50° and 60° on the zenith stage, at each of the 8 azimuths, and nothing else
    expected = {(az, zen) for az in range(0, 360, 45) for zen in (50, 60)}
    listed = {(int(float(a)), int(float(z))) for a, z in
              re.findall(r"point grid/zen=\S+/az=\S+ \(azimuth ([\d.]+)°, zenith stage ([\d.]+)°\)", message)}
    assert listed == expected, message
    assert len(proc.stderr.strip().splitlines()) == 1 + len(expected)  # one line per violation
    assert "outside the soft limits [-10.0, 45.0]" in message  # the limit it breaks
    with Catalogue(db, readonly=True) as cat:
        assert cat.runs() == [] and cat.campaigns() == []


def _capture_sessions(monkeypatch, on_open=None) -> list:
    """Keep every session the CLI opens (and let `on_open` look at it first)."""
    sessions = []
    original = cli_runs._session

    def capture(bench, catalogue, time_scale):
        session = original(bench, catalogue, time_scale)
        sessions.append(session)
        if on_open:
            on_open(session)
        return session

    monkeypatch.setattr(cli_runs, "_session", capture)
    return sessions


def test_a_refused_campaign_moves_nothing_and_lights_nothing(workdir, monkeypatch):
    bench = workdir / "limited.yaml"
    bench.write_text(LIMITED_BENCH)
    homed = []
    sessions = _capture_sessions(monkeypatch, lambda s: homed.append(s.devices.sim.world.stage_true_deg()))
    result = invoke("run", SEED003, "--bench", bench, "--time-scale", 0, "--catalogue", workdir / "limited2.sqlite")
    assert result.exit_code == 2, result.output
    (session,) = sessions
    world = session.devices.sim.world
    assert world.stage_true_deg() == homed[0]  # where homing left it
    assert not world.lamp.on and not world.lamp.shutter_open


# --- runs, show, export ----------------------------------------------------------------------------------
def test_runs_lists_the_run(seed003_run):
    _, db, run_id = seed003_run
    result = invoke("runs", "--catalogue", db)
    assert result.exit_code == 0, result.output
    row = next(line for line in result.stdout.splitlines() if re.match(rf"^\W*{run_id}\s", line))
    assert re.search(r"\b1\b.*SIM-0001.*seed003.*completed.*80/80", row), row


def test_show_prints_status_provenance_and_every_method(seed003_run):
    _, db, run_id = seed003_run
    result = invoke("show", run_id, "--catalogue", db)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert f"run {run_id} · sensor SIM-0001 (cmos) · plan seed003 · completed" in text
    assert "points recorded (lineage): 80 of 80" in text
    assert re.search(r"provenance: simulated bench, config [0-9a-f]{12}, sunbench \S+, operator lab", text), text
    for role in ("table:", "source:", "sensor:"):
        assert role in text
    assert "exposure_ms:" in text and "centre_px:" in text and "tilt_stage:" in text
    rows = method_rows(result.stdout)
    assert set(rows) == set(ALL_METHODS), result.stdout
    assert [m for m, chosen in rows.items() if chosen] == ["physical"]
    for column in ("RMS", "zenith", "azimuth", "vector"):
        assert column in text


def test_export_csv_is_the_bench_data_that_fit_reads(seed003_run, workdir):
    _, db, run_id = seed003_run
    path = workdir / "data.csv"
    result = invoke("export", run_id, "--format", "csv", "-o", path, "--catalogue", db)
    assert result.exit_code == 0, result.output
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert {"zenith_deg", "azimuth_deg", "x_px", "y_px", "repeat", "exposure_ms", "sensor_id"} <= set(rows[0])
    with Catalogue(db, readonly=True) as cat:
        assert len(rows) == len(good_readings(cat, [run_id])) > 300
    fit = invoke("fit", "cmos", path)
    assert fit.exit_code == 0, fit.output
    assert set(method_rows(fit.stdout)) == set(ALL_METHODS)
    assert f"{len(rows)} frames from" in flat(fit.stdout)


def test_export_json_has_the_run_its_points_readings_and_calibrations(seed003_run):
    _, db, run_id = seed003_run
    result = invoke("export", run_id, "--format", "json", "--catalogue", db)
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert {"run", "points", "readings", "calibrations"} <= set(document)
    assert document["run"]["id"] == run_id and document["run"]["status"] == "completed"
    assert document["lineage"] == [run_id]
    assert len(document["points"]) == 80
    assert len(document["readings"]) == sum(p["n_readings"] for p in document["points"]) == 312
    assert {c["method"] for c in document["calibrations"]} == set(ALL_METHODS)
    assert [c["method"] for c in document["calibrations"] if c["chosen"]] == ["physical"]


def test_export_refuses_an_unknown_format(seed003_run):
    _, db, run_id = seed003_run
    result = invoke("export", run_id, "--format", "xml", "--catalogue", db)
    assert result.exit_code == 2
    assert "csv or json" in flat(result.output)


def test_show_an_unknown_run(seed003_run):
    _, db, _ = seed003_run
    result = invoke("show", 999, "--catalogue", db)
    assert result.exit_code == 2, result.output
    assert "no run 999" in flat(result.stderr)
    assert "Traceback" not in result.output


# --- fleet -----------------------------------------------------------------------------------------------
def test_a_fleet_campaign_runs_every_sensor_and_fleet_prints_a_row_each(workdir):
    campaign = workdir / "fleet.yaml"
    campaign.write_text(SMALL.format(name="fleet", sensors="[A, B, C]"))
    db = workdir / "fleet.sqlite"
    proc = sunbench_process("run", campaign, "--time-scale", 0, "--catalogue", db, "--yes", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    runs = runs_in(db)
    assert [(r["sensor_id"], r["status"], r["n_points_recorded"]) for r in runs] == \
        [(s, "completed", 40) for s in "ABC"]
    # the first sensor is checked by its serial alone; each next one is confirmed mounted (here by --yes)
    text = flat(proc.stderr)
    assert "mount sensor A" not in text
    for i, sensor in ((2, "B"), (3, "C")):
        assert f"mount sensor {sensor} on the bench (sensor {i} of 3 of campaign 1): confirmed (--yes)" in text
    with Catalogue(db, readonly=True) as cat:
        assert [r["provenance"]["devices"]["sensor"] for r in runs] == \
            [f"SB-CMOS-PINHOLE, serial {s}, firmware 1.0.0" for s in "ABC"]  # what the module said, per run
        assert cat.campaign(runs[0]["campaign_id"])["status"] == "completed"
    assert proc.stdout.strip().splitlines()[-1] == str(runs[-1]["id"])
    for r in runs:
        assert f"run {r['id']} ({r['sensor_id']}): completed" in proc.stdout
    (campaign_id,) = {r["campaign_id"] for r in runs}

    result = invoke("fleet", campaign_id, "--catalogue", db)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    for column in ("RMS zenith", "RMS azimuth", "RMS vector"):
        assert column in text
    rows = [line for line in result.stdout.splitlines() if re.match(r"^\W*\d+\W+[ABC]\W", line)]
    assert len(rows) == 3, result.stdout
    for line, r in zip(rows, runs):
        cells = [c.strip() for c in re.split(r"[│┃|]", line) if c.strip()]
        assert cells[1:4] == [r["sensor_id"], "done", str(r["id"])], cells
        rms = [float(c) for c in cells[-3:]]
        assert all(0 < v < 1 for v in rms), cells  # held-out RMS of a good fit: hundredths of a degree


def test_the_operator_confirms_each_next_sensor_at_the_prompt_and_resume_goes_on(workdir):
    campaign = workdir / "asked.yaml"
    campaign.write_text(SMALL.format(name="asked", sensors="[A, B, C]"))
    db = workdir / "asked.sqlite"
    proc = subprocess.run([str(SUNBENCH), "run", str(campaign), "--time-scale", "0", "--catalogue", str(db)],
                          input="y\nn\n", capture_output=True, text=True, env=ENV, cwd=workdir, timeout=120)
    assert proc.returncode == 1, proc.stderr  # the campaign did not complete
    text = flat(proc.stderr)
    assert "Mount sensor B on the bench (sensor 2 of 3 of campaign 1). Is it mounted? [y/N]" in text
    assert "Mount sensor C on the bench (sensor 3 of 3 of campaign 1). Is it mounted?" in text
    runs = runs_in(db)
    assert [(r["sensor_id"], r["status"]) for r in runs] == [("A", "completed"), ("B", "completed")]
    assert proc.stdout.strip().splitlines()[-1] == str(runs[-1]["id"])
    assert f"campaign 1: aborted; `sunbench resume {runs[-1]['id']}` goes on with it" in flat(proc.stdout)

    # nobody at the terminal: no answer is no confirmation
    proc = sunbench_process("resume", runs[-1]["id"], "--time-scale", 0, "--catalogue", db, cwd=workdir)
    assert proc.returncode == 1 and "no answer: the sensor was not confirmed" in flat(proc.stderr)
    assert len(runs_in(db)) == 2
    proc = sunbench_process("resume", runs[-1]["id"], "--time-scale", 0, "--catalogue", db, "--yes", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    assert [(r["sensor_id"], r["status"]) for r in runs_in(db)][-1] == ("C", "completed")
    with Catalogue(db, readonly=True) as cat:
        assert cat.campaign(1)["status"] == "completed"


def test_fleet_of_an_unknown_campaign(workdir, seed003_run):
    _, db, _ = seed003_run
    result = invoke("fleet", 999, "--catalogue", db)
    assert result.exit_code == 2
    assert "no campaign 999" in flat(result.stderr)


# --- Ctrl-C -----------------------------------------------------------------------------------------------
def test_sigint_aborts_a_running_run_and_records_it(workdir):
    campaign = workdir / "sigint.yaml"
    campaign.write_text(SMALL.format(name="sigint", sensors="[SIM-0001]"))
    bench = workdir / "slow.yaml"
    bench.write_text("simulation:\n  time_scale: 20\n  source: led\n")  # ~25 s for the whole plan
    db = workdir / "sigint.sqlite"
    with open(workdir / "sigint.out", "w") as out, open(workdir / "sigint.err", "w") as err:
        proc = subprocess.Popen([str(SUNBENCH), "run", str(campaign), "--bench", str(bench), "--catalogue", str(db)],
                                stdout=out, stderr=err, env=ENV, cwd=workdir)
    try:
        deadline = time.monotonic() + 30
        while True:
            assert proc.poll() is None, "the run ended before it could be interrupted"
            assert time.monotonic() < deadline, "no point recorded in 30 s"
            try:
                runs = runs_in(db)
            except CatalogueError:
                runs = []
            if runs and runs[0]["n_points_recorded"] >= 2:
                break
            time.sleep(0.02)
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    stdout = (workdir / "sigint.out").read_text()
    assert "Traceback" not in (workdir / "sigint.err").read_text()
    assert proc.returncode == 1  # an aborted run is not a success
    (run,) = runs_in(db)
    assert stdout.strip().splitlines()[-1] == str(run["id"])
    assert f"run {run['id']} (SIM-0001): aborted" in stdout
    assert (run["status"], run["exit_reason"]) == ("aborted", "aborted by the operator")
    assert run["ended_utc"] is not None
    assert 2 <= run["n_points_recorded"] < 40
    with Catalogue(db, readonly=True) as cat:
        events = cat.events(run["id"])
        planned = {p.key: p.repeats for p in preflight_campaign(load_campaign_file(campaign),
                                                        check=lambda a, z: None).points}
        for p in cat.points(run["id"]):  # whole points only
            assert p["n_readings"] == planned[p["key"]], p
        (queue,) = cat.fleet(run["campaign_id"])
    messages = [(e["kind"], e["message"]) for e in events]
    assert ("state", "running → aborting") in messages
    assert ("status", "running → aborted: aborted by the operator") in messages
    assert messages[-1] == ("state", "aborting → idle")
    # finalisation (shutter closed, lamp to standby, table stopped) journals a warning only when it fails
    assert not [m for kind, m in messages if kind == "warning" and "finalisation" in m], messages
    # not done: still queued, linked to its run, so resuming the campaign resumes that run
    assert (queue["status"], queue["run_id"]) == ("queued", run["id"])
    with Catalogue(db, readonly=True) as cat:
        assert cat.campaign(run["campaign_id"])["status"] == "aborted"


def test_sigint_leaves_the_shutter_closed_and_the_lamp_in_standby(workdir, monkeypatch):
    """In-process, so the simulated world can be looked at afterwards: SIGINT at the third point."""

    def interrupt_at_third_point(session):
        def on_event(event):
            if event.kind == "point" and event.data["index"] == 3:
                os.kill(os.getpid(), signal.SIGINT)  # the CLI's handler runs in this (the main) thread
        session.engine.subscribe(on_event)

    sessions = _capture_sessions(monkeypatch, interrupt_at_third_point)
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    db = workdir / "sigint-inprocess.sqlite"
    try:
        result = invoke("run", SEED003, "--time-scale", 0, "--catalogue", db)
    finally:
        for s, handler in handlers.items():
            signal.signal(s, handler)
    assert result.exit_code == 1, result.output  # aborted
    (run,) = runs_in(db)
    assert (run["status"], run["exit_reason"]) == ("aborted", "aborted by the operator")
    assert 3 <= run["n_points_recorded"] <= 4
    assert result.stdout.strip().splitlines()[-1] == str(run["id"])
    world = sessions[0].devices.sim.world
    assert not world.lamp.shutter_open and world.irradiance() == 0.0  # shutter closed
    assert world.lamp.on  # standby: a xenon lamp keeps burning behind its closed shutter
    assert not world.azimuth.busy() and not world.zenith.busy()  # table stopped


def test_a_run_that_could_not_close_the_shutter_is_shown_ended_unsafe(workdir, monkeypatch):
    """The shutter's cable pulled after the last point: `run` and `show` say the run ended unsafe, and that the
    lamp was switched off instead of left at standby behind the open shutter."""

    def pull_the_shutter_cable_at_the_end(session):
        shutter = session.devices.sim.devices["shutter"]
        session.engine.subscribe(lambda e: e.kind == "point" and e.data["index"] == e.data["total"]
                                 and setattr(shutter.faults, "disconnected", True))

    sessions = _capture_sessions(monkeypatch, pull_the_shutter_cable_at_the_end)
    campaign = workdir / "unsafe.yaml"
    campaign.write_text(SMALL.format(name="unsafe", sensors="[SIM-0001]"))
    db = workdir / "unsafe.sqlite"
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        result = invoke("run", campaign, "--time-scale", 0, "--catalogue", db)
    finally:
        for s, handler in handlers.items():
            signal.signal(s, handler)
    assert result.exit_code == 1, result.output
    (run,) = runs_in(db)
    text = flat(result.stdout)
    assert f"run {run['id']} ended unsafe: the shutter did not close" in text, result.stdout
    assert "the lamp was switched off instead" in text and "see to the bench before the next run" in text
    assert not sessions[0].devices.sim.world.lamp.on  # out, not burning behind the open shutter
    shown = invoke("show", run["id"], "--catalogue", db)
    assert shown.exit_code == 0, shown.output
    assert f"run {run['id']} ended unsafe: the shutter did not close" in flat(shown.stdout)
