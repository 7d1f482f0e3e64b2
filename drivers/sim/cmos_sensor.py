"""Protocol front of the simulated CMOS pinhole sun-sensor module (wire format: drivers.cmos_protocol).

A capture takes the exposure plus the read-out in simulated time: its reply is held back until then (at
time scale 0 the clock jumps there at once). The on-board centroid runs the same seed 003 algorithm as
the library (calibration.centroid.find_spot), as the module's firmware does. Back door: the WireFaults
of every simulator, `corrupt_crc` (the next replies carry a wrong CRC) and the world's temperature.
"""

from __future__ import annotations

import numpy as np

from calibration.centroid import CentroidError, MultipleSpotsError, NoSpotError, SaturatedSpotError, find_spot

from .. import cmos_protocol as wire
from ..framed_protocol import FramedResponder
from .device import SimDevice
from .sensor_optics import DetectorSpec, SpotRenderer
from .world import SimWorld

MODEL = "SB-CMOS-PINHOLE"
FIRMWARE = "1.0.0"
EXPOSURE_RANGE_US = (10, 1_000_000)
LINE_TIME_US = 10  # exposure is set in whole lines


class CmosSensorSimulator(FramedResponder, SimDevice):
    """The CMOS module on the simulated bench (its frame loop: :class:`drivers.framed_protocol.FramedResponder`)."""

    name = "cmos-sensor"
    frame_format = wire.FORMAT

    def __init__(self, world: SimWorld, detector: DetectorSpec = DetectorSpec()):
        super().__init__()
        self.world = world
        self.renderer = SpotRenderer(world, detector)
        self.exposure_us = 4000
        self.frames = 0

    # -- commands --------------------------------------------------------------------------------------
    def _commands(self):
        return {wire.IDENTIFY: self._identify, wire.SET_EXPOSURE: self._set_exposure,
                wire.GET_EXPOSURE: self._get_exposure, wire.CAPTURE: self._capture, wire.CENTROID: self._centroid,
                wire.TEMPERATURE: self._temperature}

    def _identify(self, frame):
        design = self.world.sensor.design
        payload = wire.IDENTITY.pack(wire.pad(MODEL, 16), wire.pad(self.world.sensor.serial, 16), wire.pad(FIRMWARE, 8),
                                     design.width_px, design.height_px, design.bit_depth)
        return self._reply(frame.code, frame.sequence, payload)

    def _set_exposure(self, frame):
        if len(frame.payload) != wire.EXPOSURE.size:
            return self._error(frame.sequence, wire.BAD_LENGTH, "SET_EXPOSURE takes a u32")
        (us,) = wire.EXPOSURE.unpack(frame.payload)
        if not EXPOSURE_RANGE_US[0] <= us <= EXPOSURE_RANGE_US[1]:
            return self._error(frame.sequence, wire.OUT_OF_RANGE, f"exposure {us} us outside {EXPOSURE_RANGE_US}")
        self.exposure_us = max(LINE_TIME_US, round(us / LINE_TIME_US) * LINE_TIME_US)
        return self._reply(frame.code, frame.sequence, wire.EXPOSURE.pack(self.exposure_us))

    def _get_exposure(self, frame):
        return self._reply(frame.code, frame.sequence, wire.EXPOSURE.pack(self.exposure_us))

    def _expose(self) -> np.ndarray:
        """Expose: the light integrates over the exposure (rendered at its middle) and the read-out follows."""
        exposure_ms = self.exposure_us / 1000.0
        image = self.renderer.render(exposure_ms)
        self.frames += 1
        return image

    def _hold(self, reply: bytes) -> bytes:
        """`reply` once the exposure and the read-out are over."""
        return self._hold_until(
            self.world.clock.now() + (self.exposure_us / 1000.0 + self.renderer.spec.readout_ms) / 1000.0, reply)

    def _capture(self, frame):
        packing = frame.payload[0] if frame.payload else wire.RAW16
        if packing not in (wire.RAW16, wire.PACKED10):
            return self._error(frame.sequence, wire.OUT_OF_RANGE, f"packing {packing}")
        image = self._expose()
        h, w = image.shape
        pixels = image.astype("<u2").tobytes() if packing == wire.RAW16 else wire.pack10(image)
        header = wire.FRAME_HEADER.pack(w, h, self.world.sensor.design.bit_depth, packing, self.exposure_us,
                                        self.renderer.counter)
        return self._hold(self._reply(frame.code, frame.sequence, header + pixels))

    def _centroid(self, frame):
        image = self._expose()
        status, x, y, peak, n = 0, float("nan"), float("nan"), 0, 0
        try:
            spot = find_spot(image, saturation_dn=self.world.sensor.design.saturation_dn)
            x, y, peak, n = spot.x_px, spot.y_px, int(min(spot.peak_dn, 65535)), min(spot.n_pixels, 65535)
        except NoSpotError:
            status = 1
        except SaturatedSpotError:
            status = 2
        except MultipleSpotsError:
            status = 3
        except CentroidError:
            status = 1
        payload = wire.CENTROID_REPLY.pack(x, y, peak, n, status, self.exposure_us)
        return self._hold(self._reply(frame.code, frame.sequence, payload))

    def _temperature(self, frame):
        payload = wire.TEMPERATURE_REPLY.pack(wire.centi(self.world.temperature_c))
        return self._reply(frame.code, frame.sequence, payload)
