"""The truth every simulator of one bench shares.

The world holds the clock, the bench geometry (offset zenith axis, source distance and size), the table's
axes (their true mechanical angles), the sun simulator's lamp and shutter, and the sensor under test's
true build. The sensor simulator asks it where the sun is in the sensor's body frame, so the spot in a
captured frame moves exactly as the table did — including the table's zero offsets, backlash and the
sensor's misalignment on its fixture, none of which a driver can see.

Bench geometry (seed 003 §4.1, Fig. 4.5): the sensor sits on an azimuth stage that turns it about its
boresight; that stage rides on a zenith stage whose axis is `lever_arm_mm` behind the sensor, facing a
source `source_distance_mm` away. The incidence angle follows seed 003 eq. 8; the sun lies in the zenith
stage's plane of rotation, which the azimuth stage turns in the sensor frame.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from calibration.design import DEFAULT_BENCH, DEFAULT_SENSOR, BenchGeometry, SensorDesign
from calibration.geometry import direction_vector, incidence_from_stage_angle, zenith_azimuth_from_vector
from calibration.pinhole import PinholeBuild, detector_rotation
from calibration.synthetic import EXAMPLE_BUILD

from .clock import SimClock
from .lamp import XENON, LampModel, LampSpec
from .motion import AxisModel, AxisSpec


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
        Relative stretch of the spot offset with azimuth, 1 + e cos 2(φ − φ_e): a slightly non-round pinhole
        (seed 003 §4.5) [unitless].
    aperture_axis_deg : float
        φ_e [°].
    serial : str
    """

    build: PinholeBuild = EXAMPLE_BUILD
    design: SensorDesign = DEFAULT_SENSOR
    aperture_ellipticity: float = 0.0002
    aperture_axis_deg: float = 20.0
    serial: str = "SIM-0001"


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
    lamp_spec: LampSpec = XENON
    seed: int = 0
    azimuth: AxisModel | None = None
    zenith: AxisModel | None = None
    lamp: LampModel | None = None
    temperature_c: float = 22.0

    def __post_init__(self) -> None:
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

    def sun_direction_body(self) -> tuple[float, float]:
        """True sun direction in the sensor body frame (zenith_deg, azimuth_deg), from the table's pose.

        References
        ----------
        seed 003, eq. 8 (incidence on a bench with an offset zenith axis) and eq. 12.
        """
        az, omega = self.stage_true_deg()
        theta = float(incidence_from_stage_angle(omega, self.bench.lever_arm_mm, self.bench.source_distance_mm))
        phi = (0.0 if theta >= 0 else 180.0) + self.azimuth_sign * az
        s = direction_vector(abs(theta), phi)
        if self.mount_tilt_x_deg or self.mount_tilt_y_deg:
            s = s @ detector_rotation(self.mount_tilt_x_deg, self.mount_tilt_y_deg, 0.0)
        zenith, azimuth = zenith_azimuth_from_vector(s)
        return float(zenith), float(azimuth)

    def irradiance(self) -> float:
        """Relative irradiance on the sensor (lamp output through the shutter) [unitless]."""
        return self.lamp.irradiance()

    def rng(self, stream: str) -> np.random.Generator:
        """A reproducible random generator for one named process of this bench."""
        return np.random.default_rng([self.seed, zlib.crc32(stream.encode())])
