"""The dashboard's camera family (seed 001's camera sun sensor) on the simulated camera bench, in-process at time scale
0: the bench says its family and its plan, the launcher's camera grid is a valid campaign, a small camera grid run
through the API completes as a camera run, and the camera results view's route gives its calibration's model with
the 1σ of each parameter, the fit's and the held-out figures (the worse scheme marked), the warnings and every
point's spot with the calibration's residual — the stored model applied again gives back the fit's own figures; the
route refuses a run of another family (409) and a run or calibration that is not there (404)."""

import math
import re

import numpy as np
import pytest
from inprocess import AUTH, api_client, camera_bench_service
from test_api import SMALL_JSON, _finished_run, _submit, _wait_for

from bench.campaign import CameraGridProcedure
from calibration.camera import PARAMETERS, camera_from_document, project, ray_directions
from calibration.geometry import direction_vector

#: the launcher's camera grid as it sends it (launch.html: the fieldset's fields), kept small: 3 rings (the least
#: CameraGridProcedure takes) × 4 azimuths (the least) and the frame's 4 corners, 2 frames each — 19 directions
#: reach the frame (the outer ring only at the corners), 38 frames for 12 parameters (the fit wants 36)
SMALL_CAMERA_GRID = {"name": "bench-campaign", "plan": "camera-grid", "sensors": ["CAM-0001"], "frames": "roi",
                     "camera_grid": {"horizontal_fov_deg": 43.6, "width_px": 640, "height_px": 480, "rings": 3,
                                     "azimuths": 4, "margin_radii": 2, "repeats": 2}}
SMALL_POINTS = 19
#: the same grid with its spots half a disc radius from the frame's border: the outer corners' spots lie at the
#: border (bench.families.camera.EDGE_MARGIN_PX), recorded and never fitted
EDGE_CAMERA_GRID = {**SMALL_CAMERA_GRID, "name": "edge",
                    "camera_grid": {**SMALL_CAMERA_GRID["camera_grid"], "margin_radii": 0.5}}
FIT_TIMEOUT_S = 60.0


def _get(client, path, status=200):
    response = client.get(path, headers=AUTH)
    assert response.status_code == status, (path, response.text)
    return response.json()


@pytest.fixture(scope="module")
def camera_service(tmp_path_factory):
    """A started bench service on the simulated camera bench (examples/bench-sim-camera.yaml) at time scale 0, the
    small camera grid (SMALL_CAMERA_GRID) run to completion on it: its run is the catalogue's first."""
    with camera_bench_service(tmp_path_factory.mktemp("camera")) as service, api_client(service) as client:
        run = _finished_run(client, _submit(client, SMALL_CAMERA_GRID), timeout_s=FIT_TIMEOUT_S)
        assert run["status"] == "completed", run
        yield service


@pytest.fixture(scope="module")
def camera_client(camera_service):
    with api_client(camera_service) as client:
        yield client


@pytest.fixture(scope="module")
def camera_run(camera_client):
    return _get(camera_client, "/api/runs/1")


def _document(client, run_id, method="opencv"):
    return _get(client, f"/api/calibrations/{run_id}/{method}.json")


# -- the bench says what it measures ------------------------------------------------------------------------
def test_the_status_and_the_pages_say_the_bench_is_a_camera_bench_and_its_plan(camera_client):
    status = _wait_for(lambda: (s := _get(camera_client, "/api/status"))["sensor"] and s, "the sensor's status")
    bench = status["bench"]
    assert (bench["family"], bench["plans"], bench["has_frames"]) == ("camera", ["camera-grid"], True)
    assert "seed 001" in bench["family_title"]
    for path in ("/", "/launch", "/run", "/results", "/fleet"):
        body = re.search(r"<body[^>]*>", camera_client.get(path).text).group()
        assert 'data-family="camera"' in body and 'data-plans="camera-grid"' in body and 'data-frames="true"' in body


def test_the_launcher_form_of_a_camera_grid_is_a_valid_campaign_and_a_cmos_plan_is_refused(camera_client):
    dry = camera_client.post("/api/campaigns/dry-run", json=SMALL_CAMERA_GRID, headers=AUTH)
    assert dry.status_code == 200 and dry.json()["violations"] == [], dry.text
    assert dry.json()["points"] == SMALL_POINTS
    foreign = camera_client.post("/api/campaigns/dry-run", json=SMALL_JSON, headers=AUTH).json()
    assert any("seed003" in v for v in foreign["violations"])


def test_the_launcher_offers_the_camera_grid_with_the_models_fields(camera_client):
    from test_pages import _launch_form
    form = _launch_form(camera_client)
    assert "camera-grid" in form.options
    # every field of the procedure but its auto-exposure (kept at the plan's defaults, as seed 003's is)
    assert set(form.inputs["camera-grid"]) == set(CameraGridProcedure.model_fields) - {"auto_exposure"}
    assert set(form.inputs["camera-grid"]) == set(SMALL_CAMERA_GRID["camera_grid"])


# -- a camera campaign through the API ----------------------------------------------------------------------
def test_the_small_camera_grid_completes_as_a_camera_run_with_its_calibration(camera_client, camera_run):
    assert (camera_run["status"], camera_run["plan_name"]) == ("completed", "camera-grid")
    assert (camera_run["family"], camera_run["results_view"]) == ("camera", "camera")
    assert camera_run["n_points_recorded"] == SMALL_POINTS
    listed = next(r for r in _get(camera_client, "/api/runs")["data"] if r["id"] == camera_run["id"])
    assert (listed["family"], listed["results_view"]) == ("camera", "camera")
    (calibration,) = _get(camera_client, f"/api/runs/{camera_run['id']}/calibrations")["data"]
    assert (calibration["method"], calibration["chosen"]) == ("opencv", True)


def test_the_camera_fit_route_gives_the_model_its_figures_and_warnings(camera_client, camera_run):
    rid = camera_run["id"]
    fit = _get(camera_client, f"/api/runs/{rid}/camera/fit")
    document = _document(camera_client, rid)
    metrics = document["metrics"]["opencv"]
    assert (fit["run_id"], fit["method"], fit["chosen"], fit["sensor_id"]) == (rid, "opencv", True, "CAM-0001")
    assert (fit["width_px"], fit["height_px"]) == (640, 480)
    assert fit["fov_half_deg"] == pytest.approx(document["design"]["fov_half_deg"])
    # the model: every parameter in calibration.camera's order, its value the document's, with its 1σ
    model = camera_from_document(document)
    assert [p["name"] for p in fit["parameters"]] == list(PARAMETERS)
    values = {p["name"]: p["value"] for p in fit["parameters"]}
    for name in PARAMETERS[:9]:
        assert values[name] == getattr(model, name), name
    assert [values[f"rot_{a}_deg"] for a in "xyz"] == list(model.rotation_deg)
    for p in fit["parameters"]:
        assert p["fitted"] and p["sd"] == document["sigma"][p["name"]] and p["sd"] > 0, p
        assert p["unit"] == {"px": "px", "deg": "°"}.get(p["name"].rsplit("_", 1)[-1], ""), p
    assert "1σ" in fit["parameters_note"]
    # the figures: the fit's, and each held-out scheme's as the document has them, the worse marked once
    figures = fit["figures"]
    assert figures["fit"] == {"n_points": metrics["n_points"], "rms_deg": metrics["fit_rms_deg"],
                              "max_deg": metrics["fit_max_deg"], "rms_px": metrics["fit_rms_px"],
                              "reduced_chi2": metrics["reduced_chi2"], "noise_px": metrics["noise_px"]}
    assert metrics["n_points"] == 2 * SMALL_POINTS
    held = metrics["held_out"]
    assert [s["scheme"] for s in figures["held_out"]] == ["rings", "azimuths"]
    for scheme in figures["held_out"]:
        stored = held[scheme["scheme"]]
        assert (scheme["rms_deg"], scheme["max_deg"], scheme["n_points"]) == (stored["rms_deg"], stored["max_deg"],
                                                                              stored["n_points"])
        assert scheme["groups_deg"] == stored["groups"] and scheme["n_groups"] == len(stored["groups"])
        assert scheme["worse"] == (scheme["scheme"] == held["worst_scheme"])
    assert [s["worse"] for s in figures["held_out"]].count(True) == 1
    assert figures["worse_scheme"] == held["worst_scheme"] == metrics["heldout"]["scheme"]
    assert (figures["heldout_rms_deg"], figures["heldout_max_deg"]) == (held["worst_rms_deg"], held["max_deg"])
    # 2 interior rings left out (not the boresight, not the outermost); 4 azimuths and the 4 corners'
    assert (len(held["rings"]["groups"]), len(held["azimuths"]["groups"])) == (2, 8)
    assert fit["warnings"] == document["warnings"]


def test_the_stored_model_applied_again_gives_back_the_fits_own_figures(camera_client, camera_run):
    fit = _get(camera_client, f"/api/runs/{camera_run['id']}/camera/fit")
    stored = fit["figures"]["fit"]
    assert fit["frames"]["n_points"] == stored["n_points"]
    assert fit["frames"]["rms_deg"] == pytest.approx(stored["rms_deg"], rel=1e-6)
    assert fit["frames"]["max_deg"] == pytest.approx(stored["max_deg"], rel=1e-6)
    assert fit["frames"]["rms_px"] == pytest.approx(stored["rms_px"], rel=1e-6)
    # the points' mean spots: no worse than the frames' largest residual, and well calibrated (the simulated camera)
    assert fit["points"]["n_points"] == fit["count"] == SMALL_POINTS
    assert 0 < fit["points"]["rms_deg"] <= fit["points"]["max_deg"] <= stored["max_deg"] * (1 + 1e-9) < 0.01


def test_every_point_has_its_spot_the_direction_set_and_the_calibrations_residual(camera_client, camera_run):
    rid = camera_run["id"]
    fit = _get(camera_client, f"/api/runs/{rid}/camera/fit")
    model = camera_from_document(_document(camera_client, rid))
    points = {p["id"]: p for p in _get(camera_client, f"/api/runs/{rid}/points")["data"]}
    assert [p["id"] for p in fit["data"]] == sorted(points)  # recording order
    assert fit["data"][0]["zenith_deg"] == 0  # the boresight first
    for p in fit["data"]:
        point = points[p["id"]]
        assert (p["key"], p["stage"], p["run_id"]) == (point["key"], "grid", rid)
        # the direction the table set, and the mean of the point's spots (none at the border here)
        assert (p["zenith_deg"], p["azimuth_deg"]) == (point["zenith_deg"], point["azimuth_body_deg"])
        assert p["n_frames"] == 2 and p["excluded"] is None and p["frames_left_out"] == []
        assert p["x_px"] == pytest.approx(point["x_px"], abs=1e-9)
        assert p["y_px"] == pytest.approx(point["y_px"], abs=1e-9)
        # the residual: the angle between the direction set and the model's ray through the spot …
        n = direction_vector(p["zenith_deg"], p["azimuth_deg"])
        ray = ray_directions(model, np.array([p["x_px"], p["y_px"]]))
        angle = math.degrees(math.atan2(np.linalg.norm(np.cross(n, ray)), float(np.dot(n, ray))))
        assert p["error_deg"] == pytest.approx(angle, abs=1e-9)
        # … and the vector from the spot to where the model puts the direction set
        x, y = project(model, n)
        assert (p["residual_x_px"], p["residual_y_px"]) == (pytest.approx(x - p["x_px"], abs=1e-9),
                                                            pytest.approx(y - p["y_px"], abs=1e-9))
        assert math.hypot(p["residual_x_px"], p["residual_y_px"]) < 0.2  # px: a calibrated camera
        assert p["zenith_fit_deg"] == pytest.approx(p["zenith_deg"], abs=0.01)


def test_the_route_takes_the_method_and_refuses_what_is_not_there(camera_client, camera_run):
    rid = camera_run["id"]
    assert _get(camera_client, f"/api/runs/{rid}/camera/fit?method=opencv")["method"] == "opencv"
    unknown = _get(camera_client, f"/api/runs/{rid}/camera/fit?method=nonsense", 404)["detail"]
    assert unknown == f"run {rid} has no nonsense calibration"
    assert _get(camera_client, "/api/runs/999/camera/fit", 404)["detail"] == "no run 999"
    assert camera_client.get(f"/api/runs/{rid}/camera/fit").status_code == 401  # a read needs the token
    # the other families' result routes refuse a camera run, and say where its results are
    refused = _get(camera_client, f"/api/runs/{rid}/fit", 409)["detail"]
    assert "camera sensor" in refused and f"/api/runs/{rid}/camera/fit" in refused
    assert "measured a camera sensor" in _get(camera_client, f"/api/runs/{rid}/qd/metrics", 409)["detail"]


def test_a_point_whose_spots_lie_at_the_frames_border_is_left_out_and_said_so(camera_service, camera_client):
    run = _finished_run(camera_client, _submit(camera_client, EDGE_CAMERA_GRID), timeout_s=FIT_TIMEOUT_S)
    assert run["status"] == "completed"
    fit = _get(camera_client, f"/api/runs/{run['id']}/camera/fit")
    left = [p for p in fit["data"] if p["excluded"]]
    assert left, "the half-radius margin put no spot at the frame's border"
    for p in left:
        assert "frame's border" in p["excluded"] and p["n_frames"] == 0
        assert [f["reason"] for f in p["frames_left_out"]] == [p["excluded"]] * 2
        # drawn where its spots were: at the border
        assert min(p["x_px"], 639 - p["x_px"], p["y_px"], 479 - p["y_px"]) < 15
    # counted in no summary: the frames the fit used are those of the other points, and give its figures back
    assert fit["points"]["n_points"] == fit["count"] - len(left)
    assert fit["frames"]["n_points"] == fit["figures"]["fit"]["n_points"] == 2 * (fit["count"] - len(left))
    assert fit["frames"]["rms_deg"] == pytest.approx(fit["figures"]["fit"]["rms_deg"], rel=1e-6)
    log = " ".join(e["message"] for e in _get(camera_client, f"/api/runs/{run['id']}/log")["data"])
    assert f"{2 * len(left)} spot(s) at the frame's border left out" in log


def test_the_camera_route_refuses_a_cmos_run(client):
    run = _finished_run(client, _submit(client))
    assert run["family"] == "cmos"
    response = client.get(f"/api/runs/{run['id']}/camera/fit", headers=AUTH)
    assert response.status_code == 409 and "measured a cmos sensor, not a camera one" in response.json()["detail"]
    assert client.get("/api/runs/999/camera/fit", headers=AUTH).status_code == 404


def test_the_results_page_ships_the_camera_view(camera_client):
    from test_pages import page_ids, script_ids
    results = camera_client.get("/results").text
    for element in ("camera-view", "camera-metrics", "camera-parameters", "camera-spot-plot", "camera-error-plot",
                    "camera-warnings"):
        assert f'id="{element}"' in results, element
    assert 'import { showCameraRun } from "./results-camera.js"' in camera_client.get("/static/results.js").text
    # every element the camera view's script looks up is on the results page
    camera_view = {i for i, modules in script_ids(camera_client, "/static/results.js").items()
                   if "/static/results-camera.js" in modules}
    drawn = {"camera-view", "camera-metrics", "camera-parameters", "camera-spot-plot", "camera-error-plot"}
    assert drawn <= camera_view
    assert camera_view <= page_ids(results), camera_view - page_ids(results)
