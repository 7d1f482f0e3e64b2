"""The truth every simulator of one bench shares.

The world holds the clock, the bench geometry (offset zenith axis, source distance and size), the table's
axes (their true mechanical angles), the sun simulator's lamp and shutter, and the sensor under test's
true build (whose physics is the simulator's own, :mod:`drivers.sim.raytrace`, not the calibration's model).
The sensor simulator asks it where the sun is in the sensor's body frame, so the spot in a captured frame
moves exactly as the table did — including the table's zero offsets, backlash and the sensor's
misalignment on its fixture, none of which a driver can see.

Bench geometry (seed 003 §4.1, Fig. 4.5): the sensor sits on an azimuth stage that turns it about its
boresight; that stage rides on a zenith stage whose axis is `lever_arm_mm` behind the sensor, facing a
source `source_distance_mm` away — or, with the other axis order, on an alt-az mount. The sun direction
is computed from the pose of the sensor along that chain (:func:`drivers.sim.raytrace.body_direction_from_stage`),
so for seed 003's order its zenith is eq. 8's incidence angle.
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from calibration.design import DEFAULT_BENCH, DEFAULT_SENSOR, BenchGeometry, SensorDesign

from .clock import SimClock
from .lamp import XENON, LampModel, LampSpec
from .motion import AxisModel, AxisSpec
from .raytrace import AXIS_ORDERS, SensorOptics, body_direction_from_stage, stage_pose

#: The default simulated sensor's build: realistic errors a calibration should recover (a cover glass on the
#: die under a 1.05 mm air gap, the die tilted 0.3° and turned 1.4°, a 10 µm mask) and a 650 nm effective
#: wavelength for the diffraction blur (a xenon arc seen by silicon).
EXAMPLE_OPTICS = SensorOptics(x0_px=325.8, y0_px=233.4, gap_mm=1.05, glass_mm=0.5, glass_index=1.52,
                              tilt_x_deg=0.22, tilt_y_deg=-0.21, rotation_deg=1.4, mask_thickness_mm=0.01,
                              wavelength_mm=0.00065)


@dataclass(frozen=True)
class SensorTruth:
    """What the simulated sensor really is (never visible to drivers).

    Attributes
    ----------
    build : SensorOptics
        Pinhole offset, air gap, cover glass and where it lies, die tilt and rotation, mask thickness; its
        detector and hole fields are taken from `design` and the two aperture fields (see :attr:`optics`).
    design : SensorDesign
        Detector size, pitch, bit depth, hole diameter.
    aperture_ellipticity : float
        A slightly non-round pinhole (seed 003 §4.5): its long axis is 1 + e times its short one [unitless].
    aperture_axis_deg : float
        Direction of the long axis in the mask plane, from body +x [°].
    serial : str
    """

    build: SensorOptics = EXAMPLE_OPTICS
    design: SensorDesign = DEFAULT_SENSOR
    aperture_ellipticity: float = 0.002
    aperture_axis_deg: float = 20.0
    serial: str = "SIM-0001"

    @cached_property
    def optics(self) -> SensorOptics:
        """The whole optics the ray trace needs: the build with the design's detector and hole."""
        d = self.design
        return dataclasses.replace(self.build, pixel_pitch_mm=d.pixel_pitch_mm, width_px=d.width_px,
                                   height_px=d.height_px, hole_diameter_mm=d.hole_diameter_mm,
                                   hole_axis_ratio=1.0 + self.aperture_ellipticity,
                                   hole_axis_deg=self.aperture_axis_deg)


def fleet_sensor(base: SensorTruth, serial: str) -> SensorTruth:
    """The simulated sensor of serial `serial`: `base` itself for its own serial, any other a flight sensor of
    the same design with its own build errors drawn around `base` from the serial alone.

    A serial's build depends on nothing else (not on the sensors mounted before it), so a fleet resumed in
    another process measures the same sensor. Draws are clipped at 3σ and the air gap kept above half the
    mask, so every serial is a sensor the ray trace accepts.
    """
    if serial == base.serial:
        return base
    rng = np.random.default_rng(zlib.crc32(serial.encode()))
    draw = lambda sd: float(np.clip(rng.normal(0.0, 1.0), -3.0, 3.0)) * sd  # noqa: E731
    b = base.build
    build = dataclasses.replace(
        b, x0_px=b.x0_px + draw(6.0), y0_px=b.y0_px + draw(6.0),
        gap_mm=max(b.gap_mm + draw(0.03), (b.gap_mm + b.mask_thickness_mm / 2) / 2),
        glass_mm=max(b.glass_mm + draw(0.03), 0.0), tilt_x_deg=draw(0.2), tilt_y_deg=draw(0.2),
        rotation_deg=draw(1.5))
    return dataclasses.replace(base, build=build, serial=serial,
                               aperture_ellipticity=abs(base.aperture_ellipticity * (1 + draw(0.3))))


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
        """Orientation R (columns: body axes in the lab) and position P [mm] of the sensor in the lab frame
        (:func:`drivers.sim.raytrace.stage_pose` at the table's true angles)."""
        az, omega = self.stage_true_deg()
        return stage_pose(az, omega, lever_arm_mm=self.bench.lever_arm_mm, axis_order=self.axis_order,
                          mount_tilt_x_deg=self.mount_tilt_x_deg, mount_tilt_y_deg=self.mount_tilt_y_deg,
                          azimuth_sign=self.azimuth_sign)

    def sun_direction_body(self) -> tuple[float, float]:
        """True sun direction in the sensor body frame (zenith_deg, azimuth_deg), from the table's pose.

        The direction from the sensor to the centre of the source, expressed in the body frame
        (:func:`drivers.sim.raytrace.body_direction_from_stage` at the table's true angles); for the seed 003
        axis order its zenith is eq. 8's incidence angle and its azimuth the azimuth stage's angle.

        References
        ----------
        seed 003, eq. 8 (incidence on a bench with an offset zenith axis) and eq. 12.
        """
        az, omega = self.stage_true_deg()
        zenith, azimuth = body_direction_from_stage(
            az, omega, lever_arm_mm=self.bench.lever_arm_mm, source_distance_mm=self.bench.source_distance_mm,
            axis_order=self.axis_order, mount_tilt_x_deg=self.mount_tilt_x_deg,
            mount_tilt_y_deg=self.mount_tilt_y_deg, azimuth_sign=self.azimuth_sign)
        return float(zenith), float(azimuth)

    def irradiance(self) -> float:
        """Relative irradiance on the sensor (lamp output through the shutter) [unitless]."""
        return self.lamp.irradiance()

    def occlusion(self) -> tuple[float, float, float] | None:
        """A cloud's edge across the source (offset, direction [°], transmission), as
        :func:`drivers.sim.raytrace.spot_patch` takes it; the lab's source has none (a field world does)."""
        return None

    def rng(self, stream: str) -> np.random.Generator:
        """A reproducible random generator for one named process of this bench."""
        return np.random.default_rng([self.seed, zlib.crc32(stream.encode())])
