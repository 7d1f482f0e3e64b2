"""The simulated camera sun sensor (seed 001): a webcam looking at the sun simulator, or at the Sun outdoors.

:class:`SimulatedCamera` is an :class:`~drivers.interfaces.ImageSensor` like the real camera's driver
(:class:`drivers.usb_camera.UsbCamera`): it identifies itself, takes an exposure in the range and the steps a
UVC webcam has (V4L2's ``exposure_time_absolute``, 100 µs units, 1…5000), and answers grey frames as 2-D uint16
arrays of 8-bit values (what ``UsbCamera.capture`` returns of a webcam). Its frames are rendered by the
simulator's own optics (:class:`drivers.sim.camera_optics.CameraRenderer`: a lens whose distortion is a polynomial
in the field angle, a tilted detector, a rotated mount; never the calibration's OpenCV model) from the shared world:
the source's direction in the sensor's body frame (:meth:`~drivers.sim.world.SimWorld.sun_direction_body`, so the
spot moves exactly as the table did), its brightness (:meth:`~drivers.sim.world.SimWorld.irradiance`: the lamp
through the shutter, or the Sun through the haze), the clouds in front of it (a field world's
``clouds()``; the lab has none) and the source's size (``world.bench.source_diameter_deg``: the bench's 0.5° sun
simulator, the Sun's 0.533° outdoors). A capture takes the exposure and a frame's read-out in simulated time
(the world is seen at the exposure's middle): at time scale 0 the clock jumps, otherwise the call sleeps the
wall time that is.

Why in-process, not on a wire. Every other simulator of the bench serves its device's own bytes (``sim://``,
``socket://``), so the real driver is tested on it. A USB camera's wire is UVC, which the kernel's V4L2 driver
speaks and OpenCV's ``VideoCapture`` reads through ``/dev/videoN``; the project has no protocol of its own there
(tests/test_conventions.py: ``usb_camera.py`` is not a wire driver). A user-space simulator cannot sit on that
wire without a kernel module (v4l2loopback) that makes a fake ``/dev/videoN``, which a test machine cannot be
assumed to have. So the simulated camera is handed to the bench directly (:mod:`bench.hardware`), behind the same
interface; and the real driver is tested on the simulator's frames another way: written as a PNG image sequence
and read back through ``UsbCamera`` with OpenCV's ``CAP_IMAGES`` (tests/drivers/test_sim_camera.py).

Truth: :class:`CameraSimConfig` is the ``simulation.camera`` section of a bench file (the lens, the detector, the
serial); any other serial of a fleet is a camera of the same design whose build errors are drawn from its serial
alone (:func:`camera_fleet_truth`). Back door: ``faults.disconnected`` (a pulled USB cable: a capture raises
:class:`~drivers.errors.DeviceDisconnected`), as a wire simulator's :class:`~drivers.sim.device.WireFaults`.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
import zlib
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import DeviceDisconnected, LimitError
from ..interfaces import ImageSensor, SensorIdentity
from .camera_optics import DEFAULT_LENS, CameraDetector, CameraLens, CameraRenderer
from .device import WireFaults
from .sky import CLEAR, CloudState

MODEL = "SB-SIM-WEBCAM"
FIRMWARE = "1.0.0"
#: V4L2's exposure_time_absolute unit [ms] (100 µs) and a common UVC webcam's range of it (1…5000 units) [ms].
EXPOSURE_STEP_MS = 0.1
EXPOSURE_RANGE_MS = (0.1, 500.0)
#: A frame's read-out after the exposure: one frame period at 30 frames per second [ms].
READOUT_MS = 1000.0 / 30.0

_L, _D = DEFAULT_LENS, CameraDetector()


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CameraLensConfig(_Strict):
    """The simulated camera's true optics and mounting (:class:`drivers.sim.camera_optics.CameraLens`, same fields,
    same defaults): what a calibration should represent."""

    focal_mm: float = Field(_L.focal_mm, gt=0)
    pixel_pitch_mm: float = Field(_L.pixel_pitch_mm, gt=0)
    distortion_a: float = _L.distortion_a
    distortion_b: float = _L.distortion_b
    principal_x_px: float = _L.principal_x_px
    principal_y_px: float = _L.principal_y_px
    detector_tilt_x_deg: float = Field(_L.detector_tilt_x_deg, ge=-10, le=10)
    detector_tilt_y_deg: float = Field(_L.detector_tilt_y_deg, ge=-10, le=10)
    mount_tilt_x_deg: float = Field(_L.mount_tilt_x_deg, ge=-20, le=20)
    mount_tilt_y_deg: float = Field(_L.mount_tilt_y_deg, ge=-20, le=20)
    mount_twist_deg: float = Field(_L.mount_twist_deg, ge=-180, le=180)
    psf_sigma_px: float = Field(_L.psf_sigma_px, ge=0, le=10)


class CameraDetectorConfig(_Strict):
    """The simulated webcam's detector and electronics (:class:`drivers.sim.camera_optics.CameraDetector`)."""

    width_px: int = Field(_D.width_px, ge=16, le=8192)
    height_px: int = Field(_D.height_px, ge=16, le=8192)
    bias_dn: float = Field(_D.bias_dn, ge=0)
    read_noise_dn: float = Field(_D.read_noise_dn, ge=0)
    electrons_per_dn: float = Field(_D.electrons_per_dn, gt=0)
    full_well_e: float = Field(_D.full_well_e, gt=0)
    signal_dn_per_ms: float = Field(_D.signal_dn_per_ms, gt=0)
    full_scale_dn: int = Field(_D.full_scale_dn, ge=1, le=255)  # an 8-bit webcam
    bloom: bool = _D.bloom
    pool_size: int = Field(_D.pool_size, ge=1, le=64)


@dataclass(frozen=True)
class CameraTruth:
    """What the simulated camera really is (never visible to the bench)."""

    lens: CameraLens = DEFAULT_LENS
    detector: CameraDetector = CameraDetector()
    serial: str = "CAM-0001"


class CameraSimConfig(_Strict):
    """The simulated camera sun sensor (the ``simulation.camera`` section of a bench file, used when
    ``simulation.family`` is camera): its serial, lens and detector."""

    serial: str = Field("CAM-0001", min_length=1, max_length=64)
    lens: CameraLensConfig = CameraLensConfig()
    detector: CameraDetectorConfig = CameraDetectorConfig()

    @model_validator(mode="after")
    def _physical(self):
        self.truth()  # the optics' own checks (a distortion that folds the image back) at load time
        return self

    def truth(self) -> CameraTruth:
        """The simulated camera this section describes."""
        return CameraTruth(lens=CameraLens(**self.lens.model_dump()),
                           detector=CameraDetector(**self.detector.model_dump()), serial=self.serial)


def camera_fleet_truth(base: CameraTruth, serial: str) -> CameraTruth:
    """The simulated camera of serial `serial`: `base` itself for its own serial, any other a camera of the same
    design with its own build errors drawn around `base` from the serial alone (reproducible in any process,
    whatever was mounted before): focal length ±0.5 %, principal point ±3 px, distortion ±0.01 (a) and ±0.005 (b),
    detector tilt ±0.2°, mounting ±0.3° and twist ±0.5° (1σ, clipped at 3σ)."""
    if serial == base.serial:
        return base
    rng = np.random.default_rng([zlib.crc32(serial.encode()), zlib.crc32(b"camera-build")])

    def draw(sd: float) -> float:
        return float(np.clip(rng.normal(0.0, 1.0), -3.0, 3.0)) * sd

    lens = base.lens
    lens = dataclasses.replace(
        lens, focal_mm=lens.focal_mm * (1.0 + draw(0.005)), principal_x_px=lens.principal_x_px + draw(3.0),
        principal_y_px=lens.principal_y_px + draw(3.0), distortion_a=lens.distortion_a + draw(0.01),
        distortion_b=lens.distortion_b + draw(0.005), detector_tilt_x_deg=draw(0.2), detector_tilt_y_deg=draw(0.2),
        mount_tilt_x_deg=draw(0.3), mount_tilt_y_deg=draw(0.3), mount_twist_deg=draw(0.5))
    return dataclasses.replace(base, lens=lens, serial=serial)


def _unit_vector(zenith_deg: float, azimuth_deg: float) -> np.ndarray:
    """n = (sin θ cos φ, sin θ sin φ, cos θ) [unitless]."""
    t, p = math.radians(zenith_deg), math.radians(azimuth_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


class SimulatedCamera(ImageSensor):
    """The camera sun sensor on a simulated bench or field (module docstring).

    Parameters
    ----------
    world : SimWorld
        The shared truth: clock, the source's direction and brightness (and, outdoors, the clouds).
    truth : CameraTruth
        The camera's lens, detector and serial.
    """

    name = "simulated-camera"
    #: A UVC camera's USB serial number: the bench checks it is the sensor the run is labelled with
    reports_serial = True

    def __init__(self, world, truth: CameraTruth = CameraTruth()):
        self.world = world
        self.faults = WireFaults()  # `disconnected`: the USB cable pulled
        self.frames = 0
        self._lock = threading.Lock()
        self._exposure_ms = 4.0
        self.mount(truth)

    def mount(self, truth: CameraTruth) -> None:
        """Put the camera `truth` on the bench (a fleet's next sensor): its own renderer and noise stream."""
        with self._lock:
            self.truth = truth
            self.renderer = CameraRenderer(truth.lens, truth.detector, rng=self.world.rng(f"camera:{truth.serial}"),
                                           source_diameter_deg=self.world.bench.source_diameter_deg)

    # -- the ImageSensor interface ----------------------------------------------------------------------
    def identify(self) -> SensorIdentity:
        self._check_plugged()
        d = self.truth.detector
        return SensorIdentity(model=f"{MODEL} {d.width_px}x{d.height_px}", serial=self.truth.serial,
                              firmware=FIRMWARE)

    def set_exposure_ms(self, exposure_ms: float) -> float:
        """Set the exposure [ms] as a webcam does: in whole 100 µs steps, clamped to its range; answers the exposure
        set. A non-positive or non-finite request is refused (:class:`~drivers.errors.LimitError`)."""
        if not (isinstance(exposure_ms, (int, float)) and math.isfinite(exposure_ms) and exposure_ms > 0):
            raise LimitError(self.name, f"exposure must be a positive number of ms, got {exposure_ms!r}")
        self._check_plugged()
        low, high = EXPOSURE_RANGE_MS
        steps = round(min(max(float(exposure_ms), low), high) / EXPOSURE_STEP_MS)
        self._exposure_ms = round(steps * EXPOSURE_STEP_MS, 6)
        return self._exposure_ms

    def exposure_ms(self) -> float:
        return self._exposure_ms

    def capture(self) -> np.ndarray:
        """One grey frame, 2-D uint16 of 8-bit values [DN]: the exposure, then the read-out, in simulated time."""
        with self._lock:
            self._check_plugged()
            exposure = self._exposure_ms
            self._wait(exposure / 2000.0)  # the world as it is at the exposure's middle
            zenith, azimuth = self.world.sun_direction_body()
            frame = self.renderer.render(_unit_vector(zenith, azimuth), exposure_ms=exposure,
                                         irradiance=max(float(self.world.irradiance()), 0.0), clouds=self._clouds())
            self._wait((exposure / 2.0 + READOUT_MS) / 1000.0)
            self.frames += 1
            return frame.astype(np.uint16)

    def temperature_c(self) -> float:
        """A webcam reports no temperature (as :class:`drivers.usb_camera.UsbCamera`): NaN."""
        return math.nan

    def close(self) -> None:
        """Nothing to release (the real driver releases its capture)."""

    # -- for the simulation's own use (tests, the back door) --------------------------------------------
    @property
    def full_scale_dn(self) -> int:
        """The detector's largest value [DN] (8 bits)."""
        return int(self.truth.detector.full_scale_dn)

    def true_pixel(self) -> tuple[float, float] | None:
        """Where the image of the source's centre lands now [px] (the truth; None off the detector)."""
        return self.renderer.true_pixel(_unit_vector(*self.world.sun_direction_body()))

    def _clouds(self) -> CloudState:
        clouds = getattr(self.world, "clouds", None)  # a field world's sky; the lab's source has none
        return clouds() if callable(clouds) else CLEAR

    def _check_plugged(self) -> None:
        if self.faults.disconnected:
            raise DeviceDisconnected(self.name, "no frame (camera unplugged)")

    def _wait(self, dt_s: float) -> None:
        """Let `dt_s` of simulated time pass: the clock jumps at time scale 0, else the wall time that takes."""
        clock = self.world.clock
        if clock.instant:
            clock.advance(dt_s)
        else:
            time.sleep(dt_s / clock.time_scale)
