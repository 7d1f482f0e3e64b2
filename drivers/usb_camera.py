"""A USB camera as a sun sensor (seed 001 used a webcam), through OpenCV's VideoCapture, behind the same
:class:`~drivers.interfaces.ImageSensor` interface as the CMOS module.

The source is whatever VideoCapture opens: a device index (``0``), a device path (``/dev/video0``), a video
file or an image sequence (``frames/img_%04d.png``, which is how the tests feed it). Colour frames are
converted to grey; frames come out as uint16 so the centroid code sees one type.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .errors import DeviceDisconnected, DeviceError, LimitError
from .interfaces import ImageSensor, SensorIdentity


class UsbCamera(ImageSensor):
    """A camera opened with ``cv2.VideoCapture``.

    Parameters
    ----------
    source : int or str
        Device index, device path, video file or image-sequence pattern.
    exposure_ms : float, optional
        Exposure to request at opening [ms]; whether the camera honours it depends on its backend.
    backend : int
        OpenCV capture API (``cv2.CAP_ANY`` lets OpenCV choose; ``cv2.CAP_IMAGES`` for image sequences).
    """

    def __init__(self, source, *, exposure_ms: float | None = None, backend: int = cv2.CAP_ANY,
                 name: str | None = None):
        self.source = source
        self.name = name or f"camera:{source}"
        self._capture = cv2.VideoCapture(source, backend)
        if not self._capture.isOpened():
            raise DeviceDisconnected(self.name, "VideoCapture could not open the source")
        self._exposure_ms = float("nan")
        if exposure_ms is not None:
            self.set_exposure_ms(exposure_ms)

    def identify(self) -> SensorIdentity:
        backend = self._capture.getBackendName() if self._capture.isOpened() else "closed"
        return SensorIdentity(model=f"OpenCV {backend} camera", serial=str(self.source), firmware=cv2.__version__)

    def set_exposure_ms(self, exposure_ms: float) -> None:
        """Ask for an exposure [ms]. Backends differ in units (V4L2: 100 µs steps); this sends V4L2 units
        and keeps the request, so :meth:`exposure_ms` says what was asked, not what the camera did."""
        if not exposure_ms > 0:
            raise LimitError(self.name, f"exposure must be positive, got {exposure_ms} ms")
        self._capture.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1)  # manual exposure (V4L2 convention)
        self._capture.set(cv2.CAP_PROP_EXPOSURE, exposure_ms * 10.0)
        self._exposure_ms = float(exposure_ms)

    def exposure_ms(self) -> float:
        return self._exposure_ms

    def capture(self) -> np.ndarray:
        if not self._capture.isOpened():
            raise DeviceDisconnected(self.name, "camera is closed")
        ok, frame = self._capture.read()
        if not ok or frame is None:
            raise DeviceDisconnected(self.name, "no frame (camera unplugged or end of stream)")
        if frame.ndim == 3:
            frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        if frame.dtype == np.uint8 or frame.dtype == np.uint16:
            return frame.astype(np.uint16, copy=False)
        raise DeviceError(self.name, f"unsupported frame type {frame.dtype}")

    def temperature_c(self) -> float:
        """Cameras report no temperature: NaN."""
        return math.nan

    def close(self) -> None:
        self._capture.release()
