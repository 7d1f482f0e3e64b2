"""The web API on the simulated bench (time scale 0): every route, its refusals, and the event stream."""

import csv
import io
import json
import logging
import queue
import signal
import socket
import stat
import statistics
import threading
import time
from contextlib import contextmanager
from types import SimpleNamespace

import annotated_types
import cv2
import httpx
import numpy as np
import pytest
import uvicorn
from fastapi.testclient import TestClient
from inprocess import AUTH, TOKEN, api_client, settings_for_tests
from uvicorn.logging import AccessFormatter

from bench.campaign import Campaign, PhysicalProcedure, Seed003Procedure
from bench.events import BenchEvent
from bench.runner import bench_data
from bench.service import EventBus
from calibration.models import METHODS, calibration_from_dict
from web.app import create_app
from web.routes.runs import _physical_records
from web.security import load_or_create_token
from web.server import BenchServer, RedactToken, Shutdown, serve
from web.settings import WebSettings

SMALL = Campaign(name="small", frames="none", seed003=Seed003Procedure(
    azimuth_step_deg=90.0, repeats=1, centre_repeats=1, tilt_stage=False))
SMALL_JSON = SMALL.model_dump(mode="json")
# the physical plan as the launcher sends it: its own procedure, fitted by every method when the run ends
PHYSICAL_JSON = {"name": "physical", "plan": "physical", "frames": "none"}
# zenith 80° is beyond the table's soft limits: preflight names each of its 4 poses
BEYOND_LIMITS = {**SMALL_JSON, "seed003": {**SMALL_JSON["seed003"], "zenith_stage_deg": [0, 10, 20, 30, 40, 50, 80]}}

COMMANDS = [
    ("POST", "/api/table/jog", {"azimuth_deg": 10.0, "zenith_deg": 10.0}),
    ("POST", "/api/source/lamp", {"on": True}),
    ("POST", "/api/source/shutter", {"open": True}),
    ("POST", "/api/stop", None),
    ("POST", "/api/stop/acknowledge", None),
    ("POST", "/api/campaigns", SMALL_JSON),
    ("POST", "/api/run/pause", None),
    ("POST", "/api/run/resume", None),
    ("POST", "/api/run/abort", None),
    ("POST", "/api/run/mount", {"sensor_id": "FM-102"}),
    ("POST", "/api/runs/1/resume", None),
    ("POST", "/api/campaigns/1/resume", None),
]
READS = [
    ("GET", "/api/status", None),
    ("GET", "/api/frame.png", None),
    ("GET", "/api/frame/spot", None),
    ("POST", "/api/campaigns/dry-run", SMALL_JSON),
    ("POST", "/api/field/analyse", {"csv": "# latitude_deg: 54.8437\n# longitude_deg: 83.093\n# heading_deg: 0\n"
                                           "time_utc,zenith_deg,azimuth_deg\n2019-09-29T05:00:00Z,58,160\n"
                                           "2019-09-29T05:01:00Z,58,160.3\n", "locate": False}),
    ("GET", "/api/campaigns", None),
    ("GET", "/api/campaigns/1/fleet", None),
    ("GET", "/api/runs", None),
    ("GET", "/api/runs/1", None),
    ("GET", "/api/runs/1/points", None),
    ("GET", "/api/runs/1/calibrations", None),
    ("GET", "/api/runs/1/log", None),
    ("GET", "/api/runs/1/values", None),
    ("GET", "/api/runs/1/fit", None),
    ("GET", "/api/runs/1/qd/currents", None),
    ("GET", "/api/runs/1/qd/dark", None),
    ("GET", "/api/runs/1/qd/error-map", None),
    ("GET", "/api/runs/1/qd/metrics", None),
    ("GET", "/api/runs/1/camera/fit", None),
    ("GET", "/api/runs/1/css/metrics", None),
    ("GET", "/api/runs/1/css/detectors", None),
    ("GET", "/api/runs/1/css/directions", None),
    ("GET", "/api/runs/1/css/quantiser", None),
    ("GET", "/api/runs/1/horizon/metrics", None),
    ("GET", "/api/runs/1/horizon/edges", None),
    ("GET", "/api/runs/1/horizon/attitude", None),
    ("GET", "/api/runs/1/horizon/pulse", None),
    ("GET", "/api/runs/1/data.csv", None),
    ("GET", "/api/calibrations/1/physical.json", None),
    ("GET", "/api/calibrations/1/physical.h", None),
    ("GET", "/api/events", None),
]


def _wait_for(predicate, what, timeout_s=15.0, poll_s=0.02):
    """`predicate()`'s first true value, asked every `poll_s` until `timeout_s` (else an AssertionError naming
    `what`)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(poll_s)
    raise AssertionError(f"timed out waiting for {what}")


def _engine_state(client):
    return client.get("/api/status", headers=AUTH).json()["engine"]["state"]


def _campaign_status(client, campaign_id):
    campaigns = client.get("/api/campaigns", headers=AUTH).json()["data"]
    return next(c["status"] for c in campaigns if c["id"] == campaign_id)


def _finished_run(client, campaign_id, timeout_s=15.0):
    """The campaign's run once the campaign has ended: its fits are stored by then (the engine stores them before
    it marks the run completed), and the worker is done with the campaign."""
    def done():
        if _campaign_status(client, campaign_id) not in ("completed", "aborted", "failed"):
            return None
        (entry,) = client.get(f"/api/campaigns/{campaign_id}/fleet", headers=AUTH).json()["data"]
        return entry
    entry = _wait_for(done, "the campaign to finish", timeout_s)
    return client.get(f"/api/runs/{entry['run_id']}", headers=AUTH).json()


def _submit(client, body=SMALL_JSON):
    response = client.post("/api/campaigns", json=body, headers=AUTH)
    assert response.status_code == 202, response.text
    return response.json()["campaign_id"]


def _gate_points(service, indices):
    """Hold the engine inside its 'point' event at these indices (the run stays running) until released."""
    reached, release = threading.Event(), threading.Event()

    def hook(event):
        if event.kind == "point" and event.data["index"] in indices:
            reached.set()
            release.wait(10)  # bounded: a failing test must not leave the worker stuck
            release.clear()
    service.engine.subscribe(hook)
    return reached, release


# -- the token ----------------------------------------------------------------------------------------------
def test_the_token_is_created_once_private_and_reused(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    token, created = load_or_create_token()
    path = tmp_path / "xdg" / "sunbench" / "token"
    assert created and len(token) >= 40 and path.read_text().strip() == token
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert load_or_create_token() == (token, False)
    assert load_or_create_token(tmp_path / "elsewhere")[0] != token
    assert WebSettings.from_env().token == token


def test_settings_fail_fast():
    with pytest.raises(ValueError, match="token"):
        WebSettings(token="short")
    with pytest.raises(ValueError, match="port"):
        WebSettings(token=TOKEN, port=0)
    assert (WebSettings(token=TOKEN).host, WebSettings(token=TOKEN).public_read) == ("127.0.0.1", False)


@pytest.mark.parametrize("public_read", [False, True])
@pytest.mark.parametrize("headers", [{}, {"Authorization": "Bearer wrong-token-0123456789"},
                                     {"Authorization": f"Basic {TOKEN}"}], ids=["none", "wrong", "basic"])
def test_every_command_needs_the_token(service, public_read, headers):
    with api_client(service, public_read=public_read) as client:
        for method, url, body in COMMANDS:
            response = client.request(method, url, json=body, headers=headers)
            assert response.status_code == 401, (url, response.text)
            assert "token" in response.json()["detail"] and response.headers["www-authenticate"] == "Bearer"
    assert service.status()["engine"]["state"] == "idle" and not service.catalogue.campaigns()


def test_reads_need_the_token_unless_public_read(service):
    with api_client(service) as private, api_client(service, public_read=True) as public:
        for method, url, body in READS:
            response = private.request(method, url, json=body)
            assert response.status_code == 401, (url, response.text)
            assert private.request(method, url, json=body, headers={"Authorization": "Bearer nope"}).status_code == 401
            if url != "/api/events":  # a stream never ends by itself; it is read in its own tests
                # 404s (nothing recorded yet) are fine: the point is that the token was not asked for
                assert public.request(method, url, json=body).status_code in (200, 404), url


# -- status and manual commands -----------------------------------------------------------------------------
def test_status_frame_and_manual_commands(client):
    status = _wait_for(lambda: (s := client.get("/api/status", headers=AUTH).json())["table"] and s,
                       "the poller to fill the status cache")
    assert status["engine"]["state"] == "idle" and status["sensor"]["temperature_c"] > 0
    assert (status["sensor"]["width_px"], status["sensor"]["height_px"]) == (640, 480)  # from a dark frame
    assert client.get("/api/frame.png", headers=AUTH).status_code == 404
    assert client.get("/api/frame/spot", headers=AUTH).status_code == 404

    assert client.post("/api/source/lamp", json={"on": True}, headers=AUTH).json()["source"]["lamp_on"]
    assert client.post("/api/source/shutter", json={"open": True}, headers=AUTH).json()["source"]["shutter_open"]
    status = client.post("/api/table/jog", json={"azimuth_deg": 90.0, "zenith_deg": 30.0}, headers=AUTH).json()
    assert status["table"]["azimuth_deg"] == pytest.approx(90.0, abs=1e-3)
    assert status["table"]["zenith_deg"] == pytest.approx(30.0, abs=1e-3)

    png = client.get("/api/frame.png", headers=AUTH)
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert png.content.startswith(b"\x89PNG\r\n\x1a\n")
    image = cv2.imdecode(np.frombuffer(png.content, np.uint8), cv2.IMREAD_UNCHANGED)
    assert image.shape == (480, 640) and image.dtype == np.uint8 and image.max() > 100  # the spot, scaled up
    spot = client.get("/api/frame/spot", headers=AUTH).json()
    assert 0 < spot["x_px"] < 640 and 0 < spot["y_px"] < 480 and spot["error"] is None

    stop = client.post("/api/stop", headers=AUTH)
    assert stop.status_code == 200 and "emergency stop" in stop.json()["message"]
    assert not client.post("/api/source/shutter", json={"open": False}, headers=AUTH).json()["source"]["shutter_open"]
    assert client.post("/api/stop/acknowledge", headers=AUTH).status_code == 200


def test_a_jog_outside_the_limits_is_422_and_nothing_moves(client):
    client.post("/api/table/jog", json={"azimuth_deg": 0.0, "zenith_deg": 20.0}, headers=AUTH)
    response = client.post("/api/table/jog", json={"azimuth_deg": 0.0, "zenith_deg": 80.0}, headers=AUTH)
    assert response.status_code == 422
    assert "80" in response.json()["detail"] and "limit" in response.json()["detail"].lower()
    assert client.get("/api/status", headers=AUTH).json()["table"]["zenith_deg"] == pytest.approx(20.0, abs=1e-3)


def test_bad_command_bodies_are_422(client):
    response = client.post("/api/table/jog", json={"azimuth_deg": "north"}, headers=AUTH)
    assert response.status_code == 422
    assert {e["loc"][-1] for e in response.json()["detail"]} == {"azimuth_deg", "zenith_deg"}
    assert client.post("/api/source/lamp", json={"on": "maybe"}, headers=AUTH).status_code == 422


# -- run control --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("action", ["pause", "resume", "abort"])
def test_run_control_when_idle_is_409(client, action):
    response = client.post(f"/api/run/{action}", headers=AUTH)
    assert response.status_code == 409 and "idle" in response.json()["detail"]


def test_pause_resume_abort_a_running_campaign(client, service):
    reached, release = _gate_points(service, {2, 4})
    campaign_id = _submit(client)
    assert reached.wait(10)
    reached.clear()
    assert client.post("/api/run/pause", headers=AUTH).json() == {"message": "pausing"}
    release.set()
    _wait_for(lambda: _engine_state(client) == "paused", "the run to pause")

    busy = client.post("/api/table/jog", json={"azimuth_deg": 10.0, "zenith_deg": 10.0}, headers=AUTH)
    assert busy.status_code == 409 and "a run owns the bench" in busy.json()["detail"]
    assert client.post("/api/source/lamp", json={"on": False}, headers=AUTH).status_code == 409
    assert client.post("/api/run/pause", headers=AUTH).status_code == 409  # already paused

    assert client.post("/api/run/resume", headers=AUTH).status_code == 200
    assert reached.wait(10)
    assert client.post("/api/run/pause", headers=AUTH).status_code == 200
    release.set()
    _wait_for(lambda: _engine_state(client) == "paused", "the run to pause again")
    assert client.post("/api/run/abort", headers=AUTH).json() == {"message": "aborting"}
    run = _finished_run(client, campaign_id)
    assert run["status"] == "aborted" and 0 < run["n_points_recorded"] < run["n_points_planned"]

    log = client.get(f"/api/runs/{run['id']}/log", headers=AUTH).json()
    assert log["count"] == len(log["data"]) > 0
    states = [e["message"] for e in log["data"] if e["kind"] == "state"]
    assert states.count("pausing → paused") == 2 and "paused → aborting" in states  # the operator's commands
    last = log["data"][-1]["id"]
    assert client.get(f"/api/runs/{run['id']}/log", params={"after_id": last}, headers=AUTH).json()["count"] == 0


# -- campaigns ----------------------------------------------------------------------------------------------
def test_an_invalid_campaign_body_is_422_naming_the_field(client):
    response = client.post("/api/campaigns", json={**SMALL_JSON, "seed003": {"repeats": 0}}, headers=AUTH)
    assert response.status_code == 422
    assert ["body", "seed003", "repeats"] in [e["loc"] for e in response.json()["detail"]]
    response = client.post("/api/campaigns/dry-run", json={"name": "x", "sensorz": ["A"]}, headers=AUTH)
    assert response.status_code == 422 and response.json()["detail"][0]["loc"] == ["body", "sensorz"]
    assert client.post("/api/campaigns", json={"plan": "grid"}, headers=AUTH).json()["detail"][0]["loc"] == [
        "body", "name"]


def test_a_campaign_beyond_the_limits_is_refused_with_every_violation(client, service):
    dry = client.post("/api/campaigns/dry-run", json=BEYOND_LIMITS, headers=AUTH)
    assert dry.status_code == 200 and len(dry.json()["violations"]) == 4
    response = client.post("/api/campaigns", json=BEYOND_LIMITS, headers=AUTH)
    assert response.status_code == 422
    assert response.json() == {"detail": {"violations": dry.json()["violations"]}}
    assert client.get("/api/campaigns", headers=AUTH).json() == {"data": [], "count": 0}


def test_a_campaign_runs_and_its_results_download(client, service):
    dry = client.post("/api/campaigns/dry-run", json=SMALL_JSON, headers=AUTH).json()
    assert dry["points"] == 32 and dry["violations"] == [] and dry["duration_s"] > 0 and dry["moves"] > 0
    campaign_id = _submit(client)
    run = _finished_run(client, campaign_id)
    assert run["status"] == "completed" and run["campaign_id"] == campaign_id
    run_id = run["id"]
    assert client.get(f"/api/runs/{run_id}", headers=AUTH).json()["n_points_recorded"] == 32
    assert client.get("/api/runs", params={"campaign_id": campaign_id}, headers=AUTH).json()["count"] == 1

    campaigns = client.get("/api/campaigns", headers=AUTH).json()
    assert campaigns["count"] == 1 and campaigns["data"][0]["name"] == "small"
    fleet = client.get(f"/api/campaigns/{campaign_id}/fleet", headers=AUTH).json()
    assert [(f["sensor_id"], f["status"], f["run_id"]) for f in fleet["data"]] == [("SIM-0001", "done", run_id)]

    points = client.get(f"/api/runs/{run_id}/points", headers=AUTH).json()
    assert points["count"] == 32 and all(p["n_ok"] == 1 and 0 < p["x_px"] < 640 for p in points["data"])

    calibrations = client.get(f"/api/runs/{run_id}/calibrations", headers=AUTH).json()["data"]
    assert sorted(c["method"] for c in calibrations) == sorted(METHODS)
    assert sum(c["chosen"] for c in calibrations) == 1 and all("heldout" in c["metrics"] for c in calibrations)
    # from each document: the fit's quality in words, the frames it rejected, and a physical model's 1σ map
    for c in calibrations:
        assert isinstance(c["quality"]["warnings"], list) and isinstance(c["rejected"], list), c["method"]
        assert (c["uncertainty_map"] is not None) == c["method"].startswith("physical"), c["method"]
        if c["uncertainty_map"]:
            assert 0 < c["uncertainty_map"]["rms_deg"] <= c["uncertainty_map"]["max_deg"] < 0.5

    data = client.get(f"/api/runs/{run_id}/data.csv", headers=AUTH)
    assert data.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(data.text)))
    assert rows[0][:4] == ["zenith_deg", "azimuth_deg", "x_px", "y_px"]
    fitted = bench_data(service.catalogue, [run_id])  # frames whose spot touches an edge are left out
    assert len(rows) - 1 == len(fitted) > 20
    assert [float(v) for v in rows[1][:4]] == pytest.approx([fitted.zenith_deg[0], fitted.azimuth_deg[0],
                                                              fitted.x_px[0], fitted.y_px[0]])

    for method in METHODS:
        document = client.get(f"/api/calibrations/{run_id}/{method}.json", headers=AUTH).json()
        assert calibration_from_dict(document).method == method
        header = client.get(f"/api/calibrations/{run_id}/{method}.h", headers=AUTH)
        assert header.status_code == 200 and "sunbench_sun_direction" in header.text
        assert 'attachment; filename="' in header.headers["content-disposition"]
        # what `sunbench fit` writes too: created time, every method's metrics, provenance; the header names them
        assert document["created_utc"] and set(document["metrics"]) == set(METHODS)
        assert document["provenance"]["simulated"] is True
        assert f"source: run {run_id}" in header.text and "software: " in header.text
        assert "held-out vector RMS: " in header.text and f"created: {document['created_utc']}" in header.text
        assert "#define SB_DETECTOR_WIDTH_PX 640" in header.text


# -- the physical plan -------------------------------------------------------------------------------------
def test_a_physical_dry_run_gives_upper_bounds_and_the_warm_up_apart(client):
    dry = client.post("/api/campaigns/dry-run", json=PHYSICAL_JSON, headers=AUTH)
    assert dry.status_code == 200, dry.text
    dry = dry.json()
    assert dry["upper_bound"] is True and "stops" in dry["upper_bound_reason"] and dry["violations"] == []
    assert dry["points"] == PhysicalProcedure().max_points  # expanded to its cap: every batch counted
    assert dry["frames"] >= dry["points"] * PhysicalProcedure().repeats and dry["moves"] > 0
    assert 0 < dry["warmup_s"] < dry["duration_s"]  # the lamp's warm-up, a part of the duration

    seed003 = client.post("/api/campaigns/dry-run", json=SMALL_JSON, headers=AUTH).json()
    assert seed003["upper_bound"] is False and seed003["upper_bound_reason"] is None
    assert seed003["warmup_s"] == pytest.approx(dry["warmup_s"])  # the same lamp, whatever the plan

    # a fleet: the duration counts every sensor, and so does the warm-up included in it
    fleet = client.post("/api/campaigns/dry-run", json={**PHYSICAL_JSON, "sensors": ["A", "B"]}, headers=AUTH).json()
    assert fleet["points"] == dry["points"] and fleet["duration_s"] == pytest.approx(2 * dry["duration_s"])
    assert fleet["warmup_s"] == pytest.approx(2 * dry["warmup_s"])


def _beyond(field):
    """A value just outside each limit of a numeric field of the model, with the limit it breaks."""
    step = 1 if field.annotation is int else 1e-6
    for m in field.metadata:
        if isinstance(m, annotated_types.Ge):
            yield m.ge - step
        elif isinstance(m, annotated_types.Gt):
            yield m.gt
        elif isinstance(m, annotated_types.Le):
            yield m.le + step
        elif isinstance(m, annotated_types.Lt):
            yield m.lt


@pytest.mark.parametrize("name", [n for n, f in PhysicalProcedure.model_fields.items() if f.annotation in (int, float)])
def test_every_limit_of_the_physical_procedure_is_a_422_naming_its_field(client, name):
    values = list(_beyond(PhysicalProcedure.model_fields[name]))
    assert values, f"{name} has no limit"
    for value in [*values, "many", None]:
        for url in ("/api/campaigns/dry-run", "/api/campaigns"):
            response = client.post(url, json={**PHYSICAL_JSON, "physical": {name: value}}, headers=AUTH)
            assert response.status_code == 422, (name, value, response.text)
            assert ["body", "physical", name] in [e["loc"] for e in response.json()["detail"]], (name, value)
    assert client.get("/api/campaigns", headers=AUTH).json()["count"] == 0


def test_physical_parameter_targets_are_checked_by_the_model(client):
    for targets, words in [({"x0_pix": 0.01}, "unknown parameter"), ({"x0_px": 0}, "positive"),
                           ({"x0_px": -1.0}, "positive")]:
        response = client.post("/api/campaigns/dry-run",
                               json={**PHYSICAL_JSON, "physical": {"parameter_targets": targets}},
                               headers=AUTH)
        assert response.status_code == 422
        (error,) = response.json()["detail"]
        assert error["loc"] == ["body", "physical", "parameter_targets"] and words in error["msg"]
    fine = {"parameter_targets": {"x0_px": 0.02, "gap_mm": 0.001}, "check_rms_target_deg": 0.03}
    fine_run = client.post("/api/campaigns/dry-run", json={**PHYSICAL_JSON, "physical": fine}, headers=AUTH)
    assert fine_run.status_code == 200


def test_a_physical_campaign_runs_stops_at_a_batch_and_shows_its_decisions(client, service):
    with client.stream("GET", "/api/events", headers=AUTH) as response:
        campaign_id = _submit(client, PHYSICAL_JSON)
        seen = _read_events(response.iter_lines(), until=lambda s: any(k == "queued" for k, _ in s))
    (queued,) = [d for k, d in seen if k == "queued"]
    assert queued["upper_bound"] is True and queued["points"] == PhysicalProcedure().max_points
    run = _finished_run(client, campaign_id, timeout_s=60)
    assert run["status"] == "completed" and run["plan_name"] == "physical"
    assert run["n_points_planned"] == PhysicalProcedure().max_points  # the cap
    procedure = PhysicalProcedure()
    assert procedure.first_batch + procedure.check_directions <= run["n_points_recorded"] <= run["n_points_planned"]

    values = client.get(f"/api/runs/{run['id']}/values", headers=AUTH).json()
    assert values["run_id"] == run["id"]
    assert values["values"] == service.catalogue.run_values(run["id"])  # every record, as `sunbench show` reads them
    physical = values["physical"]
    batches, stop = physical["batches"], physical["stop"]
    assert [b["batch"] for b in batches] == list(range(1, len(batches) + 1))
    assert stop["batches_measured"] == len(batches)
    assert physical["n_batches"] == procedure.max_batches
    assert physical["check_rms_target_deg"] == procedure.check_rms_target_deg
    assert physical["n_check_directions"] == procedure.check_directions
    assert stop["reason"] in ("targets met", "cap reached") and stop["stop"] == (stop["reason"] == "targets met")
    for b in batches:
        assert b["n_check_directions"] == procedure.check_directions and set(b["sigmas"]) <= set(b["targets"])
        assert b["stop"] == (b is batches[-1] and stop["stop"])
        assert b["stop"] or b["reasons"]
    recorded = batches[-1]["n_fit_directions"] + procedure.check_directions
    assert run["n_points_recorded"] == recorded

    # every method is fitted to the scattered directions, and the result plots' route takes each
    calibrations = client.get(f"/api/runs/{run['id']}/calibrations", headers=AUTH).json()["data"]
    assert sum(c["chosen"] for c in calibrations) == 1
    for c in calibrations:
        fit = client.get(f"/api/runs/{run['id']}/fit", params={"method": c["method"]}, headers=AUTH)
        assert fit.status_code == 200 and fit.json()["count"] == recorded, c["method"]
    stages = {p["stage"] for p in client.get(f"/api/runs/{run['id']}/points", headers=AUTH).json()["data"]}
    assert stages == {"physical", "check"}


def test_a_seed003_run_has_no_physical_records(client):
    run = _finished_run(client, _submit(client))
    values = client.get(f"/api/runs/{run['id']}/values", headers=AUTH).json()
    assert values["physical"] is None and values["values"]["exposure_ms"] > 0 and "centre_px" in values["values"]


def test_the_physical_batches_come_in_batch_order():
    decision = {"stop": False, "reasons": ["go on"], "n_fit_directions": 16, "n_check_directions": 8}
    values = {f"physical_batch_{k}": {**decision, "n_fit_directions": k} for k in (10, 2, 1, 9)}
    records = _physical_records({**values, "physical_batch_x": {}, "exposure_ms": 4.0})
    batches = records["batches"]
    assert [b["batch"] for b in batches] == [1, 2, 9, 10] == [b["n_fit_directions"] for b in batches]
    assert records["stop"] is None and records["n_batches"] is None
    assert _physical_records({"exposure_ms": 4.0}) is None


@pytest.mark.parametrize("url", ["/api/runs/99", "/api/runs/99/points", "/api/runs/99/calibrations", "/api/runs/99/log",
                                 "/api/runs/99/values",
                                 "/api/runs/99/data.csv", "/api/calibrations/99/physical.json",
                                 "/api/calibrations/99/physical.h", "/api/campaigns/99/fleet"])
def test_unknown_ids_are_404(client, url):
    response = client.get(url, headers=AUTH)
    assert response.status_code == 404 and "99" in response.json()["detail"]


def test_an_unknown_method_is_404(client):
    run_id = _finished_run(client, _submit(client))["id"]
    response = client.get(f"/api/calibrations/{run_id}/nonsense.json", headers=AUTH)
    assert response.status_code == 404 and "no nonsense calibration" in response.json()["detail"]


# -- events -------------------------------------------------------------------------------------------------
def _read_events(lines, *, until, timeout_s=10.0):
    """Parse an SSE stream into (event, data) pairs and comments until `until(seen)`; never blocks for long
    when the stream sends a status event or a keep-alive comment every 0.2 s, as the `client` fixture's does."""
    seen, event, deadline = [], None, time.monotonic() + timeout_s
    for line in lines:
        if line.startswith(":"):
            seen.append(("comment", line))
        elif line.startswith("event: "):
            event = line[len("event: "):]
        elif line.startswith("data: "):
            seen.append((event, json.loads(line[len("data: "):])))
        if until(seen):
            return seen
        if time.monotonic() > deadline:
            break
    raise AssertionError(f"stream ended or timed out; saw {[k for k, _ in seen]}")


def test_the_event_stream_delivers_the_points_of_a_running_campaign(client, service):
    before = service.bus.subscribers
    with client.stream("GET", "/api/events", headers=AUTH) as response:
        assert response.status_code == 200 and response.headers["content-type"].startswith("text/event-stream")
        assert response.headers["cache-control"] == "no-cache"
        assert service.bus.subscribers == before + 1  # subscribed before the answer: nothing can be missed
        assert client.post("/api/campaigns", json=SMALL_JSON, headers=AUTH).status_code == 202
        seen = _read_events(response.iter_lines(), until=lambda s: sum(k == "point" for k, _ in s) >= 3)
    points = [d for k, d in seen if k == "point"]
    assert [p["index"] for p in points] == [1, 2, 3] and points[0]["kind"] == "point" and points[0]["total"] == 32
    assert any(k == "queued" for k, _ in seen)
    _wait_for(lambda: service.bus.subscribers == before, "the stream to unsubscribe")


def _idle_app(keepalive_s):
    """An app around a bare bus (no status poller: its streams stay idle), and the bus."""
    bus = EventBus()
    return create_app(SimpleNamespace(bus=bus), settings=settings_for_tests(sse_keepalive_s=keepalive_s)), bus


def test_an_idle_stream_sends_keep_alives():
    app, bus = _idle_app(0.1)
    with TestClient(app) as client, client.stream("GET", "/api/events", headers=AUTH) as response:
        lines = response.iter_lines()
        seen = _read_events(lines, until=lambda s: [k for k, _ in s].count("comment") >= 2, timeout_s=5)
        assert seen == [("comment", ": keep-alive")] * 2
        bus.publish(BenchEvent("log", None, {"message": "hello", "value": np.float64(1.5), "n": np.int64(2)}))
        seen = _read_events(lines, until=lambda s: any(k == "log" for k, _ in s), timeout_s=5)
        assert seen[-1] == ("log", {"kind": "log", "run_id": None, "message": "hello", "value": 1.5, "n": 2})
        assert bus.subscribers == 1


def test_an_event_from_the_engine_thread_reaches_an_idle_stream_at_once():
    """The stream sleeps until the bus wakes it: no poll interval between a publish and the wire (a stream
    that looked at its queue every 0.2 s was 0.1 s late on average)."""
    app, bus = _idle_app(30.0)  # no keep-alive during the test: only the events wake the stream
    latencies_s = []

    def publish(index, stamps):
        stamps.append(time.perf_counter())
        bus.publish(BenchEvent("point", None, {"index": index}))

    with TestClient(app) as client, client.stream("GET", "/api/events", headers=AUTH) as response:
        lines = response.iter_lines()
        for index in range(5):
            stamps = []
            threading.Timer(0.03 + 0.02 * index, publish, (index, stamps)).start()  # at varied phases
            seen = _read_events(lines, until=lambda s: any(k == "point" for k, _ in s), timeout_s=5)
            latencies_s.append(time.perf_counter() - stamps[0])
            assert seen[-1][1]["index"] == index
    assert statistics.median(latencies_s) < 0.05, latencies_s  # a 0.2 s poll would put it near 0.1 s


def test_shutdown_set_from_any_thread_ends_an_idle_stream_at_once():
    app, bus = _idle_app(30.0)  # only the shutdown can end the wait
    with TestClient(app) as client, client.stream("GET", "/api/events", headers=AUTH) as response:
        assert bus.subscribers == 1
        threading.Timer(0.1, app.state.shutdown.set).start()
        t0 = time.monotonic()
        assert list(response.iter_lines()) == []  # the stream ends, instead of holding the server
        assert time.monotonic() - t0 < 1.0
    _wait_for(lambda: bus.subscribers == 0, "the stream to unsubscribe", 5)


def test_a_stream_opened_during_shutdown_ends_at_once():
    app, bus = _idle_app(30.0)
    with TestClient(app) as client:
        app.state.shutdown.set()
        with client.stream("GET", "/api/events", headers=AUTH) as response:
            assert response.status_code == 200 and list(response.iter_lines()) == []
    assert bus.subscribers == 0


@contextmanager
def _served(app):
    """`app` under BenchServer on a free loopback port, in a thread: what a real client does reaches the app
    as in production. Yields the server and its base URL."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = BenchServer(app, uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, name="test-uvicorn", daemon=True)
    thread.start()
    try:
        _wait_for(lambda: server.started or not thread.is_alive(), "the server to start", 10)
        assert server.started
        yield server, f"http://127.0.0.1:{port}"
    finally:
        app.state.shutdown.set()
        server.should_exit = True
        thread.join(10)


def test_a_client_that_disconnects_is_unsubscribed():
    app, bus = _idle_app(0.1)
    with _served(app) as (_, base), httpx.Client(headers=AUTH, timeout=5) as http:
        with http.stream("GET", f"{base}/api/events") as response:
            lines = response.iter_lines()  # kept: a discarded line iterator closes the connection
            assert next(lines) == ": keep-alive"
            assert bus.subscribers == 1
        # leaving the block mid-stream closes the connection
        _wait_for(lambda: bus.subscribers == 0, "the stream to unsubscribe", 5)
        bus.publish(BenchEvent("log", None))  # nobody left to deliver to, and no error for the publisher


def test_the_server_asked_to_exit_ends_open_streams_at_once():
    app, bus = _idle_app(30.0)  # only the exit can end the waits
    with _served(app) as (server, base), httpx.Client(headers=AUTH, timeout=5) as http:
        with http.stream("GET", f"{base}/api/events") as first, http.stream("GET", f"{base}/api/events") as second:
            _wait_for(lambda: bus.subscribers == 2, "both streams to subscribe", 5)
            t0 = time.monotonic()
            server.handle_exit(signal.SIGINT, None)  # what Ctrl+C does
            assert list(first.iter_lines()) == [] and list(second.iter_lines()) == []
            assert time.monotonic() - t0 < 1.0
    assert bus.subscribers == 0


def test_the_server_ends_event_streams_when_asked_to_exit():
    app = create_app(SimpleNamespace(bus=EventBus()), settings=WebSettings(token=TOKEN))
    server = BenchServer(app, uvicorn.Config(app))
    server.handle_exit(signal.SIGINT, None)
    assert app.state.shutdown.is_set() and server.should_exit


def test_a_shutdown_signal_landing_while_a_stream_subscribes_does_not_deadlock():
    # uvicorn's signal handler runs on the loop's thread, possibly inside add_callback's critical section
    shutdown, closed = Shutdown(), []
    shutdown.add_callback(lambda: closed.append(1))
    done = threading.Event()

    def signal_inside_add():
        with shutdown._callbacks_lock:
            shutdown.set()
        done.set()
    threading.Thread(target=signal_inside_add, daemon=True).start()
    assert done.wait(5), "Shutdown.set() blocked on a lock its own thread held"
    assert shutdown.is_set() and closed == [1]


def test_the_access_log_masks_the_token_of_an_event_stream(monkeypatch):
    # shaped as uvicorn's access records: (client_addr, method, full_path, http_version, status_code)
    record = logging.LogRecord("uvicorn.access", logging.INFO, __file__, 0, '%s - "%s %s HTTP/%s" %d',
                               ("127.0.0.1:50000", "GET", f"/api/events?token={TOKEN}&x=1", "1.1", 200), None)
    assert RedactToken().filter(record)
    assert record.args == ("127.0.0.1:50000", "GET", "/api/events?token=***&x=1", "1.1", 200)
    line = AccessFormatter('%(client_addr)s - "%(request_line)s" %(status_code)s', use_colors=False).format(record)
    assert line == '127.0.0.1:50000 - "GET /api/events?token=***&x=1 HTTP/1.1" 200 OK'
    # the API decodes the parameter's name, so its encodings are masked too; other parameters are left alone
    for path in (f"/api/events?%74oken={TOKEN}", f"/api/events?x=token&TOKEN={TOKEN}", f"/api/events?to%6Ben={TOKEN}"):
        assert TOKEN not in RedactToken.redact(path) and RedactToken.redact(path).endswith("=***"), path
    assert RedactToken.redact("/api/runs?campaign_id=3&after_id=7") == "/api/runs?campaign_id=3&after_id=7"

    app = create_app(SimpleNamespace(bus=EventBus()), settings=WebSettings(token=TOKEN))
    monkeypatch.setattr(BenchServer, "run", lambda self: None)
    access = logging.getLogger("uvicorn.access")
    # restored after the test
    monkeypatch.setattr(access, "filters", [f for f in access.filters if not isinstance(f, RedactToken)])
    serve(app)
    serve(app)
    assert sum(isinstance(f, RedactToken) for f in access.filters) == 1  # installed by serve(), once


# -- documentation ------------------------------------------------------------------------------------------
def test_the_openapi_schema_lists_every_route(client):
    schema = client.get("/openapi.json").json()
    documented = {(method.upper(), path) for path, item in schema["paths"].items() for method in item}
    templates = {"/api/campaigns/1/": "/api/campaigns/{campaign_id}/", "/1": "/{run_id}", "physical.": "{method}."}

    def template(url):
        for concrete, general in templates.items():
            url = url.replace(concrete, general)
        return url
    assert documented == {(method, template(url)) for method, url, _ in COMMANDS + READS}
    for path, item in schema["paths"].items():
        for operation in item.values():
            assert operation["tags"] and operation["summary"], path
    assert schema["components"]["securitySchemes"]["HTTPBearer"]["scheme"] == "bearer"
    assert "CampaignQueued" in schema["components"]["schemas"]


# -- the emergency stop latches (issue 10) --------------------------------------------------------------------
LIGHT_AND_MOTION = [
    ("POST", "/api/table/jog", {"azimuth_deg": 10.0, "zenith_deg": 10.0}),
    ("POST", "/api/source/lamp", {"on": True}),
    ("POST", "/api/source/shutter", {"open": True}),
    ("POST", "/api/campaigns", SMALL_JSON),
]


def test_an_emergency_stop_latches_until_acknowledged(client, service):
    assert client.post("/api/source/lamp", json={"on": True}, headers=AUTH).status_code == 200
    stop = client.post("/api/stop", headers=AUTH)
    assert stop.status_code == 200 and stop.json()["message"].startswith("emergency stop latched: table stopped, "
                                                                         "shutter closed")
    assert _engine_state(client) == "estop"
    for method, url, body in LIGHT_AND_MOTION:
        response = client.request(method, url, json=body, headers=AUTH)
        assert response.status_code == 409, (url, response.text)
        assert "emergency stop latched" in response.json()["detail"] and "acknowledge" in response.json()["detail"]
    assert not service.catalogue.campaigns()  # nothing was queued
    # what makes the bench safer is still allowed
    assert not client.post("/api/source/shutter", json={"open": False}, headers=AUTH).json()["source"]["shutter_open"]
    assert client.post("/api/source/lamp", json={"on": False}, headers=AUTH).status_code == 200
    assert client.post("/api/run/abort", headers=AUTH).status_code == 409

    ack = client.post("/api/stop/acknowledge", headers=AUTH)
    assert ack.status_code == 200 and "acknowledged" in ack.json()["message"]
    assert _engine_state(client) == "idle"
    again = client.post("/api/stop/acknowledge", headers=AUTH)
    assert again.status_code == 409 and "no emergency stop" in again.json()["detail"]
    status = client.post("/api/table/jog", json={"azimuth_deg": 10.0, "zenith_deg": 10.0}, headers=AUTH).json()
    assert status["table"]["azimuth_deg"] == pytest.approx(10.0, abs=1e-3)


def test_an_emergency_stop_during_a_jog_answers_409_with_where_the_table_stopped(tmp_path):
    from bench.benchfile import BenchFile
    from bench.catalogue import Catalogue
    from bench.service import BenchService
    catalogue = Catalogue(tmp_path / "slow.sqlite")
    service = BenchService(BenchFile(), catalogue, time_scale=1.0, status_period_s=0.05).start()  # real time
    world = service.session.devices.sim.world
    try:
        with api_client(service) as client:
            answers = []
            jog = threading.Thread(target=lambda: answers.append(client.post(
                "/api/table/jog", json={"azimuth_deg": 300.0, "zenith_deg": 0.0}, headers=AUTH)))
            jog.start()  # 30 s at 10°/s
            _wait_for(world.azimuth.busy, "the table to turn")
            time.sleep(0.3)
            assert client.post("/api/stop", headers=AUTH).status_code == 200
            jog.join(timeout=10)
            (answer,) = answers
            azimuth, zenith = service.session.devices.table.position()
            assert answer.status_code == 409, answer.text  # not 200 "table at azimuth 300°"
            assert 0.0 < azimuth < 299.0 and not world.azimuth.busy()
            detail = answer.json()["detail"]
            assert f"stopped at azimuth {azimuth:.3f}°, zenith {zenith:.3f}°" in detail
            assert "emergency stop latched" in detail
            status = _wait_for(lambda: (s := client.get("/api/status", headers=AUTH).json())["table"]["azimuth_deg"]
                               == pytest.approx(azimuth, abs=1e-6) and s, "the status to show the stopped table")
            assert status["engine"]["state"] == "estop" and not status["table"]["moving"]
            assert client.post("/api/table/jog", json={"azimuth_deg": 0.0, "zenith_deg": 0.0},
                               headers=AUTH).status_code == 409  # the next move does not run
            assert service.session.devices.table.position() == (azimuth, zenith)
    finally:
        service.close()
        catalogue.close()


# -- a fleet's sensor mounts, resuming runs and campaigns (issue 10) ---------------------------------------------
FLEET_JSON = {**SMALL_JSON, "name": "fleet", "sensors": ["SIM-0001", "FM-102"]}


def _awaited_mount(client):
    return _wait_for(lambda: client.get("/api/status", headers=AUTH).json()["mount"], "the bench to ask for a mount")


def _campaign_ended(client, campaign_id, timeout_s=30.0):
    return _wait_for(lambda: (s := _campaign_status(client, campaign_id)) in ("completed", "aborted", "failed") and s,
                     f"campaign {campaign_id} to end", timeout_s)


def test_a_fleet_waits_for_the_operator_to_confirm_each_next_sensor(client, service):
    campaign_id = _submit(client, FLEET_JSON)
    mount = _awaited_mount(client)
    assert mount == {"campaign_id": campaign_id, "sensor_id": "FM-102", "position": 1, "count": 2,
                     "resumes_run": None, "prompt": f"mount sensor FM-102 on the bench (sensor 2 of 2 of campaign "
                                                    f"{campaign_id})"}
    time.sleep(0.3)
    (first,) = service.catalogue.runs(campaign_id)  # nothing starts without the operator
    assert first["status"] == "completed" and _campaign_status(client, campaign_id) == "running"
    # the bench is the operator's meanwhile (a fixture may need the table turned)
    assert client.post("/api/table/jog", json={"azimuth_deg": 10.0, "zenith_deg": 5.0}, headers=AUTH).status_code == 200
    wrong = client.post("/api/run/mount", json={"sensor_id": "SIM-0001"}, headers=AUTH)
    assert wrong.status_code == 409 and "awaits sensor FM-102, not SIM-0001" in wrong.json()["detail"]

    confirmed = client.post("/api/run/mount", json={"sensor_id": "FM-102"}, headers=AUTH)
    assert confirmed.status_code == 200 and confirmed.json()["message"] == "sensor FM-102 confirmed mounted"
    assert _campaign_ended(client, campaign_id) == "completed"
    runs = service.catalogue.runs(campaign_id)
    assert [(r["sensor_id"], r["status"], r["n_points_recorded"]) for r in runs] == \
        [("SIM-0001", "completed", 32), ("FM-102", "completed", 32)]
    assert runs[1]["provenance"]["devices"]["sensor"] == "SB-CMOS-PINHOLE, serial FM-102, firmware 1.0.0"
    assert client.get("/api/status", headers=AUTH).json()["mount"] is None
    late = client.post("/api/run/mount", json={"sensor_id": "FM-102"}, headers=AUTH)
    assert late.status_code == 409 and late.json()["detail"] == "no sensor mount is awaited"


def test_a_wrong_sensor_fails_its_run_unmeasured_and_the_campaign_resumes_once_it_is_fixed(client, service):
    events = service.bus.subscribe()
    campaign_id = _submit(client, FLEET_JSON)
    _awaited_mount(client)
    service.session.devices.sim.mount_sensor("SIM-0001")  # the operator put the first sensor back on
    assert client.post("/api/run/mount", json={"sensor_id": "FM-102"}, headers=AUTH).status_code == 200
    assert _campaign_ended(client, campaign_id) == "failed"
    failed = service.catalogue.runs(campaign_id)[-1]
    assert (failed["sensor_id"], failed["status"], failed["n_points_recorded"]) == ("FM-102", "failed", 0)
    assert "reports serial SIM-0001, not FM-102" in failed["exit_reason"]
    finished = _drain(events, "campaign-finished")
    assert finished["status"] == "failed" and "SIM-0001" in finished["reason"] and "FM-102" in finished["reason"]

    resumed = client.post(f"/api/campaigns/{campaign_id}/resume", headers=AUTH)
    assert resumed.status_code == 202 and resumed.json()["message"] == f"campaign {campaign_id} queued to resume"
    mount = _awaited_mount(client)  # the failed sensor is asked for again, to resume its run
    assert (mount["sensor_id"], mount["resumes_run"]) == ("FM-102", failed["id"])
    assert client.post("/api/run/mount", json={"sensor_id": "FM-102"}, headers=AUTH).status_code == 200
    assert _campaign_ended(client, campaign_id) == "completed"
    last = service.catalogue.runs(campaign_id)[-1]
    assert (last["parent_run_id"], last["status"], last["n_points_recorded"]) == (failed["id"], "completed", 32)
    again = client.post(f"/api/campaigns/{campaign_id}/resume", headers=AUTH)
    assert again.status_code == 409 and "complete" in again.json()["detail"]


def _drain(events, kind, timeout_s=10.0):
    """The next event of `kind` from a bus queue."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            event = events.get(timeout=0.5)
        except queue.Empty:
            continue
        if event["kind"] == kind:
            return event
    raise AssertionError(f"no {kind} event")


def test_abort_while_a_mount_is_awaited_stops_the_campaign_there(client, service):
    campaign_id = _submit(client, FLEET_JSON)
    _awaited_mount(client)
    assert client.post("/api/run/abort", headers=AUTH).status_code == 200
    assert _campaign_ended(client, campaign_id) == "aborted"
    fleet = client.get(f"/api/campaigns/{campaign_id}/fleet", headers=AUTH).json()["data"]
    assert [(e["sensor_id"], e["status"]) for e in fleet] == [("SIM-0001", "done"), ("FM-102", "queued")]
    assert len(service.catalogue.runs(campaign_id)) == 1  # nothing measured the sensor nobody mounted


def test_a_stopped_run_resumes_from_the_api_measuring_only_what_it_missed(client, service):
    reached, release = _gate_points(service, {3})
    campaign_id = _submit(client)
    assert reached.wait(10)
    assert client.post("/api/run/abort", headers=AUTH).status_code == 200
    release.set()
    aborted = _finished_run(client, campaign_id)
    assert aborted["status"] == "aborted" and _campaign_status(client, campaign_id) == "aborted"

    response = client.post(f"/api/runs/{aborted['id']}/resume", headers=AUTH)
    assert response.status_code == 202 and response.json()["message"] == f"run {aborted['id']} queued to resume"
    # queued: the campaign stays "aborted" until the worker starts the resumed run (on a busy machine, after a poll)
    _wait_for(lambda: any(r["parent_run_id"] == aborted["id"] for r in service.catalogue.runs(campaign_id)),
              "the resumed run to start")
    assert _campaign_ended(client, campaign_id) == "completed"
    child = service.catalogue.runs(campaign_id)[-1]
    assert (child["parent_run_id"], child["status"]) == (aborted["id"], "completed")
    assert child["n_points_recorded"] == 32 - aborted["n_points_recorded"]  # only the missing points
    again = client.post(f"/api/runs/{aborted['id']}/resume", headers=AUTH)
    assert again.status_code == 409 and f"already resumed by run {child['id']}" in again.json()["detail"]
    complete = client.post(f"/api/runs/{child['id']}/resume", headers=AUTH)
    assert complete.status_code == 409 and "complete" in complete.json()["detail"]
    assert client.post("/api/runs/99/resume", headers=AUTH).status_code == 404


def test_a_run_that_ended_unsafe_says_so_in_the_status_and_the_run(client, service):
    shutter, pulled = service.session.devices.sim.devices["shutter"], threading.Event()

    def pull_the_cable(event):  # after the first run's last point
        if event.kind == "point" and event.data["index"] == event.data["total"] and not pulled.is_set():
            pulled.set()
            shutter.faults.disconnected = True
    service.engine.subscribe(pull_the_cable)
    run = _finished_run(client, _submit(client))
    unsafe = client.get("/api/status", headers=AUTH).json()["engine"]["ended_unsafe"]
    assert unsafe.startswith("ended unsafe: the shutter did not close") and "lamp was switched off" in unsafe
    assert run["exit_reason"].endswith(unsafe)
    log = client.get(f"/api/runs/{run['id']}/log", headers=AUTH).json()["data"]
    assert [e["message"] for e in log if e["kind"] == "unsafe"] == [unsafe]
    assert not service.session.devices.sim.world.lamp.on
    shutter.faults.clear()  # the cable plugged back in
    again = _finished_run(client, _submit(client))  # strikes the lamp again
    assert (again["status"], again["exit_reason"]) == ("completed", None)
    assert client.get("/api/status", headers=AUTH).json()["engine"]["ended_unsafe"] is None
