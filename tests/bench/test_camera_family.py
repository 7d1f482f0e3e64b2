"""The camera family end to end on the simulated bench (issue 13): a camera-grid campaign runs through bench.runner,
records each frame's spot under the camera descriptor, fits OpenCV's camera model when it ends and reaches the
issue's accuracy held out ("the camera calibrated on the bench reaches ≤ 0.02° held out on its simulator"); the
direction the engine records is the one planned, on both kinds of table; the exported CSV, fitted by `sunbench fit
camera`, gives the same model.

The frames come from the simulator's own optics (drivers/sim/camera_optics.py: a lens polynomial in the field
angle, a tilted detector, a rotated mount), never OpenCV's model: the figures measure the calibration."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from clitools import flat, invoke

from bench.benchfile import BenchFile, load_bench_file
from bench.campaign import CameraGridProcedure, Campaign, load_campaign_file
from bench.catalogue import Catalogue
from bench.families.camera import DESCRIPTOR, grid_directions, grid_points
from bench.runner import check_campaign, open_session, run_campaign, session_mount
from calibration.camera import camera_from_document, zenith_azimuth
from calibration.geometry import direction_vector

ROOT = Path(__file__).resolve().parents[2]


def _angle_deg(a, b):
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


@pytest.fixture(scope="module")
def camera_run(tmp_path_factory):
    """examples/camera-grid.yaml on examples/bench-sim-camera.yaml at time scale 0: (catalogue path, run id, the
    preflight report, the wall time, the camera's truth and its renderer)."""
    path = tmp_path_factory.mktemp("camera") / "catalogue.sqlite"
    campaign = load_campaign_file(ROOT / "examples" / "camera-grid.yaml")
    with Catalogue(path) as catalogue:
        session = open_session(load_bench_file(ROOT / "examples" / "bench-sim-camera.yaml"), catalogue,
                               time_scale=0.0)
        try:
            report = check_campaign(campaign, session)
            t0 = time.perf_counter()
            (run_id,) = run_campaign(campaign, session)  # the camera tells its serial: no mount to confirm
            wall = time.perf_counter() - t0
            renderer = session.devices.sim.camera.renderer
        finally:
            session.close()
    return path, run_id, report, wall, renderer


def test_a_camera_campaign_is_recorded_under_its_descriptor_and_meets_the_issue_accuracy(camera_run):
    path, run_id, report, wall, _ = camera_run
    with Catalogue(path, readonly=True) as catalogue:
        run = catalogue.run(run_id)
        assert run["status"] == "completed", run["exit_reason"]
        assert run["family"] == "camera" and catalogue.descriptor(run_id) == DESCRIPTOR
        assert run["provenance"]["sensor_serial"] == "CAM-0001" and "SB-SIM-WEBCAM" in run["provenance"]["devices"][
            "sensor"]
        readings = catalogue.readings(run_id)
        assert len(readings) == 2 * len(report.points) and all(r.ok for r in readings)
        assert set(readings[0].values) == {"x_px", "y_px", "peak_dn", "flux_dn", "area_px", "roundness", "valid",
                                           "cloud"}
        assert isinstance(readings[0].values["cloud"], bool) and isinstance(readings[0].values["area_px"], int)
        clouds = sum(r.values["cloud"] for r in readings)
        assert clouds <= 0.02 * len(readings)  # the lab's lamp: no cloud (the flag's false alarms, if any)
        # the auto-exposure put the Sun's peak at 60–70 % of full scale at the boresight
        exposure = catalogue.run_value(run_id, "exposure_ms")
        boresight = [r.values["peak_dn"] / 255 for r in readings if r.zenith_deg == 0.0]
        assert 0.58 <= np.mean(boresight) <= 0.72 and all(r.exposure_ms == exposure for r in readings)
        (calibration,) = catalogue.calibrations(run_id)
        events = [e["message"] for e in catalogue.events(run_id) if e["kind"] == "fit"]
    assert calibration["chosen"] and calibration["method"] == "opencv"
    document = calibration["document"]
    assert document["family"] == "camera" and document["kind"] == "camera" and document["source"] == f"run {run_id}"
    held = calibration["metrics"]["held_out"]
    rings, azimuths = held["rings"], held["azimuths"]
    print(f"\ncamera grid: {len(report.points)} directions × 2 frames, {report.duration_s / 60:.1f} min on the bench "
          f"(preflight), {wall:.1f} s here at time scale 0; auto-exposure {exposure} ms "
          f"(boresight peak {np.mean(boresight):.0%}); cloud flags {clouds}/{len(readings)}")
    print(f"held out by rings: {len(rings['groups'])} rings, RMS {rings['rms_deg']:.4f}°, max {rings['max_deg']:.4f}°; "
          f"by azimuths: {len(azimuths['groups'])} azimuths, RMS {azimuths['rms_deg']:.4f}°, max "
          f"{azimuths['max_deg']:.4f}°; fit RMS {calibration['metrics']['fit_rms_deg']:.4f}°, χ²/dof "
          f"{calibration['metrics']['reduced_chi2']:.2f}")
    # the issue: the camera calibrated on the bench reaches ≤ 0.02° held out on its simulator
    for scheme in (rings, azimuths):
        assert scheme["rms_deg"] <= 0.02 and scheme["max_deg"] <= 0.02
    assert len(rings["groups"]) == 7 and len(azimuths["groups"]) == 20  # every interior ring, every azimuth
    assert document["warnings"] == []
    assert any("held out by rings" in e for e in events)


def test_the_calibration_against_the_simulators_true_lens(camera_run):
    """Beyond the held-out figures: the true lens (the simulator's, inverted) against the calibration at random
    directions over the frame. The bench's camera sits square on its fixture (the example's mount tilt is 0), so the
    body frame the engine records is the camera housing's."""
    path, run_id, _, _, renderer = camera_run
    with Catalogue(path, readonly=True) as catalogue:
        model = camera_from_document(catalogue.calibrations(run_id)[0]["document"])
    rng = np.random.default_rng(5)
    pixels = rng.uniform([20, 20], [619, 459], (500, 2))
    truth = renderer.pixel_direction(pixels[:, 0], pixels[:, 1])
    zenith, azimuth = zenith_azimuth(model, pixels)
    error = _angle_deg(truth, direction_vector(zenith, azimuth))
    print(f"\nagainst the true lens at 500 random pixels: RMS {np.sqrt(np.mean(error ** 2)):.4f}°, "
          f"max {error.max():.4f}°")
    assert error.max() < 0.02


def test_the_recorded_direction_is_the_planned_one(camera_run):
    path, run_id, _, _, _ = camera_run
    with Catalogue(path, readonly=True) as catalogue:
        campaign = Campaign.model_validate(catalogue.run(run_id)["plan_args"])
        readings = catalogue.readings(run_id)
    zenith, azimuth = grid_directions(campaign.camera_grid)
    planned = {f"grid_z{z:07.3f}_a{a:07.3f}": direction_vector(z, a) for z, a in zip(zenith, azimuth)}
    recorded = np.array([direction_vector(r.zenith_deg, r.azimuth_body_deg) for r in readings])
    wanted = np.array([planned[r.key] for r in readings])
    assert _angle_deg(recorded, wanted).max() < 1e-9


def test_on_an_alt_az_fork_the_plan_sets_the_directions_through_its_kinematics(tmp_path):
    """On an LX200 fork the table's angles are not the camera's zenith and azimuth: the plan inverts the fork's
    kinematics and the engine records the direction the same kinematics give."""
    bench = BenchFile.model_validate({"simulation": {"time_scale": 0, "family": "camera", "table": "lx200",
                                                     "axis_order": "zenith-on-azimuth"},
                                      "devices": {"table": {"zenith_limits_deg": [-60, 80]}}})
    procedure = CameraGridProcedure(rings=3, azimuths=4, repeats=1)
    campaign = Campaign(name="fork", plan="camera-grid", sensors=("CAM-0001",), camera_grid=procedure)
    with Catalogue(tmp_path / "catalogue.sqlite") as catalogue:
        session = open_session(bench, catalogue, time_scale=0.0)
        try:
            points = grid_points(procedure, session_mount(session))
            assert any(abs(p.azimuth_deg) > 1 and abs(p.zenith_stage_deg) > 1 for p in points)
            (run_id,) = run_campaign(campaign, session)
            run = catalogue.run(run_id)
            readings = catalogue.readings(run_id)
        finally:
            session.close()
    assert run["status"] == "completed", run["exit_reason"]
    zenith, azimuth = grid_directions(procedure)
    planned = {f"grid_z{z:07.3f}_a{a:07.3f}": direction_vector(z, a) for z, a in zip(zenith, azimuth)}
    recorded = np.array([direction_vector(r.zenith_deg, r.azimuth_body_deg) for r in readings])
    assert _angle_deg(recorded, np.array([planned[r.key] for r in readings])).max() < 1e-9
    assert all(r.ok for r in readings)


def test_the_exported_csv_fitted_on_the_command_line_gives_the_same_model(camera_run, tmp_path):
    path, run_id, _, _, _ = camera_run
    csv_path, cal = tmp_path / "camera.csv", tmp_path / "cal.json"
    exported = invoke("export", run_id, "--format", "csv", "-o", csv_path, "--catalogue", path)
    assert exported.exit_code == 0, exported.output
    lines = csv_path.read_text().splitlines()
    assert lines[:3] == ["# width_px: 640", "# height_px: 480",
                         "zenith_deg,azimuth_deg,x_px,y_px,repeat,sensor_id,exposure_ms"]
    fitted = invoke("fit", "camera", csv_path, "-o", cal)
    assert fitted.exit_code == 0, fitted.output
    with Catalogue(path, readonly=True) as catalogue:
        run_document = catalogue.calibrations(run_id)[0]["document"]
    cli_document = json.loads(cal.read_text())
    pixels = np.stack(np.meshgrid(np.linspace(10, 629, 12), np.linspace(10, 469, 9)), axis=-1).reshape(-1, 2)
    run_rays = direction_vector(*zenith_azimuth(camera_from_document(run_document), pixels))
    cli_rays = direction_vector(*zenith_azimuth(camera_from_document(cli_document), pixels))
    assert _angle_deg(run_rays, cli_rays).max() < 1e-6  # the same spots, the same model
    assert cli_document["metrics"]["heldout"]["rms_vector_deg"] == pytest.approx(
        run_document["metrics"]["heldout"]["rms_vector_deg"], rel=1e-4)
    shown = invoke("show", run_id, "--catalogue", path)
    assert shown.exit_code == 0, shown.output
    assert "held out, rings left out: RMS" in flat(shown.output) and "(camera)" in shown.output
