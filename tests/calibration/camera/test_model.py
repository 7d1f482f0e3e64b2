"""The camera's ray model: OpenCV pinhole + Brown–Conrady, rotated against the body frame."""

import json
import math

import numpy as np
import pytest

from calibration.camera.model import (
    CameraModel,
    camera_from_document,
    design_camera,
    project,
    ray_directions,
    rotation_matrix,
    zenith_azimuth,
)
from calibration.errors import CalibrationFormatError
from calibration.geometry import direction_vector

# a strongly distorted, decentred, rotated camera: harder than the bench's
CAMERA = CameraModel(fx_px=801.5, fy_px=798.2, cx_px=324.1, cy_px=236.8, k1=-0.16, k2=0.09, p1=0.0012, p2=-0.0009,
                     k3=-0.04, rotation_deg=(0.7, -0.4, 1.1))


def _frame_grid(model, step=8.0):
    xs, ys = np.meshgrid(np.arange(0.0, model.width_px, step), np.arange(0.0, model.height_px, step))
    return np.stack([xs.ravel(), ys.ravel()], axis=1)


def _angle_deg(a, b):
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


def test_pixels_to_rays_to_pixels_round_trips_over_the_whole_frame():
    pixels = _frame_grid(CAMERA)
    rays = ray_directions(CAMERA, pixels)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-12)
    back = project(CAMERA, rays)
    err_px = np.abs(back - pixels).max()
    again = ray_directions(CAMERA, back)
    err_deg = _angle_deg(rays, again).max()
    print(f"round trip over the frame: {err_px:.2e} px, {err_deg:.2e}°")
    assert err_px < 1e-4
    assert err_deg < 1e-6


def test_rays_to_pixels_to_rays_round_trips_for_directions_in_the_field():
    rng = np.random.default_rng(0)
    zen, az = rng.uniform(0, 25, 500), rng.uniform(0, 360, 500)
    dirs = direction_vector(zen, az)
    px = project(CAMERA, dirs)
    back = ray_directions(CAMERA, px)
    assert _angle_deg(dirs, back).max() < 1e-6
    z2, a2 = zenith_azimuth(CAMERA, px)
    np.testing.assert_allclose(z2, zen, atol=1e-6)
    np.testing.assert_allclose(np.mod(a2 - az + 180, 360) - 180, 0, atol=1e-4)  # azimuth is loose near θ = 0


def test_frames_conventions_boresight_axes_and_rotation():
    plain = CameraModel(fx_px=800.0, fy_px=800.0, cx_px=319.5, cy_px=239.5)
    np.testing.assert_allclose(project(plain, np.array([0.0, 0.0, 1.0])), [319.5, 239.5])
    # body +x is image right, body +y is image down (camera = body frame at zero rotation)
    np.testing.assert_allclose(project(plain, direction_vector(10.0, 0.0)), [319.5 + 800 * math.tan(math.radians(10)),
                                                                           239.5], atol=1e-9)
    np.testing.assert_allclose(project(plain, direction_vector(10.0, 90.0)), [319.5, 239.5 + 800 * math.tan(
        math.radians(10))], atol=1e-9)
    zen, az = zenith_azimuth(plain, np.array([[319.5, 100.0]]))
    assert az[0] == pytest.approx(270.0) and zen[0] == pytest.approx(math.degrees(math.atan(139.5 / 800)))
    # rotation_deg maps body vectors into the camera frame: about +y by ω, the boresight goes to
    # X_cam = (sin ω, 0, cos ω), i.e. to the right of the principal point
    tilted = CameraModel(fx_px=800.0, fy_px=800.0, cx_px=319.5, cy_px=239.5, rotation_deg=(0.0, 2.0, 0.0))
    np.testing.assert_allclose(project(tilted, np.array([0.0, 0.0, 1.0])),
                               [319.5 + 800 * math.tan(math.radians(2.0)), 239.5], atol=1e-9)
    r = rotation_matrix(tilted)
    np.testing.assert_allclose(r @ np.array([0, 0, 1.0]), [math.sin(math.radians(2)), 0, math.cos(math.radians(2))])


def test_directions_behind_the_camera_project_to_nan():
    out = project(CAMERA, np.array([[0.0, 0.0, -1.0], [0.1, 0.0, 1.0], [1.0, 0.0, -0.1]]))
    assert np.isnan(out[0]).all() and np.isfinite(out[1]).all() and np.isnan(out[2]).all()
    with pytest.raises(ValueError):
        project(CAMERA, np.zeros((3, 2)))
    with pytest.raises(ValueError):
        ray_directions(CAMERA, np.zeros((3, 3)))


def test_design_camera_from_the_field_of_view():
    cam = design_camera(640, 480, horizontal_fov_deg=2 * math.degrees(math.atan(320 / 800)))
    assert cam.fx_px == pytest.approx(800.0) and cam.fy_px == cam.fx_px
    assert (cam.cx_px, cam.cy_px) == (319.5, 239.5)
    assert cam.k1 == cam.k2 == cam.p1 == cam.p2 == cam.k3 == 0 and cam.rotation_deg == (0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        design_camera(640, 480)


def test_json_round_trip():
    text = json.dumps(CAMERA.to_dict())
    doc = json.loads(text)
    assert doc["kind"] == "camera"
    back = CameraModel.from_dict(doc)
    assert back == CAMERA
    d = direction_vector(12.0, 33.0)
    np.testing.assert_array_equal(project(back, d), project(CAMERA, d))


@pytest.mark.parametrize("change, field", [
    ({"kind": "qd"}, "kind"),
    ({"fx_px": None}, "fx_px"),
    ({"k1": "0.1"}, "k1"),
    ({"p2": True}, "p2"),
    ({"cy_px": float("nan")}, "cy_px"),
    ({"width_px": -640}, "width_px"),
    ({"height_px": 480.5}, "height_px"),
    ({"rotation_deg": [0.1, 0.2]}, "rotation_deg"),
    ({"fy_px": -800.0}, "fy_px"),
])
def test_invalid_fields_raise_a_typed_error_naming_them(change, field):
    doc = {**CAMERA.to_dict(), **change}
    with pytest.raises(CalibrationFormatError, match=field):
        CameraModel.from_dict(doc)


def test_missing_field_and_non_mapping_raise_a_typed_error():
    for name in ("cx_px", "k3", "rotation_deg", "width_px"):
        doc = CAMERA.to_dict()
        del doc[name]
        with pytest.raises(CalibrationFormatError, match=f"missing field `{name}`"):
            CameraModel.from_dict(doc)
    with pytest.raises(CalibrationFormatError):
        CameraModel.from_dict([1, 2, 3])
    with pytest.raises(CalibrationFormatError, match="unknown"):
        CameraModel.from_dict({**CAMERA.to_dict(), "k4": 0.0})


def test_camera_from_document_reads_a_calibration_document_or_a_bare_model():
    document = {"format": "sunbench.calibration", "version": 1, "family": "camera", "kind": "camera",
                "method": "opencv", "model": CAMERA.to_dict(), "warnings": []}
    assert camera_from_document(document) == CAMERA == camera_from_document(CAMERA.to_dict())
    for change, words in (({"format": "other"}, "`format`"), ({"version": 2}, "version 2"),
                          ({"family": "qd"}, "`family`"), ({"model": None}, "expected a JSON object")):
        with pytest.raises(CalibrationFormatError, match=words):
            camera_from_document({**document, **change})
    with pytest.raises(CalibrationFormatError, match="missing field `model`"):
        camera_from_document({k: v for k, v in document.items() if k != "model"})
    with pytest.raises(CalibrationFormatError, match="JSON object"):
        camera_from_document("camera")
