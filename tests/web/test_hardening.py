"""The API refuses what it cannot take before it reaches the bench or the catalogue, and tells the truth about the
bench (issue 10, item 11 and "telling the truth in the dashboard"): bounded ids, no booleans for numbers, a body
limit, a host check against DNS rebinding, security headers, /docs without a CDN, idempotent Start, the simulated
bench's time scale, and what the live run and the results page read."""

import re
import threading
import time
import typing
from types import SimpleNamespace

import httpx
import pytest
from fastapi.testclient import TestClient
from inprocess import AUTH, TOKEN, api_client, settings_for_tests
from pydantic import BaseModel, ValidationError
from test_api import COMMANDS, READS, SMALL_JSON, _finished_run, _read_events, _served, _submit, _wait_for

from bench.campaign import Campaign
from bench.service import EventBus
from web.app import create_app
from web.guard import MAX_JSON_DEPTH, SECURITY_HEADERS, json_depth, split_host
from web.idempotency import IdempotencyKeys, KeyReused
from web.routes.docs import inline_script_hashes
from web.routes.field import FieldAnalyseRequest
from web.schemas import JogCommand, LampCommand, MountConfirm, ShutterCommand
from web.settings import WebSettings

MAX_ID = 2**63 - 1
EXTERNAL_URL = re.compile(r"(?:https?:)?//[a-z0-9.-]+\.[a-z]{2,}", re.IGNORECASE)


# -- ids ------------------------------------------------------------------------------------------------------
def _with_id(url: str, value) -> str:
    return re.sub(r"/1(?=/|$)", f"/{value}", url)


ID_ROUTES = [(m, u, b) for m, u, b in COMMANDS + READS if re.search(r"/1(?=/|$)", u)]


def test_every_id_in_a_path_or_a_query_is_bounded_in_the_schema(client):
    schema = client.get("/openapi.json").json()
    seen = set()
    for path, item in schema["paths"].items():
        for operation in item.values():
            for parameter in operation.get("parameters", []):
                if parameter["name"].endswith("_id"):
                    bounds = parameter["schema"].get("anyOf", [parameter["schema"]])[0]
                    assert bounds["maximum"] == MAX_ID and bounds["minimum"] in (0, 1), (path, parameter)
                    seen.add(parameter["name"])
    assert seen == {"run_id", "campaign_id", "after_id", "reading_id"}


@pytest.mark.parametrize("method, url, body", ID_ROUTES, ids=[f"{m} {u}" for m, u, _ in ID_ROUTES])
def test_an_id_beyond_the_catalogue_is_422_naming_it_not_500(client, method, url, body):
    name = "campaign_id" if "/campaigns/" in url else "run_id"
    for value in (2**63, 10**30, 0, -1):
        response = client.request(method, _with_id(url, value), json=body, headers=AUTH)
        assert response.status_code == 422, (url, value, response.text)
        assert [e["loc"] for e in response.json()["detail"]] == [["path", name]], (url, value)
    largest = client.request(method, _with_id(url, MAX_ID), json=body, headers=AUTH)
    assert largest.status_code == 404, (url, largest.text)  # the largest id is looked up: no such run


def test_id_queries_are_bounded_too(client):
    for params, name in (({"campaign_id": 2**63}, "campaign_id"), ({"campaign_id": 0}, "campaign_id")):
        response = client.get("/api/runs", params=params, headers=AUTH)
        assert response.status_code == 422 and response.json()["detail"][0]["loc"] == ["query", name]
    run_id = _finished_run(client, _submit(client))["id"]
    for after in (2**63, -1):
        response = client.get(f"/api/runs/{run_id}/log", params={"after_id": after}, headers=AUTH)
        assert response.status_code == 422 and response.json()["detail"][0]["loc"] == ["query", "after_id"]
    assert client.get(f"/api/runs/{run_id}/log", params={"after_id": MAX_ID}, headers=AUTH).json()["count"] == 0
    for reading in (2**63, 0):  # a CSS reading's codes (web/routes/css.py): refused before the run is looked at
        response = client.get(f"/api/runs/{run_id}/css/quantiser", params={"reading_id": reading}, headers=AUTH)
        assert response.status_code == 422 and response.json()["detail"][0]["loc"] == ["query", "reading_id"]


# -- no JSON true for a number, anywhere in a request -------------------------------------------------------
REQUEST_MODELS = {"JogCommand": JogCommand, "LampCommand": LampCommand, "ShutterCommand": ShutterCommand,
                  "MountConfirm": MountConfirm, "Campaign": Campaign, "FieldAnalyseRequest": FieldAnalyseRequest}


def _numeric_slots(model: type[BaseModel], prefix=()):
    """(path, value with a boolean where a number goes) for every numeric field of the model and its submodels."""
    for name, field in model.model_fields.items():
        annotation = field.annotation
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            yield from _numeric_slots(annotation, (*prefix, name))
        elif any(isinstance(a, type) and issubclass(a, BaseModel) for a in args):
            yield from _numeric_slots(next(a for a in args if isinstance(a, type) and issubclass(a, BaseModel)),
                                      (*prefix, name))
        elif annotation in (int, float):
            yield (*prefix, name), True
        elif typing.get_origin(annotation) is tuple and args and args[0] in (int, float):
            yield (*prefix, name), [1.0, True]
        elif typing.get_origin(annotation) is dict and args[-1] in (int, float):
            yield (*prefix, name), {"x0_px": True}


def _nest(path, value):
    body = value
    for key in reversed(path):
        body = {key: body}
    return body


def test_the_request_bodies_are_these_models(client):
    schema = client.get("/openapi.json").json()
    bodies = {op["requestBody"]["content"]["application/json"]["schema"]["$ref"].rsplit("/", 1)[-1]
              for item in schema["paths"].values() for op in item.values() if "requestBody" in op}
    assert bodies == set(REQUEST_MODELS), "a new request body: add it to REQUEST_MODELS, so its numbers are checked"


@pytest.mark.parametrize("name", sorted(REQUEST_MODELS))
def test_every_numeric_field_of_every_request_refuses_booleans(name):
    model = REQUEST_MODELS[name]
    slots = list(_numeric_slots(model))
    if name in ("JogCommand", "Campaign"):
        assert slots, name
    base = {"JogCommand": {"azimuth_deg": 1.0, "zenith_deg": 2.0}, "Campaign": {"name": "x"}}.get(name, {})
    for path, value in slots:
        body = {**base, **_nest(path, value)} if len(path) == 1 else {**base, path[0]: _nest(path[1:], value)}
        if name == "Campaign" and len(path) > 1:
            body["plan"] = path[0] if path[0] in ("seed003", "grid", "physical") else "seed003"
        with pytest.raises(ValidationError) as refused:
            model.model_validate(body)
        assert any(tuple(e["loc"][:len(path)]) == path for e in refused.value.errors()), (name, path)


def test_the_api_refuses_true_for_a_number_and_1_for_a_switch(client, service):
    for body, field in (('{"azimuth_deg": true, "zenith_deg": 10.0}', "azimuth_deg"),
                        ('{"azimuth_deg": 10.0, "zenith_deg": "10"}', "zenith_deg"),
                        ('{"azimuth_deg": 10.0, "zenith_deg": NaN}', "zenith_deg")):  # Python's json reads NaN
        response = client.post("/api/table/jog", content=body, headers={**AUTH, "Content-Type": "application/json"})
        assert response.status_code == 422, (body, response.text)
        assert [e["loc"] for e in response.json()["detail"]] == [["body", field]]
    assert client.post("/api/source/lamp", json={"on": 1}, headers=AUTH).status_code == 422
    assert client.post("/api/source/shutter", json={"open": "true"}, headers=AUTH).status_code == 422
    targets = {**SMALL_JSON, "plan": "physical", "physical": {"parameter_targets": {"x0_px": True}}}
    response = client.post("/api/campaigns/dry-run", json=targets, headers=AUTH)
    assert response.status_code == 422 and "true/false" in response.text
    table = _wait_for(lambda: client.get("/api/status", headers=AUTH).json()["table"], "the status")
    assert table["azimuth_deg"] != pytest.approx(10.0)  # nothing moved


# -- the body limit -----------------------------------------------------------------------------------------
def test_json_depth_counts_nesting_outside_strings():
    assert json_depth(b'{"a": [1, {"b": "[[[[{{"}]}') == 3
    assert json_depth(b'"\\"[["') == 0 and json_depth(b"[[[]]]") == 3


def test_a_huge_body_is_413_and_a_deep_one_422_before_parsing_and_the_server_still_answers(service):
    app = create_app(service, settings=settings_for_tests())
    with _served(app) as (_, base), httpx.Client(headers=AUTH, timeout=10) as http:
        t0 = time.monotonic()
        huge = http.post(f"{base}/api/campaigns/dry-run", content=b"{" + b" " * (20 * 1024 * 1024) + b"}",
                         headers={"Content-Type": "application/json"})
        assert huge.status_code == 413 and "65536 bytes" in huge.json()["detail"]

        def chunks():  # no Content-Length: refused once the bytes read pass the limit
            for _ in range(200):
                yield b" " * 4096
        streamed = http.post(f"{base}/api/campaigns/dry-run", content=chunks(),
                             headers={"Content-Type": "application/json"})
        assert streamed.status_code == 413

        for deep in (b"[" * 30000 + b"]" * 30000, b'{"name": ' * 5000 + b"1" + b"}" * 5000):
            response = http.post(f"{base}/api/campaigns/dry-run", content=deep,
                                 headers={"Content-Type": "application/json"})
            assert response.status_code == 422, response.text
            assert response.json()["detail"] == f"the JSON body nests deeper than {MAX_JSON_DEPTH} levels"
        assert time.monotonic() - t0 < 5.0
        # a body within the limit still works, and the server goes on answering
        assert http.post(f"{base}/api/campaigns/dry-run", json=SMALL_JSON).status_code == 200
        assert http.get(f"{base}/api/status").status_code == 200


# -- the host check (DNS rebinding) --------------------------------------------------------------------------
def test_split_host():
    assert split_host("localhost:8000") == ("localhost", 8000)
    assert split_host("[::1]:8000") == ("[::1]", 8000) and split_host("[::1]") == ("[::1]", None)
    assert split_host("Bench.Lab") == ("bench.lab", None) and split_host("a:b") == ("a", -1)


def test_only_the_servers_own_names_are_answered(service):
    app = create_app(service, settings=settings_for_tests())
    with _served(app) as (_, base), httpx.Client(headers=AUTH, timeout=10) as http:
        port = int(base.rsplit(":", 1)[1])
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST:{port}", f"[::1]:{port}"):
            assert http.get(f"{base}/api/status", headers={"Host": host}).status_code == 200, host
        for host in (f"evil.example:{port}", "evil.example", f"localhost:{port + 1}", "localhost",
                     f"127.0.0.1.evil.example:{port}", ""):
            response = http.get(f"{base}/api/status", headers={"Host": host})
            assert response.status_code == 400, host
            assert "is not this server's" in response.json()["detail"]
            assert response.headers["x-frame-options"] == "DENY"
        page = http.get(f"{base}/", headers={"Host": f"evil.example:{port}"})
        assert page.status_code == 400  # the pages too: a rebound page would run with the bench's origin


def test_the_test_clients_host_is_allowed_only_when_asked_for(service):
    with TestClient(create_app(service, settings=WebSettings(token=TOKEN))) as client:
        assert client.get("/api/status", headers=AUTH).status_code == 400  # Host: testserver
    with TestClient(create_app(service, settings=WebSettings(token=TOKEN, host="bench.lab")),
                    base_url="http://bench.lab") as client:
        assert client.get("/api/status", headers=AUTH).status_code == 200  # the configured host
    with api_client(service) as client:
        assert client.get("/api/status", headers=AUTH).status_code == 200
    with pytest.raises(ValueError, match="host name"):
        WebSettings(token=TOKEN, allowed_hosts=("http://bench.lab",))


# -- security headers ------------------------------------------------------------------------------------------
def _secured(response):
    for name, value in SECURITY_HEADERS.items():
        if name == "content-security-policy":
            assert "default-src 'self'" in response.headers[name] and "frame-ancestors 'none'" in response.headers[name]
        else:
            assert response.headers[name] == value, (response.url, name)
    return True


def test_every_response_carries_the_security_headers(client):
    for url, headers in (("/", {}), ("/results", {}), ("/static/common.js", {}), ("/static/plotly.min.js", {}),
                         ("/api/status", AUTH), ("/api/status", {}), ("/api/runs/99", AUTH), ("/api/runs/0", AUTH),
                         ("/openapi.json", {}), ("/docs", {}), ("/favicon.ico", {}), ("/nowhere", {})):
        assert _secured(client.get(url, headers=headers)), url
    assert _secured(client.post("/api/table/jog", json={"azimuth_deg": True}, headers=AUTH))
    with client.stream("GET", "/api/events", headers=AUTH) as stream:
        assert _secured(stream)
    policy = client.get("/").headers["content-security-policy"]
    assert "script-src 'self';" in policy and "unsafe-eval" not in policy  # no inline script on the pages


def test_even_a_server_error_carries_them():
    app = create_app(SimpleNamespace(bus=EventBus()), settings=settings_for_tests())  # no status: a 500
    with TestClient(app, raise_server_exceptions=False) as client:
        response = client.get("/api/status", headers=AUTH)
        assert response.status_code == 500 and _secured(response)


# -- /docs without a CDN -----------------------------------------------------------------------------------------
def test_the_docs_page_loads_swagger_ui_from_this_server(client):
    page = client.get("/docs")
    assert page.status_code == 200 and "SwaggerUIBundle" in page.text
    assert not EXTERNAL_URL.search(page.text), EXTERNAL_URL.search(page.text).group()
    assets = re.findall(r'(?:src|href)="([^"]+)"', page.text)
    assert {"/static/swagger-ui/swagger-ui-bundle.js", "/static/swagger-ui/swagger-ui.css",
            "/static/favicon.svg"} == set(assets)
    for asset in assets:
        response = client.get(asset)
        assert response.status_code == 200 and len(response.content) > 300, asset
    bundle = client.get("/static/swagger-ui/swagger-ui-bundle.js").text
    assert "javascript" in client.get("/static/swagger-ui/swagger-ui-bundle.js").headers["content-type"]
    assert re.search(r'"5\.\d+\.\d+"', bundle)  # Swagger UI 5: FastAPI's schema is OpenAPI 3.1
    assert client.get("/openapi.json").json()["openapi"].startswith("3.1")
    # the page's one inline script (it starts Swagger UI) is allowed by its hash, nothing else inline
    (allowed,) = inline_script_hashes(page.text)
    assert f"script-src 'self' {allowed};" in page.headers["content-security-policy"]
    assert client.get("/static/swagger-ui/other.js").status_code == 404
    assert client.get("/redoc").status_code == 404  # FastAPI's CDN page is gone


def test_the_favicon(client):
    for url in ("/favicon.ico", "/static/favicon.svg"):
        response = client.get(url)
        assert response.status_code == 200 and response.headers["content-type"].startswith("image/svg+xml")
        assert "<svg" in response.text


# -- a double-clicked Start queues one campaign ---------------------------------------------------------------------
def test_the_same_idempotency_key_queues_one_campaign(client, service):
    key = {"Idempotency-Key": "8c6e9d62-2f0e-4c7b-9f3a-1c2d3e4f5a6b"}
    first = client.post("/api/campaigns", json=SMALL_JSON, headers={**AUTH, **key})
    again = client.post("/api/campaigns", json=SMALL_JSON, headers={**AUTH, **key})
    assert (first.status_code, again.status_code) == (202, 200)
    assert first.json() == {"campaign_id": again.json()["campaign_id"], "replayed": False}
    assert again.json()["replayed"] is True
    other = client.post("/api/campaigns", json={**SMALL_JSON, "name": "other"}, headers={**AUTH, **key})
    assert other.status_code == 422 and "another campaign" in other.json()["detail"]
    assert [c["name"] for c in client.get("/api/campaigns", headers=AUTH).json()["data"]] == ["small"]
    bad = client.post("/api/campaigns", json=SMALL_JSON, headers={**AUTH, "Idempotency-Key": "has space"})
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"] == ["header", "idempotency-key"]
    # without a key every request queues its own
    assert client.post("/api/campaigns", json=SMALL_JSON, headers=AUTH).json()["replayed"] is False
    _wait_for(lambda: all(c["status"] in ("completed", "failed", "aborted")
                          for c in client.get("/api/campaigns", headers=AUTH).json()["data"]), "the campaigns", 60)


def test_two_requests_with_one_key_at_once_queue_one_campaign(client, service):
    key = {"Idempotency-Key": "double-click"}
    answers, barrier = [], threading.Barrier(4)

    def click():
        barrier.wait()
        answers.append(client.post("/api/campaigns", json=SMALL_JSON, headers={**AUTH, **key}))
    threads = [threading.Thread(target=click) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert sorted(a.status_code for a in answers) == [200, 200, 200, 202]
    assert len({a.json()["campaign_id"] for a in answers}) == 1
    assert client.get("/api/campaigns", headers=AUTH).json()["count"] == 1
    _wait_for(lambda: client.get("/api/campaigns", headers=AUTH).json()["data"][0]["status"] == "completed",
              "the campaign", 60)


def test_a_key_is_forgotten_after_its_time_and_a_refused_submit_keeps_it_free():
    now = [0.0]
    keys = IdempotencyKeys(ttl_s=600, clock=lambda: now[0])
    assert keys.submit("k", "a", lambda: 1) == (1, False)
    now[0] = 599
    assert keys.submit("k", "a", lambda: 2) == (1, True)
    with pytest.raises(KeyReused):
        keys.submit("k", "b", lambda: 3)
    now[0] = 601
    assert keys.submit("k", "b", lambda: 4) == (4, False)

    def refused():
        raise RuntimeError("preflight refused")
    with pytest.raises(RuntimeError):
        keys.submit("j", "a", refused)
    assert keys.submit("j", "a", lambda: 5) == (5, False)


# -- the simulated bench says so ------------------------------------------------------------------------------------
def test_the_status_and_every_page_say_the_bench_is_simulated_and_its_time_scale(client, service):
    bench = client.get("/api/status", headers=AUTH).json()["bench"]
    assert (bench["simulated"], bench["time_scale"]) == (True, 0.0)
    assert (bench["family"], bench["has_frames"]) == ("cmos", True)  # and what it measures (tests/web/test_qd.py)
    for path in ("/", "/launch", "/run", "/results", "/fleet"):
        html = client.get(path).text
        assert 'id="bench-banner"' in html and "Simulated bench" in html and "time scale 0" in html, path


def test_the_banner_gives_the_pace_of_a_faster_clock():
    from web.routes.pages import bench_banner
    assert "a bench hour takes 36 s of wall time" in bench_banner({"simulated": True, "time_scale": 100.0})
    assert "time scale 1:" in bench_banner({"simulated": True, "time_scale": 1.0})
    assert bench_banner({"simulated": False, "time_scale": None}) == ""
    assert "every wait is skipped" in bench_banner({"simulated": True, "time_scale": 0.0})
    unknown = bench_banner({"simulated": True, "time_scale": None})
    assert "its time scale is unknown" in unknown and 'data-time-scale=""' in unknown


def test_the_dry_run_gives_per_sensor_and_total_bench_and_wall_time(client, service, monkeypatch):
    two = {**SMALL_JSON, "sensors": ["A", "B"]}
    dry = client.post("/api/campaigns/dry-run", json=two, headers=AUTH).json()
    assert dry["sensors"] == 2 and dry["duration_per_sensor_s"] == pytest.approx(dry["duration_s"] / 2)
    assert (dry["simulated"], dry["time_scale"], dry["wall_duration_s"]) == (True, 0.0, None)  # no waiting at 0
    monkeypatch.setattr(service.session.devices.sim.world.clock, "time_scale", 100.0)
    fast = client.post("/api/campaigns/dry-run", json=two, headers=AUTH).json()
    assert fast["wall_duration_s"] == pytest.approx(fast["duration_s"] / 100)
    monkeypatch.setattr(service, "bench_info", lambda: {"simulated": False, "time_scale": None})  # a real bench
    assert service.wall_time_s(120.0) == 120.0  # its wall time is its bench time
    real = client.post("/api/campaigns/dry-run", json=two, headers=AUTH).json()
    assert (real["simulated"], real["wall_duration_s"]) == (False, pytest.approx(real["duration_s"]))


# -- the live run: each point with its angles, exposure and spots; each stage result ---------------------------------
def test_point_events_carry_the_angles_exposure_and_clipped_spots_and_stage_results_arrive(client):
    with client.stream("GET", "/api/events", headers=AUTH) as response:
        campaign_id = _submit(client)
        seen = _read_events(response.iter_lines(), timeout_s=60,
                            until=lambda s: any(k == "finished" for k, _ in s))
    points = [d for k, d in seen if k == "point"]
    assert len(points) == 32
    for p in points:
        assert {"zenith_deg", "azimuth_body_deg", "exposure_ms", "stage", "spots", "spots_clipped"} <= set(p)
        assert p["exposure_ms"] > 0 and len(p["spots_clipped"]) == len(p["spots"])
    assert any(any(p["spots_clipped"]) for p in points)  # a 60° spot at the detector's edge
    records = {d["key"]: d["value"] for k, d in seen if k == "record"}
    assert records["exposure_ms"] > 0 and len(records["centre_px"]) == 2
    _finished_run(client, campaign_id)


def test_the_calibrations_carry_their_parameters_with_their_uncertainties(client):
    run_id = _finished_run(client, _submit(client))["id"]
    calibrations = {c["method"]: c for c in client.get(f"/api/runs/{run_id}/calibrations", headers=AUTH).json()["data"]}
    physical = calibrations["physical"]["parameters"]
    assert physical["x0_px"] > 0 and set(physical["uncertainties"]) == set(physical["fitted"])
    assert all(s > 0 for s in physical["uncertainties"].values())
    assert "zenith_coefficients" in calibrations["seed003"]["parameters"]
