"""Driver of the CMOS pinhole sun-sensor module (seed 003), over the framed protocol of
:mod:`drivers.cmos_protocol`.

Replies are checked, and a bad exchange is raised as a typed error and asked again, by
:class:`~drivers.framed_protocol.FramedModule`: every command of this module is safe to repeat (the queries;
SET_EXPOSURE sets an absolute value, not a step; CAPTURE and CENTROID take a fresh exposure, and the frame whose
reply was lost is never used). An error frame from the module is a :class:`SensorError` with its code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import cmos_protocol as wire
from .errors import LimitError
from .framed_protocol import FramedModule, ModuleError
from .interfaces import ImageSensor, SensorIdentity
from .transport import DEFAULT_RETRIES, Port


class SensorError(ModuleError):
    """The module answered with an error frame; `code` is its error code."""


@dataclass(frozen=True)
class OnboardCentroid:
    """The module's own centroid (its firmware runs seed 003 §3.3).

    Attributes
    ----------
    x_px, y_px : float
        Spot centre [px]; NaN unless `status` is "ok".
    peak_dn : int
    n_pixels : int
    status : str
        "ok", "no spot", "saturated spot" or "several spots".
    exposure_ms : float
    """

    x_px: float
    y_px: float
    peak_dn: int
    n_pixels: int
    status: str
    exposure_ms: float


class CmosSunSensor(FramedModule, ImageSensor):
    """The CMOS pinhole sun-sensor module.

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=921600)`` (RS-485 adapter, or a simulator URL).
    exposure_range_ms : (float, float)
        Exposures the module accepts [ms]; requests outside are refused before sending.
    packing : int
        Pixel packing requested for frames (:data:`~drivers.cmos_protocol.PACKED10` halves the transfer).
    frame_timeout_s : float
        Timeout of a capture reply [s]; it must cover the exposure and the transfer.
    retries : int
        How many times a command is sent again after a garbled, cut or missing reply (default 3,
        :data:`~drivers.transport.DEFAULT_RETRIES`); a dead module is reported after ``retries + 1`` timeouts.

    Attributes
    ----------
    retry_count : int
        Commands sent again so far: how noisy the link is.
    """

    reports_serial = True  # IDENTIFY answers the module's own serial
    frame_format = wire.FORMAT
    module_error = SensorError

    def __init__(self, port: Port, *, exposure_range_ms=(0.01, 1000.0), packing: int = wire.PACKED10,
                 frame_timeout_s: float = 5.0, retries: int = DEFAULT_RETRIES, name: str | None = None):
        self._attach(port, retries=retries, name=name)
        self.exposure_range_ms = exposure_range_ms
        self.packing = packing
        self.frame_timeout_s = frame_timeout_s
        self._identity: SensorIdentity | None = None
        self._shape: tuple[int, int] | None = None

    # -- the interface ----------------------------------------------------------------------------------
    def identify(self) -> SensorIdentity:
        model, serial, firmware, width, height, bits = self._unpack(wire.IDENTITY, self._exchange(wire.IDENTIFY),
                                                                    "IDENTIFY")
        self._identity = SensorIdentity(wire.unpad(model), wire.unpad(serial), wire.unpad(firmware))
        self._shape = (height, width)
        self.bit_depth = bits
        return self._identity

    def set_exposure_ms(self, exposure_ms: float) -> float:
        """Set the exposure [ms]; returns what the module set (it rounds to its line time)."""
        low, high = self.exposure_range_ms
        if not low <= exposure_ms <= high:
            raise LimitError(self.name, f"exposure {exposure_ms} ms is outside [{low}, {high}] ms")
        (us,) = self._unpack(wire.EXPOSURE,
                             self._exchange(wire.SET_EXPOSURE, wire.EXPOSURE.pack(round(exposure_ms * 1000))),
                             "SET_EXPOSURE")
        return us / 1000.0

    def exposure_ms(self) -> float:
        (us,) = self._unpack(wire.EXPOSURE, self._exchange(wire.GET_EXPOSURE), "GET_EXPOSURE")
        return us / 1000.0

    def capture(self) -> np.ndarray:
        """Expose and transfer one frame: 2-D uint16 [DN]."""
        frame, _ = self.capture_with_metadata()
        return frame

    def capture_with_metadata(self) -> tuple[np.ndarray, dict]:
        payload = self._exchange(wire.CAPTURE, bytes([self.packing]), timeout_s=self.frame_timeout_s)
        if len(payload) < wire.FRAME_HEADER.size:
            self._fail("CAPTURE reply too short", payload[:64])
        width, height, bits, packing, exposure_us, counter = wire.FRAME_HEADER.unpack_from(payload)
        pixels = payload[wire.FRAME_HEADER.size:]
        count = width * height
        expected = count * 2 if packing == wire.RAW16 else count * 5 // 4
        if packing not in (wire.RAW16, wire.PACKED10) or len(pixels) != expected:
            self._fail(f"frame of {width}×{height} with packing {packing} has {len(pixels)} pixel bytes", payload[:64])
        if packing == wire.RAW16:
            image = np.frombuffer(pixels, dtype="<u2").astype(np.uint16).reshape(height, width)
        else:
            image = wire.unpack10(pixels, count).reshape(height, width)
        return image, {"exposure_ms": exposure_us / 1000.0, "frame_counter": counter, "bit_depth": bits}

    def onboard_centroid(self) -> OnboardCentroid:
        x, y, peak, n, status, exposure_us = self._unpack(wire.CENTROID_REPLY, self._exchange(
            wire.CENTROID, timeout_s=self.frame_timeout_s), "CENTROID")
        return OnboardCentroid(float(x), float(y), int(peak), int(n),
                               wire.CENTROID_STATUS.get(status, f"status {status}"), exposure_us / 1000.0)

    def temperature_c(self) -> float:
        (centi,) = self._unpack(wire.TEMPERATURE_REPLY, self._exchange(wire.TEMPERATURE), "TEMPERATURE")
        return centi / 100.0
