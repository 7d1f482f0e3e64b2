"""The dashboard's QD family (seed 002's quadrant-photodiode sensor) on the simulated QD bench, in-process at time
scale 0: the bench says its family and plans, a QD campaign queued through the API completes, its run says it
is a QD run, and the QD results view's routes give its currents, its dark-current fit, the error map of each
calibration (agreeing with the figures its fit stored) and every method's figures; the CMOS routes refuse or
answer sensibly on it, and the QD routes refuse a CMOS run."""

import math
import re

import pytest
from inprocess import AUTH, QD_BENCH, api_client, qd_bench_service
from test_api import SMALL_JSON, _finished_run, _submit, _wait_for

from bench.campaign import QdDarkSweep, QdGridProcedure, load_campaign_file
from bench.qd_datafile import read_qd_csv
from calibration.qd.angles import angle_between_projections_deg

ROOT = QD_BENCH.parents[1]
#: the README's QD campaign: dark sweep at 4 temperatures × 8, then a 17 × 17 grid over ±40° with 16 × 16 check points
QD_GRID = load_campaign_file(ROOT / "examples" / "qd-grid.yaml").model_dump(mode="json")
#: the launcher's QD grid as it sends it (launch.html: the fieldset's fields, nothing else)
LAUNCHER_QD_GRID = {"name": "bench-campaign", "plan": "qd-grid", "sensors": ["SIM-0001"], "frames": "roi",
                    "qd_grid": {"field_deg": 20, "step_deg": 10, "repeats": 2, "check_points": True,
                                "temperature_c": 25, "dark": {"temperatures_c": [15, 35], "repeats": 3}}}
QD_DARK = {"name": "dark", "plan": "qd-dark", "sensors": ["QD-0001"], "qd_dark": {"temperatures_c": [10, 25, 40],
                                                                                  "repeats": 4}}
FIT_TIMEOUT_S = 180.0  # the grid's fits, every method held out, on a busy machine


def _get(client, path, status=200):
    response = client.get(path, headers=AUTH)
    assert response.status_code == status, (path, response.text)
    return response.json()


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The README's QD campaign run to its end on one QD service: (client, run)."""
    with qd_bench_service(tmp_path_factory.mktemp("qd")) as service, api_client(service) as client:
        run = _finished_run(client, _submit(client, QD_GRID), timeout_s=FIT_TIMEOUT_S)
        yield client, run


# -- the bench says what it measures ------------------------------------------------------------------------
def test_the_status_and_the_pages_say_the_bench_is_a_qd_bench_and_its_plans(qd_client):
    status = _wait_for(lambda: (s := _get(qd_client, "/api/status"))["sensor"] and s, "the sensor's status")
    bench = status["bench"]
    assert (bench["family"], bench["plans"], bench["has_frames"]) == ("qd", ["qd-grid", "qd-physical", "qd-dark"],
                                                                      False)
    assert bench["simulated"] is True and "seed 002" in bench["family_title"]
    sensor = status["sensor"]
    assert sensor["family"] == "qd" and len(sensor["currents_a"]) == 4 and sensor["exposure_ms"] is None
    for path in ("/", "/launch", "/run", "/results", "/fleet"):
        body = re.search(r"<body[^>]*>", qd_client.get(path).text).group()
        assert 'data-family="qd"' in body and 'data-plans="qd-grid qd-physical qd-dark"' in body
        assert 'data-frames="false"' in body
    no_frame = qd_client.get("/api/frame.png", headers=AUTH)  # a photodiode takes no frame, and says so
    assert no_frame.status_code == 404 and "qd sensor on this bench takes no frames" in no_frame.text


def test_the_launcher_form_of_a_qd_grid_is_a_valid_campaign_and_a_cmos_plan_is_refused(qd_client):
    dry = qd_client.post("/api/campaigns/dry-run", json=LAUNCHER_QD_GRID, headers=AUTH)
    assert dry.status_code == 200 and dry.json()["violations"] == [], dry.text
    # 5 × 5 nodes, 4 × 4 check points, 2 dark temperatures
    assert dry.json()["points"] == 25 + 16 + 2
    foreign = qd_client.post("/api/campaigns/dry-run", json=SMALL_JSON, headers=AUTH).json()
    assert any("seed003" in v for v in foreign["violations"])


# -- a QD campaign through the API ------------------------------------------------------------------------
def test_a_qd_campaign_completes_and_its_run_is_a_qd_run(finished):
    client, run = finished
    assert run["status"] == "completed" and run["plan_name"] == "qd-grid"
    assert (run["family"], run["results_view"]) == ("qd", "qd")
    listed = next(r for r in _get(client, "/api/runs")["data"] if r["id"] == run["id"])
    assert (listed["family"], listed["results_view"]) == ("qd", "qd")
    calibrations = _get(client, f"/api/runs/{run['id']}/calibrations")["data"]
    assert {c["method"] for c in calibrations} == {"physical", "polynomial", "geometric"}
    assert sum(c["chosen"] for c in calibrations) == 1
    # the rejected readings of a QD fit are readings with a direction in α, β (not CMOS frames with a spot)
    document = _get(client, f"/api/calibrations/{run['id']}/{calibrations[0]['method']}.json")
    assert calibrations[0]["rejected"] == [{k: r.get(k) for k in ("row", "alpha_deg", "beta_deg", "reason")}
                                           for r in document["rejected"]]


def test_the_points_of_a_qd_run_carry_their_currents_as_the_live_page_reads_them(finished):
    client, run = finished
    points = _get(client, f"/api/runs/{run['id']}/points")["data"]
    assert len(points) == run["n_points_recorded"] == 549
    assert all(len(p["summary"]["currents_a"]) == 4 and p["summary"]["temperature_c"] > 0 for p in points)
    assert all(p["x_px"] is None for p in points)  # no spot: the spot map has nothing to draw


def test_the_currents_route_gives_every_point_with_its_direction_and_currents(finished):
    client, run = finished
    currents = _get(client, f"/api/runs/{run['id']}/qd/currents")
    data = currents["data"]
    assert currents["count"] == len(data) == 549
    assert [p["index"] for p in data] == list(range(1, 550))
    dark = [p for p in data if p["stage"] == "dark"]
    assert len(dark) == 4 and data[:4] == dark and all(p["alpha_deg"] is None for p in dark)
    lit = [p for p in data if p["stage"] != "dark"]
    assert {p["stage"] for p in lit} == {"grid", "check"}
    assert max(abs(p["alpha_deg"]) for p in lit) == pytest.approx(40, abs=0.01)
    for p in data:
        assert len(p["currents_a"]) == 4 and p["sum_a"] == pytest.approx(sum(p["currents_a"]))
        assert p["n_ok"] + p["n_saturated"] <= p["n_readings"]
    # the dark currents are nA, the lit ones µA: every lit point's sum is above every dark one's
    assert max(p["sum_a"] for p in dark) < min(p["sum_a"] for p in lit)
    key = lit[0]["key"]  # "grid_a-040.00_b-040.00": its true α, β are its key's
    alpha, beta = (float(v) for v in re.findall(r"[ab]([+-]\d+\.\d+)", key))
    assert (lit[0]["alpha_deg"], lit[0]["beta_deg"]) == (pytest.approx(alpha, abs=0.01), pytest.approx(beta, abs=0.01))


def test_the_dark_route_gives_the_dark_readings_and_the_chosen_documents_model(finished):
    client, run = finished
    dark = _get(client, f"/api/runs/{run['id']}/qd/dark")
    chosen = next(c for c in _get(client, f"/api/runs/{run['id']}/calibrations")["data"] if c["chosen"])
    assert (dark["method"], dark["chosen"], dark["source"]) == (chosen["method"], True, "calibration")
    document = _get(client, f"/api/calibrations/{run['id']}/{chosen['method']}.json")
    assert dark["model"] == document["dark"]["model"] in ("linear", "exponential")
    assert dark["quadrants"] == document["dark"]["quadrants"]
    assert dark["count"] == len(dark["readings"]) == 4 * 8
    assert {round(r["temperature_c"]) for r in dark["readings"]} == {10, 20, 30, 40}
    assert dark["dark_range_c"][0] < 11 and dark["dark_range_c"][1] > 39
    assert dark["light_range_c"][0] == pytest.approx(25, abs=0.5)
    # the model's curve spans every reading's temperature, and lies through the dark readings
    curve = dark["curve"]
    assert curve["temperature_c"][0] < 10 and curve["temperature_c"][-1] > 40
    assert all(len(c) == 4 for c in curve["currents_a"])
    for reading in dark["readings"]:
        if reading["left_out"]:
            continue
        t = reading["temperature_c"]
        i = min(range(len(curve["temperature_c"])), key=lambda j: abs(curve["temperature_c"][j] - t))
        for k in range(4):  # within 10 % of the nearest sample of the model (the readings scatter, the grid is coarse)
            assert reading["currents_a"][k] == pytest.approx(curve["currents_a"][i][k], rel=0.1)
    other = next(c["method"] for c in _get(client, f"/api/runs/{run['id']}/calibrations")["data"] if not c["chosen"])
    assert _get(client, f"/api/runs/{run['id']}/qd/dark?method={other}")["method"] == other
    assert "no nonsense calibration" in _get(client, f"/api/runs/{run['id']}/qd/dark?method=nonsense", 404)["detail"]


@pytest.mark.parametrize("method", ["physical", "polynomial", "geometric"])
def test_the_error_map_is_the_stored_document_applied_and_agrees_with_its_figures(finished, method):
    client, run = finished
    emap = _get(client, f"/api/runs/{run['id']}/qd/error-map?method={method}")
    calibrations = _get(client, f"/api/runs/{run['id']}/calibrations")["data"]
    metrics = next(c for c in calibrations if c["method"] == method)["metrics"]
    assert emap["method"] == method and emap["field_deg"] == pytest.approx(40, abs=0.01)
    nodes = [d for d in emap["data"] if d["kind"] == "node"]
    checks = [d for d in emap["data"] if d["kind"] == "check"]
    assert (len(nodes), len(checks)) == (17 * 17, 16 * 16) and emap["count"] == 545
    assert all(abs(d["alpha_deg"]) <= 40.01 and abs(d["beta_deg"]) <= 40.01 for d in emap["data"])
    # each direction's error is the angle between its true and its calibrated direction
    for d in emap["data"][::37]:
        expected = float(angle_between_projections_deg(d["alpha_deg"], d["beta_deg"], d["alpha_fit_deg"],
                                                       d["beta_fit_deg"]))
        assert d["error_deg"] == pytest.approx(expected, abs=1e-9)
    # the stored document applied as the fit scored it: its at-node and held-out check figures, to rounding
    node, check = emap["summary"]["node"], emap["summary"]["check"]
    assert node["max_deg"] == pytest.approx(metrics["at_nodes"]["max_deg"], rel=1e-6)
    assert node["rms_deg"] == pytest.approx(metrics["at_nodes"]["rms_deg"], rel=1e-6)
    assert node["n_points"] == metrics["at_nodes"]["n_points"]
    held = metrics["heldout_by_scheme"]["check"]
    assert check["max_deg"] == pytest.approx(held["max_deg"], rel=1e-6)
    assert check["rms_deg"] == pytest.approx(held["rms_deg"], rel=1e-6)
    # the readings the document rejected are named at their directions, not averaged in
    document = _get(client, f"/api/calibrations/{run['id']}/{method}.json")
    named = {entry["reading_id"] for d in emap["data"] for entry in d["readings_left_out"]}
    assert named == {r["row"] for r in document["rejected"] if r["alpha_deg"] is not None}


def test_the_error_map_defaults_to_the_chosen_calibration_and_refuses_an_unknown_one(finished):
    client, run = finished
    chosen = next(c["method"] for c in _get(client, f"/api/runs/{run['id']}/calibrations")["data"] if c["chosen"])
    emap = _get(client, f"/api/runs/{run['id']}/qd/error-map")
    assert (emap["method"], emap["chosen"]) == (chosen, True)
    assert _get(client, f"/api/runs/{run['id']}/qd/error-map?method=nonsense", 404)["detail"].startswith("run ")


def test_the_metrics_route_gives_every_methods_figures_the_rejected_readings_and_the_warnings(finished):
    client, run = finished
    metrics = _get(client, f"/api/runs/{run['id']}/qd/metrics")
    calibrations = _get(client, f"/api/runs/{run['id']}/calibrations")["data"]
    assert metrics["count"] == 3 and {m["method"] for m in metrics["data"]} == {c["method"] for c in calibrations}
    chosen = next(c for c in calibrations if c["chosen"])
    assert metrics["chosen"] == chosen["method"] == next(m["method"] for m in metrics["data"] if m["chosen"])
    for m in metrics["data"]:
        stored = next(c for c in calibrations if c["method"] == m["method"])["metrics"]
        assert m["heldout"]["max_deg"] == stored["heldout"]["max_deg"]
        assert m["heldout_scheme"] == stored["heldout_scheme"]
        assert m["at_nodes"]["rms_deg"] == stored["at_nodes"]["rms_deg"]
        assert m["chi2_dof"] == stored["chi2_dof"] and math.isfinite(m["heldout"]["p99_deg"])
    # the chosen one is the smallest held-out maximum (seed 002 §5.2–5.3)
    assert chosen["metrics"]["heldout"]["max_deg"] == min(m["heldout"]["max_deg"] for m in metrics["data"])
    document = _get(client, f"/api/calibrations/{run['id']}/{chosen['method']}.json")
    assert metrics["warnings"] == document["warnings"]
    assert [r["row"] for r in metrics["rejected"]] == [r["row"] for r in document["rejected"]]
    assert all(r["key"] and r["stage"] in ("dark", "grid", "check") for r in metrics["rejected"])
    assert metrics["dark_model"] == document["dark"]["model"]


def test_the_cmos_routes_on_a_qd_run_refuse_or_answer_in_its_terms(finished, tmp_path):
    client, run = finished
    rid = run["id"]
    for query in ("", "?method=geometric", "?method=physical"):  # refused for its family, whatever the method
        refused = client.get(f"/api/runs/{rid}/fit{query}", headers=AUTH)
        assert refused.status_code == 409 and "qd sensor" in refused.text and "/qd/metrics" in refused.text
    # the bench data CSV of a QD run is the one `sunbench fit qd` reads: every ok reading, the dark ones included
    csv = client.get(f"/api/runs/{rid}/data.csv", headers=AUTH)
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
    path = tmp_path / "qd.csv"
    path.write_text(csv.text)
    data = read_qd_csv(path)
    readings = sum(p["n_ok"] for p in _get(client, f"/api/runs/{rid}/qd/currents")["data"])
    assert len(data) == readings and int(data.dark.sum()) == 4 * 8 and int(data.check.sum()) == 256 * 3
    header = client.get(f"/api/calibrations/{rid}/polynomial.h", headers=AUTH)
    assert header.status_code == 200 and "sunbench_qd_sun_direction" in header.text
    assert f"run {rid}" in header.text  # its source in the opening comment
    assert _get(client, f"/api/runs/{rid}/values")["physical"] is None
    fleet = _get(client, f"/api/campaigns/{run['campaign_id']}/fleet")["data"]
    assert fleet[0]["metrics"]["heldout"]["max_deg"] > 0  # the fleet page reads its max_deg


def test_the_qd_routes_refuse_a_cmos_run(client):
    run = _finished_run(client, _submit(client))
    assert run["family"] == "cmos" and run["results_view"] == "cmos"
    for route in ("currents", "dark", "error-map", "metrics"):
        response = client.get(f"/api/runs/{run['id']}/qd/{route}", headers=AUTH)
        assert response.status_code == 409, (route, response.text)
        assert "measured a cmos sensor" in response.json()["detail"]
    assert client.get("/api/runs/999/qd/metrics", headers=AUTH).status_code == 404
    # a CMOS run's points carry their spots as their summary (the live page's spot map)
    points = _get(client, f"/api/runs/{run['id']}/points")["data"]
    assert all(set(p["summary"]) == {"spots", "spots_clipped"} for p in points if p["summary"])


def test_a_dark_sweep_alone_has_no_calibration_and_its_dark_model_is_fitted_to_its_readings(qd_client):
    run = _finished_run(qd_client, _submit(qd_client, QD_DARK), timeout_s=60)
    assert (run["status"], run["family"], run["n_points_recorded"]) == ("completed", "qd", 3)
    assert _get(qd_client, f"/api/runs/{run['id']}/calibrations")["count"] == 0
    dark = _get(qd_client, f"/api/runs/{run['id']}/qd/dark")
    assert (dark["method"], dark["source"]) == (None, "readings")
    assert dark["model"] in ("linear", "exponential") and dark["count"] == 12 and dark["light_range_c"] is None
    assert len(dark["curve"]["temperature_c"]) > 10
    metrics = _get(qd_client, f"/api/runs/{run['id']}/qd/metrics")
    assert (metrics["count"], metrics["chosen"], metrics["rejected"], metrics["warnings"]) == (0, None, [], [])
    assert "no chosen calibration" in _get(qd_client, f"/api/runs/{run['id']}/qd/error-map", 404)["detail"]
    currents = _get(qd_client, f"/api/runs/{run['id']}/qd/currents")["data"]
    assert [p["stage"] for p in currents] == ["dark"] * 3


def test_the_launcher_offers_the_qd_plans_with_the_models_fields(client):
    from test_pages import _launch_form
    form = _launch_form(client)
    grid, dark = form.inputs["qd-grid"], form.inputs["qd-dark"]
    assert set(grid) == {"field_deg", "step_deg", "repeats", "check_points", "temperature_c", "dark.temperatures_c",
                         "dark.repeats"}
    assert set(grid) - {"dark.temperatures_c", "dark.repeats"} <= set(QdGridProcedure.model_fields)
    assert [float(v) for v in grid["dark.temperatures_c"]["value"].split(",")] == list(QdDarkSweep().temperatures_c)
    assert float(grid["dark.repeats"]["value"]) == QdDarkSweep().repeats
    assert set(dark) == {"temperatures_c", "repeats", "tolerance_c"} <= set(QdDarkSweep.model_fields)


def test_the_point_events_of_a_qd_run_carry_currents_not_spots(qd_client, qd_service):
    seen = []
    qd_service.engine.subscribe(lambda event: event.kind == "point" and seen.append(event.data))
    run = _finished_run(qd_client, _submit(qd_client, QD_DARK), timeout_s=60)
    assert run["status"] == "completed" and len(seen) == 3
    for data in seen:
        assert data["family"] == "qd" and "spots" not in data
        assert len(data["currents_a"]) == 4 and data["temperature_c"] is not None


def test_the_results_and_run_pages_ship_the_qd_view(qd_client):
    from test_pages import page_ids, script_ids
    results = qd_client.get("/results").text
    for plot in ("qd-error-plot", "qd-dark-plot", "qd-currents-plot", "qd-sum-plot", "qd-metrics", "qd-rejected"):
        assert f'id="{plot}"' in results, plot
    assert 'import { showQdRun } from "./results-qd.js"' in qd_client.get("/static/results.js").text
    run = qd_client.get("/run").text
    assert 'id="currents-plot"' in run and 'id="n-currents"' in run
    # and every element the QD view's script and the live page's look up is there, on a QD bench's pages
    qd_view = {i for i, modules in script_ids(qd_client, "/static/results.js").items()
               if "/static/results-qd.js" in modules}
    assert {"qd-error-plot", "qd-dark-plot", "qd-currents-plot", "qd-sum-plot", "qd-metrics"} <= qd_view
    assert qd_view <= page_ids(results), qd_view - page_ids(results)
    live = set(script_ids(qd_client, "/static/run.js"))
    assert {"currents-plot", "n-currents", "n-temperature"} <= live <= page_ids(run), live - page_ids(run)
