"""The web API on the simulated bench (time scale 0): every route, its refusals, and the event stream."""

import csv
import io
import json
import logging
import signal
import socket
import stat
import statistics
import threading
import time
from contextlib import contextmanager
from types import SimpleNamespace

import cv2
import httpx
import numpy as np
import pytest
import uvicorn
from fastapi.testclient import TestClient
from uvicorn.logging import AccessFormatter

from bench.campaign import Campaign, Seed003Procedure
from bench.runner import bench_data
from bench.service import EventBus
from calibration.models import METHODS, calibration_from_dict
from web.app import create_app
from web.server import BenchServer, RedactToken, Shutdown, serve
from web.security import load_or_create_token
from web.settings import WebSettings

from inprocess import AUTH, TOKEN, api_client

SMALL = Campaign(name="small", frames="none", seed003=Seed003Procedure(
    azimuth_step_deg=90.0, repeats=1, centre_repeats=1, tilt_stage=False))
SMALL_JSON = SMALL.model_dump(mode="json")
# zenith 80° is beyond the table's soft limits: preflight names each of its 4 poses
BEYOND_LIMITS = {**SMALL_JSON, "seed003": {**SMALL_JSON["seed003"], "zenith_stage_deg": [0, 10, 20, 30, 40, 50, 80]}}

COMMANDS = [
    ("POST", "/api/table/jog", {"azimuth_deg": 10.0, "zenith_deg": 10.0}),
    ("POST", "/api/source/lamp", {"on": True}),
    ("POST", "/api/source/shutter", {"open": True}),
    ("POST", "/api/stop", None),
    ("POST", "/api/campaigns", SMALL_JSON),
    ("POST", "/api/run/pause", None),
    ("POST", "/api/run/resume", None),
    ("POST", "/api/run/abort", None),
]
READS = [
    ("GET", "/api/status", None),
    ("GET", "/api/frame.png", None),
    ("GET", "/api/frame/spot", None),
    ("POST", "/api/campaigns/dry-run", SMALL_JSON),
    ("GET", "/api/campaigns", None),
    ("GET", "/api/campaigns/1/fleet", None),
    ("GET", "/api/runs", None),
    ("GET", "/api/runs/1", None),
    ("GET", "/api/runs/1/points", None),
    ("GET", "/api/runs/1/calibrations", None),
    ("GET", "/api/runs/1/log", None),
    ("GET", "/api/runs/1/fit", None),
    ("GET", "/api/runs/1/data.csv", None),
    ("GET", "/api/calibrations/1/physical.json", None),
    ("GET", "/api/calibrations/1/physical.h", None),
    ("GET", "/api/events", None),
]


def _wait_for(predicate, what, timeout_s=15.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def _engine_state(client):
    return client.get("/api/status", headers=AUTH).json()["engine"]["state"]


def _finished_run(client, campaign_id, timeout_s=15.0):
    """The campaign's run once its queue entry is done or failed: a run is "completed" before its fits are
    stored, so the run's own status is not the signal that its results are there."""
    def done():
        (entry,) = client.get(f"/api/campaigns/{campaign_id}/fleet", headers=AUTH).json()["data"]
        return entry if entry["status"] in ("done", "failed") else None
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


@pytest.mark.parametrize("url", ["/api/runs/99", "/api/runs/99/points", "/api/runs/99/calibrations", "/api/runs/99/log",
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
    return create_app(SimpleNamespace(bus=bus), settings=WebSettings(token=TOKEN, sse_keepalive_s=keepalive_s)), bus


def test_an_idle_stream_sends_keep_alives():
    app, bus = _idle_app(0.1)
    with TestClient(app) as client, client.stream("GET", "/api/events", headers=AUTH) as response:
        lines = response.iter_lines()
        seen = _read_events(lines, until=lambda s: [k for k, _ in s].count("comment") >= 2, timeout_s=5)
        assert seen == [("comment", ": keep-alive")] * 2
        bus.publish({"kind": "log", "message": "hello", "value": np.float64(1.5), "n": np.int64(2)})
        seen = _read_events(lines, until=lambda s: any(k == "log" for k, _ in s), timeout_s=5)
        assert seen[-1] == ("log", {"kind": "log", "message": "hello", "value": 1.5, "n": 2})
        assert bus.subscribers == 1


def test_an_event_from_the_engine_thread_reaches_an_idle_stream_at_once():
    """The stream sleeps until the bus wakes it: no poll interval between a publish and the wire (a stream
    that looked at its queue every 0.2 s was 0.1 s late on average)."""
    app, bus = _idle_app(30.0)  # no keep-alive during the test: only the events wake the stream
    latencies_s = []

    def publish(index, stamps):
        stamps.append(time.perf_counter())
        bus.publish({"kind": "point", "index": index})

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
        bus.publish({"kind": "log"})  # nobody left to deliver to, and no error for the publisher


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
