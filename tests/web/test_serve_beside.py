"""A real `sunbench serve` process and the command line beside it, and a server killed mid-campaign
(issue 10, items 12 and 13): the CLI's readers work while the server writes, a second writer is refused in
the command line's words, and a restarted server marks the dead run crashed, leaves its campaign to the
operator (nothing moves by itself) and resumes it when asked."""

import json
import time
import urllib.error
import urllib.request

from clitools import flat, sunbench_process
from serving import serving
from test_api import _wait_for

from bench.catalogue import Catalogue

# an LED warms up in seconds (a xenon lamp takes ~7 simulated minutes); 20× real time: ~1 s a point
BENCH = "simulation:\n  time_scale: 20\n  source: led\n"
SMALL = {"name": "small", "frames": "none", "operator": "test",
         "seed003": {"azimuth_step_deg": 90.0, "repeats": 1, "centre_repeats": 1, "tilt_stage": False}}  # 32 points
SMALL_YAML = """\
name: beside
plan: seed003
sensors: [SIM-0001]
seed003: {azimuth_step_deg: 90, repeats: 1, centre_repeats: 1, tilt_stage: false}
"""


def call(served, path, body=None, *, method=None):
    """(HTTP status, JSON answer) of the server's API, with its token."""
    request = urllib.request.Request(served.base + path, method=method or ("GET" if body is None else "POST"),
                                     data=None if body is None else json.dumps(body).encode(),
                                     headers={"Authorization": f"Bearer {served.token}",
                                              "Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def get(served, path):
    status, answer = call(served, path)
    assert status == 200, (path, answer)
    return answer


def wait_for(predicate, what, timeout_s=60.0):
    return _wait_for(predicate, what, timeout_s, poll_s=0.1)  # a server in another process: asked less often


def campaign_status(served, campaign_id):
    return next(c["status"] for c in get(served, "/api/campaigns")["data"] if c["id"] == campaign_id)


def test_the_command_line_reads_beside_a_running_server_and_a_second_writer_is_refused_in_its_words(tmp_path):
    (tmp_path / "bench.yaml").write_text(BENCH)
    (tmp_path / "small.yaml").write_text(SMALL_YAML)
    db = tmp_path / "bench.sqlite"
    with serving(tmp_path, None, "--bench", str(tmp_path / "bench.yaml")) as served:
        status, queued = call(served, "/api/campaigns", SMALL)
        assert status == 202, queued
        campaign_id = queued["campaign_id"]
        run = wait_for(lambda: next((r for r in get(served, "/api/runs")["data"] if r["n_points_recorded"] >= 2), None),
                       "the server's run to record points")
        assert run["status"] == "running"
        run_id = str(run["id"])

        runs = sunbench_process("runs", "--catalogue", db, cwd=tmp_path)
        assert runs.returncode == 0, runs.stderr
        assert "running" in runs.stdout and "SIM-0001" in runs.stdout
        show = sunbench_process("show", run_id, "--catalogue", db, cwd=tmp_path)
        assert show.returncode == 0, show.stderr
        assert flat(show.stdout).startswith(f"run {run_id} · sensor SIM-0001 (cmos) · plan seed003 · running")
        export = sunbench_process("export", run_id, "--format", "csv", "--catalogue", db, cwd=tmp_path)
        assert export.returncode == 0, export.stderr
        assert len([line for line in export.stdout.splitlines() if line and not line.startswith("#")]) >= 3
        fleet = sunbench_process("fleet", campaign_id, "--catalogue", db, cwd=tmp_path)
        assert fleet.returncode == 0 and "SIM-0001" in fleet.stdout, fleet.stderr
        dry = sunbench_process("run", "small.yaml", "--dry-run", "--time-scale", 0, "--catalogue", db, cwd=tmp_path)
        assert dry.returncode == 0, dry.stderr
        assert flat(dry.stdout).startswith("preflight: 32 points")

        holder = Catalogue.writer(db)
        assert holder.startswith(f"pid {served.proc.pid} (sunbench serve")
        for args in (("run", "small.yaml", "--time-scale", 0), ("resume", run_id, "--time-scale", 0)):
            refused = sunbench_process(*args, "--catalogue", db, cwd=tmp_path)
            message = flat(refused.stderr)
            assert refused.returncode == 2 and message.startswith("error:"), (args, refused.stderr)
            assert f"is in use by {holder}" in message and "stop it first" in message
            assert "`sunbench runs`, `show`, `export`, `fleet` and `run --dry-run` work meanwhile" in message
            assert "readonly" not in message and "Traceback" not in refused.stderr

        # and the server's run went on undisturbed
        assert wait_for(lambda: campaign_status(served, campaign_id) in ("completed", "aborted", "failed")
                        and campaign_status(served, campaign_id), "the campaign to end") == "completed"
        assert get(served, f"/api/runs/{run_id}")["n_points_recorded"] == 32
    assert Catalogue.writer(db) is None


def test_a_server_killed_mid_campaign_leaves_it_to_the_operator_and_resumes_it_when_asked(tmp_path):
    (tmp_path / "bench.yaml").write_text(BENCH)
    with serving(tmp_path, None, "--bench", str(tmp_path / "bench.yaml")) as served:
        status, queued = call(served, "/api/campaigns", {**SMALL, "sensors": ["SIM-0001", "FM-102"]})
        assert status == 202, queued
        campaign_id = queued["campaign_id"]
        wait_for(lambda: any(r["n_points_recorded"] >= 3 for r in get(served, "/api/runs")["data"]),
                 "the first run to record points")
        served.proc.kill()  # a crash: no clean abort, no goodbye
        served.proc.wait(timeout=10)

    with serving(tmp_path, None, "--bench", str(tmp_path / "bench.yaml"), "--time-scale", "100") as served:
        (crashed,) = get(served, "/api/runs")["data"]
        assert crashed["status"] == "crashed" and "ended while it was running" in crashed["exit_reason"]
        assert campaign_status(served, campaign_id) == "aborted"
        fleet = get(served, f"/api/campaigns/{campaign_id}/fleet")["data"]
        assert [(e["sensor_id"], e["status"], e["run_id"]) for e in fleet] == \
            [("SIM-0001", "queued", crashed["id"]), ("FM-102", "queued", None)]
        time.sleep(1.5)  # nothing runs by itself after a restart
        assert len(get(served, "/api/runs")["data"]) == 1
        assert get(served, "/api/status")["engine"]["state"] == "idle"

        status, answer = call(served, f"/api/runs/{crashed['id']}/resume", method="POST")
        assert status == 202, answer
        mount = wait_for(lambda: get(served, "/api/status")["mount"], "the mount of the second sensor")
        assert mount["sensor_id"] == "FM-102"
        resumed = get(served, "/api/runs")["data"][1]
        assert (resumed["parent_run_id"], resumed["status"]) == (crashed["id"], "completed")
        assert crashed["n_points_recorded"] + resumed["n_points_recorded"] == 32  # only the missing points
        status, answer = call(served, "/api/run/mount", {"sensor_id": "FM-102"})
        assert status == 200, answer
        assert wait_for(lambda: campaign_status(served, campaign_id) in ("completed", "aborted", "failed")
                        and campaign_status(served, campaign_id), "the campaign to end") == "completed"
        fleet = get(served, f"/api/campaigns/{campaign_id}/fleet")["data"]
        assert [e["status"] for e in fleet] == ["done", "done"]
