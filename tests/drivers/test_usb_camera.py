"""The USB-camera driver, fed through OpenCV's own image-sequence capture (no camera needed)."""

import cv2
import numpy as np
import pytest

from calibration.centroid import find_spot
from drivers.errors import DeviceDisconnected, LimitError
from drivers.usb_camera import UsbCamera


def _spot_frame(x, y, shape=(120, 160), colour=False):
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    img = (200 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * 2.0**2)) + 10).astype(np.uint8)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if colour else img


@pytest.mark.parametrize("colour", [False, True])
def test_frames_come_out_grey_uint16_with_the_spot_in_place(tmp_path, colour):
    positions = [(40.0, 30.0), (80.0, 60.0), (120.0, 90.0)]
    for i, (x, y) in enumerate(positions):
        cv2.imwrite(str(tmp_path / f"frame_{i:03d}.png"), _spot_frame(x, y, colour=colour))
    camera = UsbCamera(str(tmp_path / "frame_%03d.png"), backend=cv2.CAP_IMAGES)
    assert "CV_IMAGES" in camera.identify().model
    for x, y in positions:
        frame = camera.capture()
        assert frame.dtype == np.uint16 and frame.ndim == 2
        spot = find_spot(frame)
        assert (spot.x_px, spot.y_px) == (pytest.approx(x, abs=0.05), pytest.approx(y, abs=0.05))
    with pytest.raises(DeviceDisconnected, match="no frame"):
        camera.capture()  # end of the stream, as when the camera is unplugged
    assert np.isnan(camera.temperature_c())


def test_a_missing_camera_and_a_bad_exposure(tmp_path):
    with pytest.raises(DeviceDisconnected):
        UsbCamera(str(tmp_path / "nothing_%03d.png"), backend=cv2.CAP_IMAGES)
    cv2.imwrite(str(tmp_path / "f_000.png"), _spot_frame(10, 10))
    camera = UsbCamera(str(tmp_path / "f_%03d.png"), backend=cv2.CAP_IMAGES)
    with pytest.raises(LimitError):
        camera.set_exposure_ms(-1.0)
    camera.set_exposure_ms(3.92)
    assert camera.exposure_ms() == 3.92
