"""The dashboard's horizon family (seed 004's scanning Earth-horizon sensor) on the simulated horizon bench
(examples/bench-sim-horizon.yaml), in-process at time scale 0: a small horizon-grid campaign queued through the API
completes as a horizon run, and the horizon results view's routes give the sensor's own errors ± 1σ against the nominal
design (the stored calibration document's), every edge's phase residual (its RMS the document's), every scan's roll
and pitch error (scoring the fitted and the check scans as the document does, calibrated and nominal) with maps over
the grid, and the pulse of a reading whose threshold crossings are the calibration's edges; they refuse other families'
runs, and other families' routes refuse a horizon run."""

from pathlib import Path

import numpy as np
import pytest
from inprocess import AUTH, api_client, bench_file_service
from test_api import _finished_run, _submit

from bench.horizon_results import horizon_attitude, horizon_calibration, horizon_edges, horizon_pulse
from calibration.horizon.bench_document import sensor_parameters_from_document
from calibration.horizon.bench_fit import ALL_PARAMETERS, NOMINAL, predicted_phases, wrap_deg
from calibration.horizon.locator import constant_locator

HORIZON_BENCH = Path(__file__).resolve().parents[2] / "examples" / "bench-sim-horizon.yaml"
#: A small grid: two disc radii (400 and 700 km), roll every 16.5° × pitch every 17° over the sensor's range, two
#: scans a pose, three check points a radius — 36 points, 72 scans
HORIZON_GRID = {"name": "horizon-small", "plan": "horizon-grid", "sensors": ["HZ-0001"],
                "horizon_grid": {"altitudes_km": [400, 700], "roll_step_deg": 16.5, "pitch_step_deg": 17,
                                 "repeats": 2, "check_points": 3}}
ROUTES = ("metrics", "edges", "attitude", "pulse")
#: The repeat scatter of one edge on the example bench is ~0.002°: a detected edge lies within this of the
#: calibration's prediction
EDGE_TOLERANCE_DEG = 0.02


def _get(client, path, status=200):
    response = client.get(path, headers=AUTH)
    assert response.status_code == status, (path, response.text)
    return response.json()


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The small horizon campaign run to its end on one horizon service: (client, run, catalogue)."""
    folder = tmp_path_factory.mktemp("horizon")
    with bench_file_service(HORIZON_BENCH, folder / "horizon.sqlite") as service, api_client(service) as client:
        run = _finished_run(client, _submit(client, HORIZON_GRID), timeout_s=120)
        yield client, run, service.catalogue


def _document(catalogue, run_id):
    return next(c for c in catalogue.calibrations(run_id) if c["chosen"])["document"]


def test_a_horizon_campaign_completes_as_a_horizon_run_with_its_calibration(finished):
    client, run, _ = finished
    assert run["status"] == "completed" and run["plan_name"] == "horizon-grid" and run["n_points_recorded"] == 36
    assert (run["family"], run["results_view"]) == ("horizon", "horizon")
    (calibration,) = _get(client, f"/api/runs/{run['id']}/calibrations")["data"]
    assert calibration["method"] == "crossings" and calibration["chosen"]


def test_the_metrics_route_gives_the_documents_parameters_against_the_nominal_design(finished):
    client, run, catalogue = finished
    shown = _get(client, f"/api/runs/{run['id']}/horizon/metrics")
    assert shown == horizon_calibration(catalogue, run["id"])
    document = _document(catalogue, run["id"])
    assert [p["name"] for p in shown["parameters"]] == list(ALL_PARAMETERS)
    for p in shown["parameters"]:
        entry = document["parameters"][p["name"]]
        assert [p[k] for k in ("value", "sd", "fitted", "nominal")] == [entry[k] for k in ("value", "sd", "fitted",
                                                                                            "nominal")]
        assert p["nominal"] == getattr(NOMINAL, p["name"])
        assert p["difference"] == pytest.approx(entry["value"] - entry["nominal"], abs=1e-12)
        if p["fitted"]:
            assert p["difference_sigma"] == pytest.approx(p["difference"] / p["sd"])
    assert not next(p for p in shown["parameters"] if p["name"] == "mount_pitch_deg")["fitted"]
    assert shown["warnings"] == document["warnings"] and shown["trades"] == document["identifiability"]["trades"]
    assert shown["fit"]["chi2_dof"] == document["fit"]["chi2_dof"] and len(shown["noise"]) == 4
    assert shown["heldout"]["check"] == document["heldout"]["check"]
    assert [e["disc_radius_deg"] for e in shown["heldout"]["radius_out"]] == document["plan"]["disc_radii_deg"]
    assert shown["correlation"]["names"] == document["correlation"]["names"]
    # the build the simulator was given differs from the design by far more than the calibration's 1σ: the view shows
    # a sensor that is not the nominal one, and the calibrated sensor scores ten times better at the check points
    assert max(abs(p["difference_sigma"]) for p in shown["parameters"] if p["fitted"]) > 10
    check = shown["heldout"]["check"]
    for q in ("roll", "pitch"):
        assert check["calibrated"][f"{q}_rms_deg"] < check["nominal"][f"{q}_rms_deg"] / 10


def test_every_edges_residual_is_against_the_documents_model(finished):
    """Each edge's residual is the reported phase − the document's crossing model (calibration.horizon.bench_fit),
    so the fitted edges' RMS is the document's fit.rms_deg; the nominal sensor misses by ten times more."""
    client, run, catalogue = finished
    edges = _get(client, f"/api/runs/{run['id']}/horizon/edges")
    assert edges == horizon_edges(catalogue, run["id"])
    document = _document(catalogue, run["id"])
    # every edge found: those the fit used, those it rejected and the check scans' (12 scans × 2 cones × 2 edges)
    fit = document["fit"]
    assert edges["count"] == 72 * 2 * 2 - fit["n_missing"] == fit["n_edges"] + len(document["rejected"]) + 48
    assert edges["fitted_rms_deg"] == pytest.approx(document["fit"]["rms_deg"], rel=1e-9)
    parameters = sensor_parameters_from_document(document)
    i = np.arange(edges["count"])
    for model, key in ((parameters, "residual_deg"), (NOMINAL, "residual_nominal_deg")):
        out, in_ = predicted_phases(np.array(edges["roll_deg"]), np.array(edges["pitch_deg"]),
                                    np.array(edges["disc_radius_deg"]), np.array(edges["cone"]), model)
        predicted = np.where(np.array(edges["edge"]) == "out", out, in_)
        assert np.allclose(edges[key], wrap_deg(np.array(edges["phase_deg"]) - predicted)[i], atol=1e-9)
    fitted = [s for s in edges["summary"] if s["kind"] == "fitted"]
    assert len(fitted) == 4 and all(s["rms_nominal_deg"] > 5 * s["rms_deg"] for s in fitted)
    check = [s for s in edges["summary"] if s["kind"] == "check"]
    assert len(check) == 4 and all(s["n"] == 12 and s["rms_deg"] < EDGE_TOLERANCE_DEG for s in check)
    assert edges["rejected"].count(None) == edges["count"] - len(document["rejected"])


def test_every_scans_roll_and_pitch_error_scores_as_the_document_does(finished):
    client, run, catalogue = finished
    attitude = _get(client, f"/api/runs/{run['id']}/horizon/attitude")
    assert attitude == horizon_attitude(catalogue, run["id"])
    held = _document(catalogue, run["id"])["heldout"]
    assert attitude["count"] == 72 and sum(attitude["check"]) == 12
    for kind, stored in (("fitted", held["at_nodes"]), ("check", held["check"])):
        for sensor in ("calibrated", "nominal"):
            shown, expected = attitude["summary"][kind][sensor], stored[sensor]
            assert shown == pytest.approx({k: expected[k] for k in shown}, rel=1e-9, abs=1e-12), (kind, sensor)
    # the maps: one per radius, the grid's 5 rolls × 3 pitches, each node the mean of its two scans
    assert [m["disc_radius_deg"] for m in attitude["maps"]] == pytest.approx([64.304, 70.218], abs=1e-3)
    for m in attitude["maps"]:
        assert m["roll_deg"] == pytest.approx([-33, -16.5, 0, 16.5, 33])
        assert m["pitch_deg"] == pytest.approx([-17, 0, 17])
        for name in ("roll_error_deg", "pitch_error_nominal_deg"):
            for p, pitch in enumerate(m["pitch_deg"]):
                for r, roll in enumerate(m["roll_deg"]):
                    scans = [attitude[name][k] for k in range(attitude["count"]) if not attitude["check"][k]
                             and abs(attitude["roll_deg"][k] - roll) < 1e-3 and abs(attitude["pitch_deg"][k] - pitch)
                             < 1e-3 and abs(attitude["disc_radius_deg"][k] - m["disc_radius_deg"]) < 1e-3]
                    assert len(scans) == 2 and m[name][p][r] == pytest.approx(np.mean(scans), abs=1e-12)


def test_the_pulse_of_a_reading_crosses_the_threshold_at_the_calibrations_edges(finished):
    """The pulse drawn from the calibration crosses half its height where the calibration's crossing model puts the
    edges (the seed 004 eq. 2.1 locator run on it), within 0.001°; the module's detected edges lie within the noise of
    those, and the nominal sensor's edges are further off."""
    client, run, catalogue = finished
    latest = _get(client, f"/api/runs/{run['id']}/horizon/pulse")
    assert latest == horizon_pulse(catalogue, run["id"])
    readings = [r for r in catalogue.readings(run["id"]) if r.ok]
    assert latest["reading"]["id"] == readings[-1].id and latest["source"] == "model"
    grid = next(r for r in readings if r.stage == "grid" and "roll+033" in r.key)
    pulse = _get(client, f"/api/runs/{run['id']}/horizon/pulse?reading_id={grid.id}")
    assert pulse["reading"]["roll_deg"] == pytest.approx(33, abs=1e-6)
    phase = np.array(pulse["phase_deg"])
    nearer = 0
    for k, cone in enumerate(pulse["cones"]):
        out, in_ = constant_locator(phase, np.array(cone["fraction"]), 0.5)
        assert [out, in_] == pytest.approx([cone["calibrated_deg"]["out"], cone["calibrated_deg"]["in"]], abs=1e-3)
        assert [cone["level_space"], cone["level_earth"]] == [grid.values[f"level_{w}"][k] for w in ("space", "earth")]
        assert cone["threshold"] == pytest.approx((cone["level_space"] + cone["level_earth"]) / 2)
        assert max(cone["level"]) == pytest.approx(cone["level_earth"], rel=1e-6)
        for edge in ("out", "in"):
            detected = cone["detected_deg"][edge]
            assert detected == pytest.approx(360 * grid.values[f"t_{edge}_s"][k] / grid.values["period_s"])
            assert abs(wrap_deg(detected - cone["calibrated_deg"][edge])) < EDGE_TOLERANCE_DEG
            nearer += abs(wrap_deg(detected - cone["nominal_deg"][edge])) > abs(wrap_deg(detected -
                                                                                       cone["calibrated_deg"][edge]))
    assert nearer == 4
    assert "no usable reading" in _get(client, f"/api/runs/{run['id']}/horizon/pulse?reading_id=999999", 404)["detail"]


# -- refusals -------------------------------------------------------------------------------------------------------
def test_the_horizon_routes_refuse_other_families_runs_and_theirs_refuse_a_horizon_run(finished, client):
    horizon_client, run, _ = finished
    for route in ("qd/metrics", "camera/fit", "css/metrics"):
        response = horizon_client.get(f"/api/runs/{run['id']}/{route}", headers=AUTH)
        assert response.status_code == 409 and "measured a horizon sensor" in response.json()["detail"], route
    refused = horizon_client.get(f"/api/runs/{run['id']}/fit", headers=AUTH)
    assert refused.status_code == 409 and f"/api/runs/{run['id']}/horizon/metrics" in refused.json()["detail"]
    for route in ROUTES:
        assert horizon_client.get(f"/api/runs/999/horizon/{route}", headers=AUTH).status_code == 404, route
    assert "no nope calibration" in _get(horizon_client, f"/api/runs/{run['id']}/horizon/metrics?method=nope",
                                         404)["detail"]
    cmos = _finished_run(client, _submit(client))
    for route in ROUTES:
        response = client.get(f"/api/runs/{cmos['id']}/horizon/{route}", headers=AUTH)
        assert response.status_code == 409 and "measured a cmos sensor" in response.json()["detail"], route


def test_the_results_pages_downloads_of_a_horizon_run(finished):
    client, run, catalogue = finished
    csv = client.get(f"/api/runs/{run['id']}/data.csv", headers=AUTH)
    lines = csv.text.splitlines()  # the sensor's IFOV as a header comment, then the columns
    assert csv.status_code == 200 and lines[0].startswith("# ifov_half_angle_deg: ") and "phase_out_deg" in lines[1]
    header = client.get(f"/api/calibrations/{run['id']}/crossings.h", headers=AUTH)
    assert header.status_code == 200 and "SUNBENCH_HORIZON_GAMMA1_DEG" in header.text


def test_the_results_page_ships_the_horizon_view(finished):
    from test_pages import page_ids, script_ids
    client = finished[0]
    results = client.get("/results").text
    assert 'import { showHorizonRun } from "./results-horizon.js"' in client.get("/static/results.js").text
    view = {i for i, modules in script_ids(client, "/static/results.js").items()
            if "/static/results-horizon.js" in modules}
    assert {"horizon-view", "horizon-parameters", "horizon-residuals-plot", "horizon-maps-plot",
            "horizon-pulse-plot"} <= view
    assert view <= page_ids(results), view - page_ids(results)


def test_the_launcher_offers_horizon_grid_with_every_field_its_default_and_limits(finished):
    """On a horizon bench the launcher's page names the family's plan; its fieldset has every field of
    HorizonGridProcedure with the model's default and limits (as tests/web/test_pages.py checks the other plans')."""
    from test_pages import _launch_form, _limits

    from bench.campaign import HorizonGridProcedure
    client = finished[0]
    assert 'data-plans="horizon-grid"' in client.get("/launch").text
    form = _launch_form(client)
    assert "horizon-grid" in form.options
    inputs = form.inputs["horizon-grid"]
    assert set(inputs) == set(HorizonGridProcedure.model_fields)
    for name, attrs in inputs.items():
        field = HorizonGridProcedure.model_fields[name]
        if name == "disc_radii_deg":  # optional: blank keeps the model's None (the altitudes decide)
            assert field.default is None and attrs["value"] == "" and "data-blank" in attrs and "required" not in attrs
        elif "data-list" in attrs:
            assert [float(v) for v in attrs["value"].split(",")] == list(field.default), name
        else:
            assert attrs["type"] == "number" and "required" in attrs, name
            assert float(attrs["value"]) == field.default, name
            assert (float(attrs["min"]), float(attrs["max"])) == _limits(field), name
            assert attrs["step"] == ("1" if field.annotation is int else "any"), name
