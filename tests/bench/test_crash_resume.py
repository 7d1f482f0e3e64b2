"""Issue acceptance test: kill the engine process at several points of a run, resume, and check that the
union of points is complete, with no duplicates and no lost readings.

The run is a real ``sunbench run`` process on a simulated bench whose clock runs 40× faster than real time
(a few seconds of wall time for the whole plan), killed with SIGKILL (a crash, not a clean abort) once the
catalogue shows it recorded enough points; then ``sunbench resume`` is started, killed again later, and so
on, and a last resume is let finish. The test watches the catalogue read-only, as the dashboard would.
"""

from __future__ import annotations

import collections
import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.campaign import load_campaign_file
from bench.catalogue import Catalogue, CatalogueError
from bench.preflight import preflight_campaign
from calibration.centroid import SpotFlag
from calibration.models import METHODS

SUNBENCH = Path(sys.executable).with_name("sunbench")

# seed 003 with fewer points: 4 centre + 8 tilt + 28 grid points, 72 frames
CAMPAIGN = """\
name: crash-resume
plan: seed003
operator: test
sensors: [SIM-0001]
seed003:
  azimuth_step_deg: 90
  zenith_stage_deg: [0, 10, 20, 30, 40, 50, 60]
  repeats: 2
  centre_repeats: 2
  tilt_stage: true
  tilt_repeats: 1
"""
# an LED warms up in seconds (a xenon lamp takes ~7 simulated minutes); 40× real time: ~12 s for the plan
BENCH = """\
simulation:
  time_scale: 40
  source: led
"""
# lineage totals at which the three processes are killed: in the centre, tilt and grid stages
KILL_AT = (3, 9, 22)
POLL_S = 0.02
ENV = {**{k: v for k, v in os.environ.items() if k != "SUNBENCH_CATALOGUE"},
       "COLUMNS": "160", "NO_COLOR": "1", "TERM": "dumb"}



def start(workdir: Path, name: str, *args) -> subprocess.Popen:
    """A sunbench process with stdout and stderr in files (a pipe nobody reads could block it)."""
    stdout = open(workdir / f"{name}.out", "w")
    stderr = open(workdir / f"{name}.err", "w")
    try:
        return subprocess.Popen([str(SUNBENCH), *map(str, args)], stdout=stdout, stderr=stderr, env=ENV,
                                cwd=workdir)
    finally:
        stdout.close()
        stderr.close()


def snapshot(path: Path):
    """(newest run, keys recorded by its lineage), read-only; None while there is nothing to read yet."""
    try:
        with Catalogue(path, readonly=True) as cat:
            runs = cat.runs()
            if not runs:
                return None
            newest = runs[-1]
            return newest, cat.completed_keys(cat.lineage(newest["id"]))
    except CatalogueError:  # not created yet, or created but not migrated yet
        return None


def kill_when(proc: subprocess.Popen, path: Path, *, after_run: int | None, at_least: int, log: Path,
              deadline_s: float = 30.0):
    """SIGKILL `proc` once its run (newer than `after_run`) recorded a point and the lineage `at_least` points.

    Returns (the killed run, the keys the catalogue showed committed just before the kill).
    """
    deadline = time.monotonic() + deadline_s
    while True:
        if proc.poll() is not None:
            pytest.fail(f"the process ended (exit {proc.returncode}) before it could be killed at {at_least} points "
                        f"(a test-design failure: slow the simulated bench down)\n{log.read_text()[-2000:]}")
        if time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            pytest.fail(f"no {at_least} points recorded within {deadline_s} s")
        state = snapshot(path)
        if state is not None:
            run, keys = state
            if (after_run is None or run["id"] > after_run) and run["n_points_recorded"] >= 1 and len(keys) >= at_least:
                proc.send_signal(signal.SIGKILL)
                proc.wait(timeout=10)
                assert proc.returncode == -signal.SIGKILL
                return run, keys
        time.sleep(POLL_S)


def test_killed_runs_resume_to_a_complete_lineage_without_duplicates(tmp_path):
    assert SUNBENCH.exists(), f"no console script {SUNBENCH}: install the package (bash scripts/setup.sh)"
    t_start = time.monotonic()
    campaign_file, bench_file, db = tmp_path / "campaign.yaml", tmp_path / "bench.yaml", tmp_path / "cat.sqlite"
    campaign_file.write_text(CAMPAIGN)
    bench_file.write_text(BENCH)
    campaign = load_campaign_file(campaign_file)
    planned = {p.key: p.repeats for p in preflight_campaign(campaign, check=lambda a, z: None).points}
    assert len(planned) == 40 and KILL_AT[-1] < len(planned) - 5

    # -- run, killed; resume, killed; resume, killed; resume to the end -----------------------------------
    killed, seen = [], {}
    name = "run"
    proc = start(tmp_path, name, "run", campaign_file, "--bench", bench_file, "--catalogue", db)
    for i, at_least in enumerate(KILL_AT):
        run, keys = kill_when(proc, db, after_run=killed[-1] if killed else None, at_least=at_least,
                              log=tmp_path / f"{name}.err")
        with Catalogue(db, readonly=True) as cat:
            # a killed process cannot say goodbye: its run stays "running" until the next engine starts
            assert cat.run(run["id"])["status"] == "running"
        killed.append(run["id"])
        seen[run["id"]] = keys
        name = f"resume{i + 1}"
        proc = start(tmp_path, name, "resume", run["id"], "--bench", bench_file, "--catalogue", db)
    assert proc.wait(timeout=60) == 0, (tmp_path / f"resume{len(KILL_AT)}.err").read_text()
    stdout = (tmp_path / f"resume{len(KILL_AT)}.out").read_text().strip().splitlines()
    final = int(stdout[-1])

    with Catalogue(db, readonly=True) as cat:
        # -- the lineage: every killed run marked crashed, each resume linked to the run before ------------
        lineage = cat.lineage(final)
        assert lineage == killed + [final]
        assert [r["id"] for r in cat.runs()] == lineage  # no stray run
        parents = [cat.run(run_id)["parent_run_id"] for run_id in lineage]
        assert parents == [None] + lineage[:-1]
        for run_id in killed:
            run = cat.run(run_id)
            assert run["status"] == "crashed", run
            assert "ended while it was running" in run["exit_reason"]
            assert run["ended_utc"] is not None
            assert run["n_points_recorded"] >= 1  # every process contributed points
        final_run = cat.run(final)
        assert final_run["status"] == "completed", final_run
        assert final_run["n_points_planned"] == len(planned)
        assert final_run["n_points_recorded"] >= 1

        # -- the union of points: complete, no key twice, nothing committed before a kill lost -------------
        points = cat.points(lineage)
        counts = collections.Counter(p["key"] for p in points)
        assert set(counts) == set(planned), (set(planned) - set(counts), set(counts) - set(planned))
        assert [k for k, n in counts.items() if n > 1] == []
        assert cat.completed_keys(lineage) == set(planned)
        for run_id, keys in seen.items():
            assert keys <= cat.completed_keys(cat.lineage(run_id)), f"points of run {run_id} lost"

        # -- readings: exactly the planned frames of every point, each repeat once -------------------------
        for p in points:
            assert p["n_readings"] == planned[p["key"]], p
        readings = cat.readings(lineage)
        repeats = collections.defaultdict(list)
        for r in readings:
            repeats[r.key].append(r.repeat)
        assert {k: sorted(v) for k, v in repeats.items()} == {k: list(range(n)) for k, n in planned.items()}
        assert len(readings) == sum(planned.values())

        # -- the campaign's queue and the calibrations of the final run --------------------------------------
        (queue,) = cat.fleet(final_run["campaign_id"])
        assert (queue["status"], queue["run_id"]) == ("done", final)
        calibrations = cat.calibrations(final)
        assert {c["method"] for c in calibrations} == set(campaign.methods or METHODS)
        chosen = [c["method"] for c in calibrations if c["chosen"]]
        assert chosen == ["physical"]

        unusable = int(SpotFlag.NEAR_EDGE | SpotFlag.ROI_CLIPPED)
        good = [r for r in readings if r.ok and not int(r.value("flags", 0)) & unusable]

    # -- the export holds one row per good frame of the whole lineage ---------------------------------------
    export = subprocess.run([str(SUNBENCH), "export", str(final), "--format", "csv", "--catalogue", str(db)],
                            capture_output=True, text=True, env=ENV, cwd=tmp_path, timeout=60)
    assert export.returncode == 0, export.stderr
    rows = list(csv.DictReader(export.stdout.splitlines()))
    assert len(rows) == len(good) > 0.9 * sum(planned.values())

    def frame(zenith, azimuth, repeat, x):
        return round(float(zenith), 6), round(float(azimuth), 6), int(repeat), round(float(x), 6)

    assert collections.Counter(frame(r["zenith_deg"], r["azimuth_deg"], r["repeat"], r["x_px"]) for r in rows) == \
        collections.Counter(frame(r.zenith_deg, r.azimuth_body_deg, r.repeat, r.value("x_px")) for r in good)
    assert {r["sensor_id"] for r in rows} == {"SIM-0001"}
    assert time.monotonic() - t_start < 60  # ~20 s on a laptop; a hung process fails here rather than never
