"""The dashboard's CSS family (seed 000's coarse-sun-sensor head) on the simulated CSS bench, in-process at time scale
0: a small css-sweep campaign queued through the API completes as a CSS run, and the CSS results view's routes give
every response law's figures, every detector's readings against incidence with the calibration's curve, residuals and
parameters (agreeing with the stored calibration document), the Sun's direction from every reading (scoring as the
document does) and the thesis' quantiser codes of a reading; they refuse other families' runs, and other families'
routes refuse a CSS run."""

import math

import numpy as np
import pytest
from inprocess import AUTH, api_client, css_bench_service
from test_api import _finished_run, _submit

from bench.css_results import (
    CLIPPED_REASON,
    NO_EARTH_C,
    css_codes,
    css_detectors,
    css_directions,
    css_methods,
)
from calibration.css.calibrate import diode_parameters_from_document
from calibration.css.head import CHANNELS, FACES, sun_vectors
from calibration.css.karel import karel_attitude
from calibration.css.quantiser import code_angle_deg

#: A small sweep, fitted with both response laws: rings every 20° × 4 azimuths about each face's normal, one reading
#: each, a reduced sweep at a second plate temperature (the temperature coefficients), a few check directions
CSS_SWEEP = {"name": "css-small", "plan": "css-sweep", "sensors": ["CSS-0001"], "methods": ["kelly", "power"],
             "css_sweep": {"step_deg": 20, "around": 4, "repeats": 1, "temperatures_c": [25, 40], "dark_repeats": 3,
                           "reduced_step_deg": 45, "reduced_around": 3, "check_directions": 8}}
FIT_TIMEOUT_S = 180.0  # both laws' fits, each held out, on a busy machine
CSS_ROUTES = ("metrics", "detectors", "directions", "quantiser")


def _get(client, path, status=200):
    response = client.get(path, headers=AUTH)
    assert response.status_code == status, (path, response.text)
    return response.json()


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The small CSS campaign run to its end on one CSS service: (client, run, catalogue)."""
    with css_bench_service(tmp_path_factory.mktemp("css")) as service, api_client(service) as client:
        run = _finished_run(client, _submit(client, CSS_SWEEP), timeout_s=FIT_TIMEOUT_S)
        yield client, run, service.catalogue


def _chosen(catalogue, run_id):
    return next(c for c in catalogue.calibrations(run_id) if c["chosen"])


# -- the run ---------------------------------------------------------------------------------------------------
def test_a_css_campaign_completes_as_a_css_run_with_a_calibration_per_law(finished):
    client, run, _ = finished
    assert run["status"] == "completed" and run["plan_name"] == "css-sweep"
    assert (run["family"], run["results_view"]) == ("css", "css")
    calibrations = _get(client, f"/api/runs/{run['id']}/calibrations")["data"]
    assert {c["method"] for c in calibrations} == {"kelly", "power"} and sum(c["chosen"] for c in calibrations) == 1


# -- every law's figures --------------------------------------------------------------------------------------
def test_the_metrics_route_gives_every_laws_figures_and_the_chosen_documents_words(finished):
    client, run, catalogue = finished
    metrics = _get(client, f"/api/runs/{run['id']}/css/metrics")
    assert metrics == css_methods(catalogue, run["id"]) | {"data": metrics["data"]}
    stored = {c["method"]: c for c in catalogue.calibrations(run["id"])}
    assert metrics["count"] == 2 and {m["method"] for m in metrics["data"]} == set(stored)
    for m in metrics["data"]:
        figures = stored[m["method"]]["metrics"]
        for key in ("held_out", "check", "at_nodes"):
            assert m[key] == figures[key], (m["method"], key)
        assert m["chosen"] == bool(stored[m["method"]]["chosen"]) and m["n_channels"] == len(figures["channels"])
    document = _chosen(catalogue, run["id"])["document"]
    assert metrics["chosen"] == _chosen(catalogue, run["id"])["method"]
    assert metrics["warnings"] == document["warnings"] and metrics["warnings"]
    assert metrics["uncertainty_scale"] == document["uncertainty_scale"]
    assert [f["channel"] for f in metrics["faulty"]] == [c for c, e in document["diodes"].items() if not e["valid"]]
    # each rejected reading of a detector, with its point
    assert len(metrics["rejected"]) == len(document["rejected"]) > 0
    keys = {r.id: r.key for r in catalogue.readings(run["id"])}
    for shown, entry in zip(metrics["rejected"], document["rejected"]):
        assert (shown["row"], shown["channel"], shown["reason"]) == (entry["row"], entry["channel"], entry["reason"])
        assert shown["key"] == keys[entry["row"]]


# -- every detector, against the calibration document ---------------------------------------------------------------
def test_every_detectors_numbers_are_the_calibration_documents(finished):
    """bench/css_results.py's detectors through the chosen calibration: the parameters ± 1σ and the normal are the
    document's; the residuals of the readings the fit used have the document's RMS and count; the curve is the model
    at normal incidence; each reading's incidence is the angle to the document's normal, and signal − residual is the
    document's model (:class:`calibration.css.diode.DiodeParameters`) at the reading's direction and temperature."""
    client, run, catalogue = finished
    view = css_detectors(catalogue, run["id"])
    assert view == _get(client, f"/api/runs/{run['id']}/css/detectors")
    chosen = _chosen(catalogue, run["id"])
    document = chosen["document"]
    assert (view["method"], view["chosen"], view["response"]) == (chosen["method"], True, document["response"])
    assert [d["channel"] for d in view["data"]] == list(CHANNELS) and view["count"] == 18
    assert len(view["temperatures_c"]) == 2 and view["main_temperature"] == 0  # the full sweep at 25 °C, reduced at 40
    assert view["temperatures_c"] == [pytest.approx(25, abs=1), pytest.approx(40, abs=1)]
    params = {p.channel: p for p in diode_parameters_from_document(document)}
    readings = {r.id: r for r in catalogue.readings(run["id"])}
    for diode in view["data"]:
        channel, entry = diode["channel"], document["diodes"][diode["channel"]]
        assert diode["valid"] == entry["valid"] and diode["warnings"] == entry["warnings"]
        if not entry["valid"]:
            assert diode["curve"] is None and diode["fault"] == entry["fault"]
            continue
        table = {p["name"]: p for p in diode["parameters"]}
        assert set(table) == set(entry["parameters"])
        for name, p in entry["parameters"].items():
            assert [table[name][k] for k in ("value", "sd", "fitted")] == [p["value"], p["sd"], p["fitted"]], name
        assert diode["normal"] == entry["normal"]
        assert diode["at_nodes"] == document["heldout"]["channels"][channel]["at_nodes"]
        assert diode["heldout"] == document["heldout"]["channels"][channel]["heldout"]
        # the residuals of the readings its fit used: the document's RMS over as many readings
        assert diode["n_fitted"] == entry["fit"]["n_points"], channel
        assert diode["rms_residual"] == pytest.approx(entry["fit"]["rms"], rel=1e-6), channel
        # the curve at normal incidence at the first plate temperature: S (1 + c_T ΔT) + b + b_T ΔT
        p, dt = params[channel], view["temperatures_c"][0] - 25.0
        assert view["incidence_deg"][0] == 0 and diode["curve"]["signals"][0][0] == pytest.approx(
            p.scale * (1 + p.temp_coeff_per_c * dt) + p.bias + p.bias_temp_coeff_per_c * dt, rel=1e-5)
        assert diode["curve"]["snr_db"][0] > 20
        normal = sun_vectors(entry["normal"]["zenith_deg"], entry["normal"]["azimuth_deg"])
        points = diode["points"]
        assert diode["count"] == len(points["reading_id"]) > 20
        assert max(points["incidence_deg"]) <= view["incidence_limit_deg"]
        for i in range(0, diode["count"], 7):
            r = readings[points["reading_id"][i]]
            s = sun_vectors(r.zenith_deg, r.azimuth_body_deg)
            assert points["incidence_deg"][i] == pytest.approx(math.degrees(math.acos(min(1.0, float(s @ normal)))),
                                                               abs=1e-4)
            raw = r.values["signals"][CHANNELS.index(channel)]
            assert points["signal"][i] == pytest.approx(raw, rel=1e-7)
            model = float(p.signal(s, r.values["temperature_c"]))
            assert points["residual"][i] == pytest.approx(raw - model, rel=1e-4, abs=1e-7 * abs(raw)), channel
            assert points["check"][i] == (r.stage == "check")
    # a reading the fit rejected is drawn as left out, with the document's reason
    entry = document["rejected"][0]
    diode = view["data"][CHANNELS.index(entry["channel"])]
    if entry["row"] in diode["points"]["reading_id"]:
        assert diode["points"]["left_out"][diode["points"]["reading_id"].index(entry["row"])] == entry["reason"]
    assert CLIPPED_REASON.startswith("clipped")
    # another law's curve, on request; an unknown one is refused
    other = next(c["method"] for c in catalogue.calibrations(run["id"]) if not c["chosen"])
    assert _get(client, f"/api/runs/{run['id']}/css/detectors?method={other}")["response"] == other
    assert "no nonsense calibration" in _get(client, f"/api/runs/{run['id']}/css/detectors?method=nonsense",
                                             404)["detail"]


# -- the Sun's direction from every reading ---------------------------------------------------------------------------
def test_the_directions_score_the_readings_as_the_calibration_document_does(finished):
    client, run, catalogue = finished
    directions = _get(client, f"/api/runs/{run['id']}/css/directions")
    assert directions == css_directions(catalogue, run["id"])
    document = _chosen(catalogue, run["id"])["document"]
    sun = document["heldout"]["sun"]
    for kind, stored in (("fitted", sun["at_nodes"]), ("check", sun["check"])):
        shown = directions["summary"][kind]
        assert {k: shown[k] for k in ("n_points", "n_degenerate", "n_failed")} == {
            k: stored[k] for k in ("n_points", "n_degenerate", "n_failed")}, kind
        for key in ("rms_deg", "p95_deg", "max_deg", "normalised_rms"):
            assert shown[key] == pytest.approx(stored[key], rel=1e-6), (kind, key)
    assert directions["summary"]["heldout"] == sun["heldout"]
    lit = [r for r in catalogue.readings(run["id"]) if r.stage != "dark"]
    assert directions["count"] == len(lit) and {d["kind"] for d in directions["data"]} == {"fitted", "check"}
    scale = directions["uncertainty_scale"]
    assert scale == document["uncertainty_scale"] >= 1
    for d in directions["data"]:
        if d["failed"]:
            continue
        true = sun_vectors(d["zenith_deg"], d["azimuth_deg"])
        fit = sun_vectors(d["zenith_fit_deg"], d["azimuth_fit_deg"])
        assert d["error_deg"] == pytest.approx(math.degrees(math.acos(min(1.0, float(true @ fit)))), abs=1e-6)
        assert d["az_deg"] == pytest.approx(d["azimuth_deg"] % 360)
        assert d["el_deg"] == pytest.approx(90 - d["zenith_deg"])
        if d["sigma_deg"] is not None:
            assert d["sigma_scaled_deg"] == pytest.approx(d["sigma_deg"] * scale)
        else:
            assert d["degenerate"]


# -- the thesis' quantiser codes ----------------------------------------------------------------------------------
def test_the_quantiser_codes_of_the_latest_and_of_a_chosen_reading(finished):
    client, run, catalogue = finished
    codes = _get(client, f"/api/runs/{run['id']}/css/quantiser")
    readings = catalogue.readings(run["id"])
    latest = [r for r in readings if r.stage != "dark"][-1]
    assert codes["reading"]["id"] == latest.id and codes["reading"]["key"] == latest.key
    assert codes["tps_shown"] is False and "seen temperature" in codes["tps_note"]
    assert [f["face"] for f in codes["faces"]] == list(FACES)
    assert set(codes["variants"]) == {"listing", "calibrated"}
    for variant in codes["variants"].values():
        for name in ("EPDsun", "BPWsun"):
            assert len(variant["matrices"][name]) == 5 and all(len(row) == 6 for row in variant["matrices"][name])
            assert set("".join(variant["matrices"][name])) <= {"0", "1", "x"}
    # the listing's tables get the photocurrents: the raw readings less the calibration's offsets
    document = _chosen(catalogue, run["id"])["document"]
    params = {p.channel: p for p in diode_parameters_from_document(document)}
    t = latest.values["temperature_c"]

    def photo(detector):
        return [latest.values["signals"][CHANNELS.index(f"{face}_{detector}")]
                - params[f"{face}_{detector}"].bias - params[f"{face}_{detector}"].bias_temp_coeff_per_c * (t - 25)
                for face in FACES]
    listing = codes["variants"]["listing"]
    assert listing["offsets_subtracted"] is True
    assert listing["inputs"]["epd_a"] == pytest.approx(photo("uv"), rel=1e-9, abs=1e-18)
    expected = karel_attitude(np.full(6, NO_EARTH_C), photo("uv"), photo("vis"))
    assert listing["matrices"] == {"EPDsun": list(expected.EPDsun), "BPWsun": list(expected.BPWsun)}
    assert listing["sun"]["epd"]["el_deg"] == expected.ELsunEPD and listing["sun"]["bpw"]["az_deg"] == expected.AZsunBPW
    assert codes["estimate"] is not None and codes["estimate"]["words"]

    # a reading with the Sun on the top face's normal: its codes say so, to within the quantiser's half bin
    top = next(r for r in readings if r.stage == "sweep" and r.zenith_deg < 1e-3)
    at_top = css_codes(catalogue, run["id"], reading_id=top.id)
    assert at_top == _get(client, f"/api/runs/{run['id']}/css/quantiser?reading_id={top.id}")
    face = at_top["faces"][FACES.index("pz")]
    assert face["epd_true_code"] == face["bpw_true_code"] == 1 and face["epd_incidence_deg"] < 2
    calibrated = at_top["variants"]["calibrated"]
    assert sorted(calibrated["tables"]) == ["bpw_sun", "epd_sun"]
    # the elevation is face 5's code read back (Table C.3: 90° − its bin centre); the tables rebuilt from the
    # calibration put the Sun nearer the truth than listing D.6's, made for the thesis' detectors
    for variant in (calibrated, at_top["variants"]["listing"]):
        code = variant["codes"]["EPDsun"][FACES.index("pz")]
        assert variant["sun"]["epd"]["el_deg"] == pytest.approx(float(code_angle_deg(code)))
    assert calibrated["sun"]["epd"]["error_deg"] <= at_top["variants"]["listing"]["sun"]["epd"]["error_deg"]
    assert at_top["estimate"]["el_deg"] == pytest.approx(90, abs=10)
    # a reading not of this run, and a dark one
    assert "no usable reading" in _get(client, f"/api/runs/{run['id']}/css/quantiser?reading_id=999999", 404)["detail"]
    dark = next(r for r in readings if r.stage == "dark")
    shut = css_codes(catalogue, run["id"], reading_id=dark.id)
    assert shut["reading"]["zenith_deg"] is None and all(f["epd_true_code"] == 19 for f in shut["faces"])


# -- refusals -------------------------------------------------------------------------------------------------------
def test_the_css_routes_refuse_other_families_runs_and_theirs_refuse_a_css_run(finished, client):
    css_client, run, _ = finished
    for route in ("qd/metrics", "qd/currents", "camera/fit"):
        response = css_client.get(f"/api/runs/{run['id']}/{route}", headers=AUTH)
        assert response.status_code == 409 and "measured a css sensor" in response.json()["detail"], route
    refused = css_client.get(f"/api/runs/{run['id']}/fit", headers=AUTH)
    assert refused.status_code == 409 and f"/api/runs/{run['id']}/css/metrics" in refused.json()["detail"]
    for route in CSS_ROUTES:
        assert css_client.get(f"/api/runs/999/css/{route}", headers=AUTH).status_code == 404, route
    cmos = _finished_run(client, _submit(client))
    for route in CSS_ROUTES:
        response = client.get(f"/api/runs/{cmos['id']}/css/{route}", headers=AUTH)
        assert response.status_code == 409 and "measured a cmos sensor" in response.json()["detail"], route


def test_the_results_pages_downloads_of_a_css_run(finished):
    """The buttons of the results page: the bench data CSV, and each calibration's JSON document and C header."""
    client, run, catalogue = finished
    csv = client.get(f"/api/runs/{run['id']}/data.csv", headers=AUTH)
    assert csv.status_code == 200 and "px_uv_a" in csv.text.splitlines()[0] + csv.text[:2000]
    for c in catalogue.calibrations(run["id"]):
        document = _get(client, f"/api/calibrations/{run['id']}/{c['method']}.json")
        assert {k: document[k] for k in c["document"]} == c["document"] and document["metrics"][c["method"]]
        header = client.get(f"/api/calibrations/{run['id']}/{c['method']}.h", headers=AUTH)
        assert header.status_code == 200 and f"run {run['id']}" in header.text


def test_the_results_page_ships_the_css_view(finished):
    from test_pages import page_ids, script_ids
    client = finished[0]
    results = client.get("/results").text
    for element in ("css-view", "css-metrics", "css-curves-plot", "css-parameters", "css-directions-plot",
                    "css-quantiser"):
        assert f'id="{element}"' in results, element
    assert 'import { showCssRun } from "./results-css.js"' in client.get("/static/results.js").text
    css_view = {i for i, modules in script_ids(client, "/static/results.js").items()
                if "/static/results-css.js" in modules}
    assert {"css-view", "css-metrics", "css-curves-plot", "css-parameters", "css-directions-plot"} <= css_view
    assert css_view <= page_ids(results), css_view - page_ids(results)
