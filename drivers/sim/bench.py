"""A whole simulated bench: one world, a table, a sun simulator and the sensor, served by URL.

`SimBenchConfig` is the ``simulation:`` section of a bench YAML file (``examples/bench-sim.yaml``): the
world's truth — the table's mechanics and zero offsets, the bench geometry, the source, the sensor's build
errors and its misalignment on the fixture. :class:`SimBench` builds the simulators from it and serves them
in-process (``sim://`` URLs) or over TCP (``socket://`` URLs, ``sunbench sim``).
"""

from __future__ import annotations

import itertools
from functools import cached_property
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from calibration.design import DEFAULT_BENCH, DEFAULT_SENSOR, BenchGeometry, SensorDesign

from . import registry
from .backdoor import BenchFaults
from .camera import CameraSimConfig, CameraTruth, SimulatedCamera, camera_fleet_truth
from .clock import SimClock
from .css_head import CssHeadConfig, css_fleet_truth
from .css_optics import CssTruth
from .earth_simulator import KELVIN, EarthSimulatorConfig, EarthSimulatorModel
from .horizon_optics import HorizonTruth
from .horizon_sensor import HorizonSensorConfig, horizon_fleet_truth
from .lamp import LED, XENON
from .motion import AxisSpec
from .qd_optics import QdTruth, qd_fleet_truth
from .qd_sensor import QdSensorConfig
from .raytrace import SensorOptics
from .world import SensorTruth, SimWorld, fleet_sensor


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class AxisConfig(_Strict):
    """Mechanics of one simulated axis (see :class:`drivers.sim.motion.AxisSpec`)."""

    max_rate_deg_s: float = Field(10.0, gt=0)
    accel_deg_s2: float = Field(20.0, gt=0)
    settle_s: float = Field(0.05, ge=0)
    backlash_deg: float = Field(0.0, ge=0)
    step_deg: float = Field(3.0 / 409600.0, gt=0)
    hard_limits_deg: tuple[float, float] | None = None
    home_switch_true_deg: float = 0.003  # the table's zero offset after homing
    home_rate_deg_s: float = Field(5.0, gt=0)
    start_true_deg: float = 0.0

    def spec(self) -> AxisSpec:
        return AxisSpec(**self.model_dump())


class GeometryConfig(_Strict):
    """The true bench geometry (:class:`calibration.design.BenchGeometry`, built by :meth:`bench_geometry`).

    The source sits 710 cm away (seed 003 §4.1, where a 0.5° source is ~62 mm across) rather than the
    design default's 710 mm: with eq. 8's 710 mm a 60° stage angle would put the sun at 68.6°, outside the
    sensor's field of view."""

    lever_arm_mm: float = Field(DEFAULT_BENCH.lever_arm_mm, ge=0)
    source_distance_mm: float = Field(7100.0, gt=0)
    source_diameter_deg: float = Field(DEFAULT_BENCH.source_diameter_deg, gt=0, lt=10)

    @model_validator(mode="after")
    def _physical(self):
        self.bench_geometry()  # the value type's own checks, at load time
        return self

    def bench_geometry(self) -> BenchGeometry:
        """The simulated world's geometry."""
        return BenchGeometry(**self.model_dump())


class BuildConfig(_Strict):
    """The sensor's true build (:class:`drivers.sim.raytrace.SensorOptics`): what a calibration should recover.

    The gap is the air path along the die's normal from the pinhole (the mid-plane of its mask) to the glass,
    so gap + glass is the pinhole's height above the die wherever the glass lies."""

    x0_px: float = 325.8
    y0_px: float = 233.4
    gap_mm: float = Field(1.05, gt=0)
    glass_mm: float = Field(0.5, ge=0)
    glass_index: float = Field(1.52, ge=1)
    glass_position: Literal["die", "mask"] = "die"  # cover glass on the die, or bonded under the mask
    tilt_x_deg: float = 0.22
    tilt_y_deg: float = -0.21
    rotation_deg: float = 1.4
    mirrored: bool = False
    mask_thickness_mm: float = Field(0.01, ge=0)  # the hole is a short cylinder; 0 = a thin mask
    wavelength_mm: float = Field(0.00065, ge=0)  # effective wavelength of the diffraction blur; 0 = none


class DetectorConfig(_Strict):
    """The detector (:class:`calibration.design.SensorDesign`): 640×480 px of 9.9 µm by default (seed 003)."""

    width_px: int = Field(DEFAULT_SENSOR.width_px, gt=0)
    height_px: int = Field(DEFAULT_SENSOR.height_px, gt=0)
    pixel_pitch_mm: float = Field(DEFAULT_SENSOR.pixel_pitch_mm, gt=0)
    bit_depth: int = Field(DEFAULT_SENSOR.bit_depth, gt=0, le=16)


class SensorConfig(_Strict):
    serial: str = "SIM-0001"
    build: BuildConfig = BuildConfig()
    detector: DetectorConfig = DetectorConfig()
    hole_diameter_mm: float = Field(DEFAULT_SENSOR.hole_diameter_mm, gt=0)
    aperture_ellipticity: float = Field(0.002, ge=0, lt=0.1)  # the hole's long axis is 1 + e times its short one
    aperture_axis_deg: float = 20.0

    @model_validator(mode="after")
    def _physical(self):
        self.truth()  # the optics' own checks (a hole that ends in air above the glass, ...) at load time
        return self

    def truth(self) -> SensorTruth:
        """The simulated sensor this section describes."""
        design = SensorDesign(**self.detector.model_dump(), hole_diameter_mm=self.hole_diameter_mm)
        return SensorTruth(build=SensorOptics(**self.build.model_dump()), design=design, serial=self.serial,
                           aperture_ellipticity=self.aperture_ellipticity, aperture_axis_deg=self.aperture_axis_deg)


class MountConfig(_Strict):
    """The sensor's misalignment on its fixture: seed 003 measured a 0.47° non-parallelism between the sensor
    and simulator planes (§4.5), which the default reproduces."""

    tilt_x_deg: float = 0.33
    tilt_y_deg: float = -0.33


class Lx200SimConfig(_Strict):
    """The simulated LX200 mount's site, clock and client compatibility (:mod:`drivers.sim.lx200`).

    `indi_compatible` answers ``:MA#``, ``:Sa`` and ``:h?#`` as INDI's LX200 drivers expect instead of as the
    Meade manual says (the conflicts are listed in :mod:`drivers.sim.lx200`). The site defaults to seed 003's
    NSU (Novosibirsk); the longitude is east positive, `utc_offset_h` in Meade's sign (hours added to local
    time to give UTC: −7 for UTC+7)."""

    indi_compatible: bool = False
    latitude_deg: float = Field(54.85, ge=-90, le=90)
    longitude_deg: float = Field(83.1, ge=-180, le=180)
    utc_offset_h: float = Field(-7.0, ge=-24, le=24)


class SimBenchConfig(_Strict):
    """The simulated bench (the ``simulation:`` section of a bench file)."""

    time_scale: float = Field(1.0, ge=0)
    seed: int = 0
    # the sensor under test: CMOS pinhole (seed 003), QD (seed 002), camera (seed 001), CSS head (seed 000) or
    # scanning Earth-horizon sensor (seed 004, in front of the IR Earth simulator: source earth)
    family: Literal["cmos", "qd", "camera", "css", "horizon"] = "cmos"
    table: Literal["apt", "lx200", "smc100"] = "apt"
    axis_order: Literal["azimuth-on-zenith", "zenith-on-azimuth"] = "azimuth-on-zenith"
    source: Literal["xenon", "led", "earth"] = "xenon"
    geometry: GeometryConfig = GeometryConfig()
    sensor: SensorConfig = SensorConfig()
    qd: QdSensorConfig = QdSensorConfig()  # the QD module, used when `family` is qd
    camera: CameraSimConfig = CameraSimConfig()  # the camera sun sensor, used when `family` is camera
    css: CssHeadConfig = CssHeadConfig()  # the coarse-sun-sensor head, used when `family` is css
    horizon: HorizonSensorConfig = HorizonSensorConfig()  # the horizon sensor, used when `family` is horizon
    earth: EarthSimulatorConfig = EarthSimulatorConfig()  # the IR Earth simulator, used when `source` is earth
    mount: MountConfig = MountConfig()
    azimuth_axis: AxisConfig = AxisConfig()
    zenith_axis: AxisConfig = AxisConfig(hard_limits_deg=(-95.0, 95.0))  # the defaults are examples/bench-sim.yaml
    lx200: Lx200SimConfig = Lx200SimConfig()  # used when `table` is lx200
    temperature_c: float = 22.0

    @model_validator(mode="before")
    @classmethod
    def _earth_follows_horizon(cls, data):
        # a horizon bench's source is the Earth simulator, and the other way round, unless the file says otherwise
        if isinstance(data, dict):
            if data.get("family") == "horizon" and "source" not in data:
                data = {**data, "source": "earth"}
            elif data.get("source") == "earth" and "family" not in data:
                data = {**data, "family": "horizon"}
        return data

    @model_validator(mode="after")
    def _earth_goes_with_horizon(self):
        # the horizon sensor sees only an Earth simulator, and an Earth simulator lights no sun sensor
        if (self.family == "horizon") != (self.source == "earth"):
            raise ValueError(f"family {self.family!r} with source {self.source!r}: the horizon sensor faces the "
                             "Earth simulator (family: horizon with source: earth), and only it does")
        return self


_prefixes = itertools.count()


class SimBench:
    """The simulators of one bench, built from a :class:`SimBenchConfig`.

    Attributes
    ----------
    world : SimWorld
    devices : dict of str to SimDevice
        By role: ``table`` (LX200) or ``table-azimuth`` and ``table-zenith`` (APT, SMC100), ``lamp`` and
        ``shutter`` (xenon), ``led`` (LED) or ``earth`` (the IR Earth simulator's controller), ``sensor`` (a CMOS
        or QD module, a CSS head, a horizon sensor): the devices served on a wire.
    camera : SimulatedCamera or None
        The camera sun sensor of a camera bench (``family: camera``): an in-process
        :class:`~drivers.interfaces.ImageSensor`, not served on a wire (:mod:`drivers.sim.camera` says why);
        the bench takes it as it is (:mod:`bench.hardware`).
    """

    def __init__(self, config: SimBenchConfig | None = None, *, time_scale: float | None = None):
        self.config = config = config or SimBenchConfig()
        clock = SimClock(config.time_scale if time_scale is None else time_scale)
        truth = config.sensor.truth()
        self.world = SimWorld(clock=clock, bench=config.geometry.bench_geometry(), sensor=truth,
                              mount_tilt_x_deg=config.mount.tilt_x_deg, mount_tilt_y_deg=config.mount.tilt_y_deg,
                              lamp_spec=XENON if config.source == "xenon" else LED, seed=config.seed,
                              temperature_c=config.temperature_c, axis_order=config.axis_order)
        self.camera = SimulatedCamera(self.world, config.camera.truth()) if config.family == "camera" else None
        #: the IR Earth simulator's instrument (source earth): its controller serves it, the horizon sensor faces it
        self.earth = EarthSimulatorModel(config.earth, clock, lambda: self.world.temperature_c + KELVIN) \
            if config.source == "earth" else None
        self.devices = {**self._table(), **self._source(), **self._sensor()}
        self._registered: list[str] = []

    # -- what the bench layer may ask of a simulated bench (never its world's internals) --------------------
    @property
    def clock(self) -> SimClock:
        """The simulated clock every model of this bench runs on (``clock.now()`` [s])."""
        return self.world.clock

    @property
    def time_scale(self) -> float:
        """Simulated seconds per wall second; 0 is instant."""
        return self.world.clock.time_scale

    def enclosure_open(self) -> bool:
        """The enclosure's door switch: True while the door is open (:attr:`faults` opens it)."""
        return self.world.enclosure_open

    @property
    def lamp_warm_time_s(self) -> float:
        """The simulated lamp's own warm-up time, in simulated time [s] (the Earth simulator's: its disc settling
        from the room to its power-up setpoint)."""
        if self.earth is not None:
            return self.config.earth.settle_time_s(self.config.earth.setpoint_k - self.config.temperature_c - KELVIN)
        return self.world.lamp.spec.warm_time_s

    @property
    def sensor_design(self) -> SensorDesign:
        """The design of the sensor on the bench (detector size, pitch, bit depth)."""
        return self.world.sensor.design

    @property
    def axis_order(self) -> str:
        """Which stage carries which: "azimuth-on-zenith" (seed 003) or "zenith-on-azimuth" (alt-az mount)."""
        return self.world.axis_order

    @cached_property
    def faults(self) -> BenchFaults:
        """The back door: faults no wire protocol can cause, and named set-ups
        (:class:`drivers.sim.backdoor.BenchFaults`)."""
        return BenchFaults(self.world, normal_temperature_c=self.config.temperature_c, earth=self.earth)

    def setup(self, name: str) -> None:
        """Put the bench in a named set-up (:data:`drivers.sim.backdoor.SETUPS`: ``normal``, ``lamp_fault`` …)."""
        self.faults.setup(name)

    def mount_sensor(self, serial: str) -> SensorTruth | QdTruth | CameraTruth | CssTruth | HorizonTruth:
        """Put the sensor of serial `serial` on the bench (what the operator does between the sensors of a
        fleet): the configured sensor for its own serial, any other built from its serial around it
        (:func:`~drivers.sim.world.fleet_sensor`; a QD module: :func:`~drivers.sim.qd_optics.qd_fleet_truth`,
        mounted on the QD simulator, powered up fresh; a camera: :func:`~drivers.sim.camera.camera_fleet_truth`;
        a CSS head: :func:`~drivers.sim.css_head.css_fleet_truth`, mounted on the head's simulator, powered up
        fresh; a horizon sensor: :func:`~drivers.sim.horizon_sensor.horizon_fleet_truth`, likewise). The module then
        identifies itself with that serial."""
        if self.camera is not None:
            truth = camera_fleet_truth(self.config.camera.truth(), serial)
            self.camera.mount(truth)
            return truth
        if self.config.family == "qd":
            truth = qd_fleet_truth(self.config.qd.truth(), serial)
            self.devices["sensor"].mount(truth)
            return truth
        if self.config.family == "css":
            head = css_fleet_truth(self.config.css, serial)
            self.devices["sensor"].mount(head)
            return head
        if self.config.family == "horizon":
            sensor = horizon_fleet_truth(self.config.horizon, serial)
            self.devices["sensor"].mount(sensor)
            return sensor
        self.world.sensor = fleet_sensor(self.config.sensor.truth(), serial)
        return self.world.sensor

    def _table(self) -> dict:
        az, zen = self.config.azimuth_axis.spec(), self.config.zenith_axis.spec()
        if self.config.table == "lx200":
            from .lx200 import LX200Simulator
            return {"table": LX200Simulator(self.world, az, zen, **self.config.lx200.model_dump())}
        if self.config.table == "apt":
            from .thorlabs_apt import AptStageSimulator
            a = AptStageSimulator(self.world, az, 55000001)
            z = AptStageSimulator(self.world, zen, 55000002)
        else:
            from .newport_smc100 import Smc100Simulator
            a, z = Smc100Simulator(self.world, az), Smc100Simulator(self.world, zen)
        self.world.attach_table(a.axis, z.axis)
        return {"table-azimuth": a, "table-zenith": z}

    def _source(self) -> dict:
        if self.config.source == "earth":
            from .earth_simulator import EarthSimulatorSimulator
            return {"earth": EarthSimulatorSimulator(self.earth, seed=self.config.seed)}
        if self.config.source == "xenon":
            from .oriel69907 import Oriel69907Simulator
            from .shutter import ShutterSimulator
            return {"lamp": Oriel69907Simulator(self.world), "shutter": ShutterSimulator(self.world)}
        from .scpi_supply import ScpiSupplySimulator
        return {"led": ScpiSupplySimulator(self.world)}

    def _sensor(self) -> dict:
        if self.config.family == "camera":
            return {}  # the camera is in-process only (`camera`): no wire to serve
        if self.config.family == "qd":
            from .qd_sensor import QdSensorSimulator
            return {"sensor": QdSensorSimulator(self.world, self.config.qd)}
        if self.config.family == "css":
            from .css_head import CssHeadSimulator
            return {"sensor": CssHeadSimulator(self.world, self.config.css)}
        if self.config.family == "horizon":
            from .horizon_sensor import HorizonSensorSimulator
            return {"sensor": HorizonSensorSimulator(self.world, self.config.horizon, self.earth)}
        from .cmos_sensor import CmosSensorSimulator
        return {"sensor": CmosSensorSimulator(self.world)}

    def register(self, prefix: str | None = None) -> dict[str, str]:
        """Serve every device in-process; returns role → ``sim://`` URL (unique names per bench)."""
        prefix = prefix or f"bench{next(_prefixes)}"
        urls = {}
        for role, device in self.devices.items():
            name = f"{prefix}-{role}"
            urls[role] = registry.register(name, device)
            self._registered.append(name)
        return urls

    def unregister(self) -> None:
        for name in self._registered:
            registry.unregister(name)
        self._registered.clear()

    def serve(self, *, host: str = "127.0.0.1", base_port: int = 0):
        """Serve every device over TCP; returns the started :class:`~drivers.sim.tcp.SimServer`."""
        from .tcp import SimServer
        server = SimServer(self.devices, host=host, base_port=base_port)
        server.start()
        return server
