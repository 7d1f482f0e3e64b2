"""The truth every simulator of one bench shares.

The world holds the clock, the bench geometry (offset zenith axis, source distance and size), the table's
axes (their true mechanical angles), the sun simulator's lamp and shutter, and the sensor under test's
true build. The sensor simulator asks it where the sun is in the sensor's body frame, so the spot in a
captured frame moves exactly as the table did — including the table's zero offsets, backlash and the
sensor's misalignment on its fixture, none of which a driver can see.

Bench geometry (seed 003 §4.1, Fig. 4.5): the sensor sits on an azimuth stage that turns it about its
boresight; that stage rides on a zenith stage whose axis is `lever_arm_mm` behind the sensor, facing a
source `source_distance_mm` away — or, with the other axis order, on an alt-az mount. The sun direction
is computed from the pose of the sensor along that chain, so for seed 003's order its zenith is eq. 8's
incidence angle.
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass, field

import numpy as np

from calibration.design import DEFAULT_BENCH, DEFAULT_SENSOR, BenchGeometry, SensorDesign
from calibration.geometry import zenith_azimuth_from_vector
from calibration.pinhole import PinholeBuild, detector_rotation
from calibration.synthetic import EXAMPLE_BUILD

from .clock import SimClock
from .lamp import XENON, LampModel, LampSpec
from .motion import AxisModel, AxisSpec


AXIS_ORDERS = ("azimuth-on-zenith", "zenith-on-azimuth")


def _rot_x(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class SensorTruth:
    """What the simulated sensor really is (never visible to drivers).

    Attributes
    ----------
    build : PinholeBuild
        Pinhole offset, air gap, cover glass, detector tilt and rotation.
    design : SensorDesign
        Detector size, pitch, bit depth.
    aperture_ellipticity : float
        Relative stretch of the spot offset with its azimuth on the detector, 1 + e cos 2(φ − φ_e): a slightly
        non-round pinhole (seed 003 §4.5) [unitless].
    aperture_axis_deg : float
        φ_e [°].
    serial : str
    """

    build: PinholeBuild = EXAMPLE_BUILD
    design: SensorDesign = DEFAULT_SENSOR
    aperture_ellipticity: float = 0.002
    aperture_axis_deg: float = 20.0
    serial: str = "SIM-0001"

    @property
    def optics(self) -> PinholeBuild:
        """The build with the non-round aperture as the pinhole model's stretch coefficients."""
        e, axis = self.aperture_ellipticity, np.radians(2.0 * self.aperture_axis_deg)
        return dataclasses.replace(self.build, aperture_c=e * np.cos(axis), aperture_s=e * np.sin(axis))


@dataclass
class SimWorld:
    """Shared truth of one simulated bench (see the module docstring).

    Attributes
    ----------
    clock : SimClock
    bench : BenchGeometry
    sensor : SensorTruth
    mount_tilt_x_deg, mount_tilt_y_deg : float
        Misalignment of the sensor on its fixture (a rigid rotation of the body frame) [°].
    azimuth_sign : float
        +1 when a positive azimuth-stage angle is a positive sun azimuth in the body frame.
    axis_order : str
        Which stage carries which: "azimuth-on-zenith" (seed 003) or "zenith-on-azimuth" (alt-az mount).
    azimuth, zenith : AxisModel or None
        The table's axes, attached by the table simulators.
    lamp : LampModel
    seed : int
        Seed of every random process of the bench (noise, hot pixels).
    """

    clock: SimClock = field(default_factory=lambda: SimClock(0.0))
    bench: BenchGeometry = DEFAULT_BENCH
    sensor: SensorTruth = field(default_factory=SensorTruth)
    mount_tilt_x_deg: float = 0.0
    mount_tilt_y_deg: float = 0.0
    azimuth_sign: float = 1.0
    axis_order: str = "azimuth-on-zenith"
    lamp_spec: LampSpec = XENON
    seed: int = 0
    azimuth: AxisModel | None = None
    zenith: AxisModel | None = None
    lamp: LampModel | None = None
    temperature_c: float = 22.0
    enclosure_open: bool = False  # back door: the enclosure door switch

    def __post_init__(self) -> None:
        if self.axis_order not in AXIS_ORDERS:
            raise ValueError(f"`axis_order` must be one of {AXIS_ORDERS}, got {self.axis_order!r}")
        if self.lamp is None:
            self.lamp = LampModel(self.lamp_spec, self.clock)

    def new_axis(self, spec: AxisSpec) -> AxisModel:
        return AxisModel(spec, self.clock)

    def attach_table(self, azimuth: AxisModel, zenith: AxisModel) -> None:
        """The table simulator(s) hand over the axes whose true angles set the sun direction."""
        self.azimuth, self.zenith = azimuth, zenith

    def stage_true_deg(self) -> tuple[float, float]:
        """True (azimuth, zenith-stage Ω) angles of the table [°]; 0, 0 when no table is attached."""
        az = self.azimuth.true_deg() if self.azimuth else 0.0
        omega = self.zenith.true_deg() if self.zenith else 0.0
        return az, omega

    def sensor_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Orientation R (columns: body axes in the lab) and position P [mm] of the sensor in the lab frame.

        Lab frame: the source lies on +z at `lever_arm_mm + source_distance_mm` from the origin, where the
        table's axes meet; at zero stage angles the sensor sits `lever_arm_mm` out along +z, facing the source.
        ``azimuth-on-zenith`` (seed 003): the zenith stage turns about lab y and carries the azimuth stage, which
        turns the sensor about its boresight. ``zenith-on-azimuth`` (an alt-az mount, seed 002): the azimuth
        axis is the lab vertical (y) and carries the altitude axis (x).
        """
        az, omega = self.stage_true_deg()
        az *= self.azimuth_sign
        if self.axis_order == "azimuth-on-zenith":
            rotation = _rot_y(-omega) @ _rot_z(-az)
            position = _rot_y(-omega) @ np.array([0.0, 0.0, self.bench.lever_arm_mm])
        else:
            rotation = _rot_y(-az) @ _rot_x(omega)
            position = rotation @ np.array([0.0, 0.0, self.bench.lever_arm_mm])
        if self.mount_tilt_x_deg or self.mount_tilt_y_deg:
            rotation = rotation @ detector_rotation(self.mount_tilt_x_deg, self.mount_tilt_y_deg, 0.0)
        return rotation, position

    def sun_direction_body(self) -> tuple[float, float]:
        """True sun direction in the sensor body frame (zenith_deg, azimuth_deg), from the table's pose.

        The direction from the sensor to the centre of the source, expressed in the body frame; for the
        seed 003 axis order its zenith is eq. 8's incidence angle and its azimuth the azimuth stage's angle.

        References
        ----------
        seed 003, eq. 8 (incidence on a bench with an offset zenith axis) and eq. 12.
        """
        rotation, position = self.sensor_pose()
        source = np.array([0.0, 0.0, self.bench.lever_arm_mm + self.bench.source_distance_mm])
        to_source = source - position
        zenith, azimuth = zenith_azimuth_from_vector(rotation.T @ (to_source / np.linalg.norm(to_source)))
        return float(zenith), float(azimuth)

    def irradiance(self) -> float:
        """Relative irradiance on the sensor (lamp output through the shutter) [unitless]."""
        return self.lamp.irradiance()

    def rng(self, stream: str) -> np.random.Generator:
        """A reproducible random generator for one named process of this bench."""
        return np.random.default_rng([self.seed, zlib.crc32(stream.encode())])
