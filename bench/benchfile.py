"""Bench files (YAML): what the bench is made of.

A bench file has four sections, all optional (``examples/bench-sim.yaml`` shows every field):

``simulation:``
    The simulated world's truth (:class:`drivers.sim.bench.SimBenchConfig`).
``devices:``
    The table, the sun simulator and the sensor: their kind, port URL, soft limits and driver options.
``geometry:``
    The bench geometry the bench *believes* (lever arm, source distance), used by seed 003 eq. 8 to turn
    stage angles into true angles in exported data.
``interlocks:``
    When a run must be suspended (sensor too hot, lamp fault).

Simulated or not. A bench is simulated when its file has a ``simulation:`` section, or when it has no
``devices:`` section at all — so ``BenchFile()`` (no file) and an empty file are a complete simulated
bench. In a simulated bench a device whose URL is omitted (or the literal ``sim``) is the simulated one;
a device given a URL is opened at that URL (a real device beside simulated ones). Without a
``simulation:`` section every device needs its URL. ``simulation: null`` says "no simulation" explicitly;
``simulation: {}`` is a simulation with every default.

The kinds follow each other: a file that names only the simulated table (``simulation.table: smc100``)
gets SMC100 devices, and a file that names only the devices' kind gets that simulator; naming both
differently is an error. The believed geometry defaults to the simulation's, else to the design defaults
(:class:`calibration.design.BenchGeometry`).

Every problem is a :class:`BenchFileError` naming the file and the dotted field.
"""

from __future__ import annotations

import hashlib
import json
import math
from typing import Annotated, Any, Literal, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from calibration.design import DEFAULT_BENCH, DEFAULT_SENSOR, BenchGeometry, SensorDesign
from drivers.earth_simulator import (
    DEFAULT_DISC_K,
    DEFAULT_RADIUS_LIMITS_DEG,
    DEFAULT_STANDBY_K,
    DEFAULT_TEMPERATURE_LIMITS_K,
)
from drivers.sim.bench import SimBenchConfig
from drivers.sim.lamp import LED
from drivers.sources import ARC_WARMUP_S, LED_WARMUP_S

from .interlocks import DEFAULT_INTERLOCKS, Interlocks
from .yamlfile import read_yaml

#: The literal URL that names the simulated device (the same as omitting the URL).
SIM_URL = "sim"
TABLE_KINDS = ("apt", "smc100", "lx200", "manual")
SOURCE_KINDS = ("xenon", "led", "earth")
SENSOR_KINDS = ("cmos", "qd", "camera", "css", "horizon")
#: The sensor kinds a simulated bench can simulate (its ``simulation.family``): every kind (the camera in-process,
#: drivers/sim/camera.py).
SIMULATED_SENSOR_KINDS = SENSOR_KINDS
# Soft limits [°] of a seed 003 run: azimuth sweeps a full turn from either side of zero, the zenith stage
# reaches past the sensor's 60° half field of view and a little below normal incidence.
DEFAULT_AZIMUTH_LIMITS_DEG = (-180.0, 360.0)
DEFAULT_ZENITH_LIMITS_DEG = (-10.0, 70.0)


class BenchFileError(Exception):
    """A bench file that cannot be used; the message names the file and the field."""


class _FieldProblems(ValueError):
    """Problems found by a validator that sees several sections; each names its own field.

    Pydantic reports a validator's error at the validator's level (the top level here), so the field is
    carried in the exception and :func:`_describe` puts it back in the message.
    """

    def __init__(self, problems: list[tuple[tuple[str, ...], str]]):
        self.problems = problems
        super().__init__("; ".join(f"{'.'.join(loc)}: {msg}" for loc, msg in problems))


# -- field types --------------------------------------------------------------------------------------------
def _check_range(value: tuple[float, float]) -> tuple[float, float]:
    low, high = value
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f"both ends must be finite, got [{low}, {high}]")
    if not low < high:
        raise ValueError(f"low must be below high, got [{low}, {high}]")
    return value


def _check_url(value: str | None) -> str | None:
    if value is None:
        return None
    value = value.strip()
    if not value:
        raise ValueError("empty URL: omit it (or write 'sim') for the simulated device")
    return None if value == SIM_URL else value  # one spelling for "simulated", so the hash does not depend on it


#: ``[low, high]``, finite, low < high (soft limits [°], exposure ranges [ms]).
Range = Annotated[tuple[float, float], AfterValidator(_check_range)]
LimitsDeg = Range
#: A port URL (``/dev/ttyUSB0``, ``socket://host:port``, ``sim://name``); None = the simulated device.
Url = Annotated[Union[str, None], AfterValidator(_check_url)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# -- table ----------------------------------------------------------------------------------------------
class _SerialAxis(_Strict):
    url: Url = None
    limits_deg: LimitsDeg
    timeout_s: float = Field(1.0, gt=0)


class AptAxisConfig(_SerialAxis):
    """One Thorlabs APT stage (K10CR1 class): its URL, soft limits [°] and controller address."""

    channel: int = Field(1, ge=1, le=4)
    dest: int = Field(0x50, ge=0, le=0x7F)  # 0x50 stand-alone USB unit (K10CR1), 0x21 a rack bay


class Smc100AxisConfig(_SerialAxis):
    """One Newport SMC100 axis: its URL, soft limits [°] and controller address (RS-485 chain)."""

    address: int = Field(1, ge=0, le=31)


class ManualAxisConfig(_Strict):
    """One stage set by hand: soft limits [°] and what its scale reads at start [°]. No URL."""

    limits_deg: LimitsDeg
    initial_deg: float = 0.0


class _TwoAxisTable(_Strict):
    """A table of two independent axes, ``azimuth:`` and ``zenith:``."""

    @model_validator(mode="before")
    @classmethod
    def _axis_limits(cls, data: Any) -> Any:
        # each axis has its own default soft limits, so the default cannot sit on the axis class
        if not isinstance(data, dict):
            return data
        data = dict(data)
        for axis, default in (("azimuth", DEFAULT_AZIMUTH_LIMITS_DEG), ("zenith", DEFAULT_ZENITH_LIMITS_DEG)):
            raw = data.get(axis)
            if raw is None:
                data[axis] = {"limits_deg": default}
            elif isinstance(raw, dict) and "limits_deg" not in raw:
                data[axis] = {**raw, "limits_deg": default}
        return data


class AptTableConfig(_TwoAxisTable):
    """Two Thorlabs APT stages (K10CR1 class)."""

    kind: Literal["apt"] = "apt"
    azimuth: AptAxisConfig
    zenith: AptAxisConfig


class Smc100TableConfig(_TwoAxisTable):
    """Two Newport SMC100 axes; two controllers chained on one RS-485 line share the URL."""

    kind: Literal["smc100"] = "smc100"
    azimuth: Smc100AxisConfig
    zenith: Smc100AxisConfig

    @model_validator(mode="after")
    def _distinct_addresses(self):
        # two controllers chained on one RS-485 line must answer to different addresses
        if self.azimuth.url is not None and self.azimuth.url == self.zenith.url \
                and self.azimuth.address == self.zenith.address:
            raise _FieldProblems([(("zenith", "address"), f"both axes are on {self.azimuth.url} at address "
                                   f"{self.zenith.address}; chained controllers need different addresses")])
        return self


class ManualTableConfig(_TwoAxisTable):
    """Two stages set by hand (the operator is asked through a callback)."""

    kind: Literal["manual"] = "manual"
    azimuth: ManualAxisConfig
    zenith: ManualAxisConfig


def _altitude_range(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] < -90.0 or value[1] > 90.0:
        raise ValueError(f"the zenith stage is the mount's altitude and must lie in [-90, 90], got {list(value)}")
    return value


class Lx200TableConfig(_Strict):
    """A Meade LX200 / Autostar alt-az mount as the two-axis table (one port for both axes)."""

    kind: Literal["lx200"] = "lx200"
    url: Url = None
    azimuth_limits_deg: LimitsDeg = DEFAULT_AZIMUTH_LIMITS_DEG
    zenith_limits_deg: Annotated[LimitsDeg, AfterValidator(_altitude_range)] = DEFAULT_ZENITH_LIMITS_DEG
    high_precision: bool | None = True  # 1″ targets; False for a mount that only takes 1′ (see drivers/meade.py)
    timeout_s: float = Field(1.0, gt=0)


TableConfig = Annotated[Union[AptTableConfig, Smc100TableConfig, Lx200TableConfig, ManualTableConfig],
                        Field(discriminator="kind")]


# -- source ---------------------------------------------------------------------------------------------
class XenonSourceConfig(_Strict):
    """A xenon arc lamp on an Oriel 69907 supply behind a Thorlabs SC10 shutter.

    `warmup_s` applies to a real lamp; a simulated one is timed by its own model (see
    :func:`bench.hardware.connect_bench`).
    """

    kind: Literal["xenon"] = "xenon"
    lamp_url: Url = None
    shutter_url: Url = None
    current_a: float | None = Field(None, gt=0)  # None keeps the supply's preset
    max_current_a: float = Field(12.0, gt=0)  # the 69907 driver refuses presets above this
    warmup_s: float = Field(ARC_WARMUP_S, ge=0)
    timeout_s: float = Field(1.0, gt=0)

    @model_validator(mode="after")
    def _current_within_limit(self):
        if self.current_a is not None and self.current_a > self.max_current_a:
            raise _FieldProblems([(("current_a",), f"{self.current_a} A is above max_current_a "
                                                   f"{self.max_current_a} A")])
        return self


class LedSourceConfig(_Strict):
    """An LED string on a SCPI bench supply in constant-current mode (the output is the shutter)."""

    kind: Literal["led"] = "led"
    url: Url = None
    current_a: float = Field(LED.nominal_current_a, gt=0)
    max_current_a: float = Field(1.0, gt=0)
    voltage_v: float | None = Field(None, gt=0)  # compliance voltage; None sends the current only
    max_voltage_v: float = Field(12.0, gt=0)
    output: str | None = None  # output name on a multi-output supply ("P6V" on an E3631A)
    warmup_s: float = Field(LED_WARMUP_S, ge=0)
    timeout_s: float = Field(1.0, gt=0)

    @model_validator(mode="after")
    def _within_limits(self):
        problems = []
        if self.current_a > self.max_current_a:
            problems.append((("current_a",), f"{self.current_a} A is above max_current_a {self.max_current_a} A"))
        if self.voltage_v is not None and self.voltage_v > self.max_voltage_v:
            problems.append((("voltage_v",), f"{self.voltage_v} V is above max_voltage_v {self.max_voltage_v} V"))
        if problems:
            raise _FieldProblems(problems)
        return self


class EarthSourceConfig(_Strict):
    """The IR Earth simulator (a heated disc behind an iris, a cold cover before it; SCPI-style line protocol,
    drivers.earth_simulator), the horizon sensor's source. The heater is its lamp, the cover its shutter."""

    kind: Literal["earth"] = "earth"
    url: Url = None
    radius_limits_deg: LimitsDeg = DEFAULT_RADIUS_LIMITS_DEG  # the iris's soft limits (disc angular radius) [°]
    temperature_limits_k: Range = DEFAULT_TEMPERATURE_LIMITS_K  # heater setpoints the bench allows [K]
    disc_temperature_k: float = Field(DEFAULT_DISC_K, gt=0)  # the disc's setpoint with the heater on [K]
    standby_temperature_k: float = Field(DEFAULT_STANDBY_K, gt=0)  # the heater's setpoint in standby [K]
    timeout_s: float = Field(1.0, gt=0)

    @model_validator(mode="after")
    def _within_limits(self):
        problems = []
        low, high = self.radius_limits_deg
        if not (0.0 < low and high < 90.0):
            problems.append((("radius_limits_deg",), f"a disc's angular radius lies within (0, 90)°, got "
                                                     f"[{low}, {high}]"))
        low, high = self.temperature_limits_k
        for name in ("disc_temperature_k", "standby_temperature_k"):
            value = getattr(self, name)
            if not low <= value <= high:
                problems.append(((name,), f"{value} K is outside temperature_limits_k [{low}, {high}] K"))
        if problems:
            raise _FieldProblems(problems)
        return self


SourceConfig = Annotated[Union[XenonSourceConfig, LedSourceConfig, EarthSourceConfig], Field(discriminator="kind")]


# -- sensor ---------------------------------------------------------------------------------------------
def _positive_range(value: tuple[float, float]) -> tuple[float, float]:
    if not value[0] > 0:
        raise ValueError(f"exposures must be positive, got {list(value)}")
    return value


class SensorDesignConfig(_Strict):
    """The detector's design (calibration.design.SensorDesign): its pitch sets the fitted gap and glass."""

    width_px: int = Field(DEFAULT_SENSOR.width_px, ge=8, le=100_000)
    height_px: int = Field(DEFAULT_SENSOR.height_px, ge=8, le=100_000)
    pixel_pitch_mm: float = Field(DEFAULT_SENSOR.pixel_pitch_mm, gt=0, le=1.0)
    pinhole_height_mm: float = Field(DEFAULT_SENSOR.pinhole_height_mm, gt=0, le=100.0)

    def sensor_design(self) -> SensorDesign:
        return SensorDesign(**{**DEFAULT_SENSOR.to_dict(), **self.model_dump()})


class CmosSensorConfig(_Strict):
    """The CMOS pinhole sun-sensor module (framed binary protocol, RS-485)."""

    kind: Literal["cmos"] = "cmos"
    url: Url = None
    exposure_range_ms: Annotated[Range, AfterValidator(_positive_range)] = (0.01, 1000.0)
    timeout_s: float = Field(1.0, gt=0)
    frame_timeout_s: float = Field(5.0, gt=0)  # must cover the longest exposure plus the transfer
    design: SensorDesignConfig | None = None  # the detector's design, for the fits (default: seed 003's)


class CameraSensorConfig(_Strict):
    """A camera opened by OpenCV: device index, device path, video file or image-sequence pattern; on a simulated
    bench, no source (or ``sim``) is the simulated camera (``simulation.camera``, in-process: drivers/sim/camera.py)."""

    kind: Literal["camera"] = "camera"
    source: int | str | None = None
    exposure_ms: float | None = Field(None, gt=0)

    @field_validator("source")
    @classmethod
    def _source(cls, value):
        if isinstance(value, str):
            value = value.strip()
            if not value:
                raise ValueError("empty source: omit it (or write 'sim') for the simulated camera")
            if value == SIM_URL:
                return None  # one spelling for "simulated", as for a URL
        return value


class QdSensorConfig(_Strict):
    """The quadrant-photodiode sun-sensor module of seed 002 (framed binary protocol, drivers.qd_protocol)."""

    kind: Literal["qd"] = "qd"
    url: Url = None
    timeout_s: float = Field(1.0, gt=0)


class CssSensorConfig(_Strict):
    """The coarse-sun-sensor head of seed 000 (18 channels: UV, visible and IR detectors on a cube's six faces;
    framed binary protocol, drivers.css_protocol)."""

    kind: Literal["css"] = "css"
    url: Url = None
    timeout_s: float = Field(1.0, gt=0)


class HorizonSensorConfig(_Strict):
    """The scanning Earth-horizon sensor of seed 004 (dual-cone scanner: crossing times per revolution; framed binary
    protocol, drivers.horizon_protocol). It faces an Earth simulator (``devices.source.kind: earth``)."""

    kind: Literal["horizon"] = "horizon"
    url: Url = None
    timeout_s: float = Field(1.0, gt=0)


SensorConfig = Annotated[Union[CmosSensorConfig, CameraSensorConfig, QdSensorConfig, CssSensorConfig,
                               HorizonSensorConfig], Field(discriminator="kind")]


class DevicesConfig(_Strict):
    """The bench's devices (the ``devices:`` section). A missing ``kind`` is apt, xenon, cmos, or what the
    ``simulation:`` section names."""

    table: TableConfig = AptTableConfig()
    source: SourceConfig = XenonSourceConfig()
    sensor: SensorConfig = CmosSensorConfig()

    @model_validator(mode="before")
    @classmethod
    def _default_kinds(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        data = dict(data)
        sensor = data.get("sensor")
        # a horizon sensor's source is the Earth simulator unless the file says otherwise
        source_kind = "earth" if isinstance(sensor, dict) and sensor.get("kind") == "horizon" else "xenon"
        if source_kind == "earth" and data.get("source") is None:
            data["source"] = {}
        for role, kind in (("table", "apt"), ("source", source_kind), ("sensor", "cmos")):
            raw = data.get(role)
            if raw is None and role in data:
                data[role] = {"kind": kind}  # a bare `table:` in YAML is an empty section
            elif isinstance(raw, dict) and "kind" not in raw:
                data[role] = {**raw, "kind": kind}
        return data


# -- geometry and interlocks ----------------------------------------------------------------------------
class GeometryConfig(_Strict):
    """The bench geometry the bench believes (seed 003 eq. 8), not the simulated truth.

    The schema of the fields of :class:`calibration.design.BenchGeometry` a bench file states (their
    defaults and checks are the value type's); :meth:`bench_geometry` builds the value."""

    lever_arm_mm: float = Field(DEFAULT_BENCH.lever_arm_mm, ge=0)
    source_distance_mm: float = Field(DEFAULT_BENCH.source_distance_mm, gt=0)
    # 1σ of the two lengths as measured; the fit at a run's end combines them with what the spots say
    lever_arm_sd_mm: float | None = Field(DEFAULT_BENCH.lever_arm_sd_mm, gt=0)
    source_distance_sd_mm: float | None = Field(DEFAULT_BENCH.source_distance_sd_mm, gt=0)

    @model_validator(mode="after")
    def _physical(self):
        self.bench_geometry()  # the value type's own checks, at load time
        return self

    def bench_geometry(self, source_diameter_deg: float = DEFAULT_BENCH.source_diameter_deg) -> BenchGeometry:
        """The believed geometry as :class:`calibration.design.BenchGeometry`; the source's size is not part of
        the belief (eq. 8 does not use it), so it is given."""
        return BenchGeometry(**self.model_dump(), source_diameter_deg=source_diameter_deg)


class InterlocksConfig(_Strict):
    """Conditions that suspend a run: the bench file's part of :class:`bench.interlocks.Interlocks`, which
    :meth:`interlocks` builds."""

    sensor_max_temperature_c: float = Field(DEFAULT_INTERLOCKS.sensor_max_temperature_c, allow_inf_nan=False)
    lamp_fault: bool = DEFAULT_INTERLOCKS.lamp_fault  # a lamp fault suspends the run

    def interlocks(self, *, enclosure_open=None, poll_s: float = DEFAULT_INTERLOCKS.poll_s,
                   hold_off_s: float = DEFAULT_INTERLOCKS.hold_off_s) -> Interlocks:
        """The engine's interlocks: this section's limits with the bench's door switch (``enclosure_open()``,
        None when it has none) and how often and how long a suspended run looks at them [s]
        (:data:`bench.interlocks.SIMULATED_TIMING` on a simulated bench)."""
        return Interlocks(**self.model_dump(), enclosure_open=enclosure_open, poll_s=poll_s, hold_off_s=hold_off_s)


# -- the file -------------------------------------------------------------------------------------------
def _section(data: dict, key: str) -> Any:
    """A section as a fresh dict (a bare ``key:`` in YAML is an empty section); other values unchanged."""
    value = data.get(key)
    if value is None:
        return {}
    if isinstance(value, BaseModel):  # a section handed over already validated
        return value.model_dump()
    return dict(value) if isinstance(value, dict) else value


class BenchFile(_Strict):
    """A whole bench file (see the module docstring).

    Attributes
    ----------
    simulation : SimBenchConfig or None
        The simulated world, or None for a bench of real devices only.
    devices : DevicesConfig
    geometry : GeometryConfig
    interlocks : InterlocksConfig
    """

    simulation: SimBenchConfig | None = None
    devices: DevicesConfig = DevicesConfig()
    geometry: GeometryConfig = GeometryConfig()
    interlocks: InterlocksConfig = InterlocksConfig()

    @model_validator(mode="before")
    @classmethod
    def _resolve_defaults(cls, data: Any) -> Any:
        """Fill what depends on another section: the simulation itself, the kinds, the believed geometry."""
        if not isinstance(data, dict):
            return data
        data = dict(data)
        if "simulation" not in data and data.get("devices") is None:
            data["simulation"] = {}  # nothing says which devices: the default simulated bench
        if data.get("simulation") is None:
            return data
        sim, devices = _section(data, "simulation"), _section(data, "devices")
        if not (isinstance(sim, dict) and isinstance(devices, dict)):
            return data  # the validation proper names the bad section
        sensor = devices.get("sensor")
        source = devices.get("source")
        if "source" not in sim and not (isinstance(source, dict) and "kind" in source) and (
                sim.get("family") == "horizon" or isinstance(sensor, dict) and sensor.get("kind") == "horizon"):
            sim["source"] = "earth"  # a horizon bench's source is the Earth simulator unless the file says otherwise
        if "family" not in sim and not (isinstance(sensor, dict) and "kind" in sensor) and (
                sim.get("source") == "earth" or isinstance(source, dict) and source.get("kind") == "earth"):
            sim["family"] = "horizon"  # and an Earth simulator's sensor is the horizon sensor
        # each simulated kind follows the device's, and the other way round (the sensor's: the simulated family)
        for role, sim_key, kinds in (("table", "table", TABLE_KINDS[:3]), ("source", "source", SOURCE_KINDS),
                                     ("sensor", "family", SIMULATED_SENSOR_KINDS)):
            device = devices.get(role)
            device = {} if device is None else device
            if not isinstance(device, dict):
                continue
            if "kind" not in device and sim.get(sim_key) in kinds:
                devices[role] = {**device, "kind": sim[sim_key]}
            elif sim_key not in sim and device.get("kind") in kinds:
                sim[sim_key] = device["kind"]
        data["simulation"], data["devices"] = sim, devices
        try:
            truth = SimBenchConfig.model_validate(sim)
        except ValidationError:
            return data  # reported by the validation proper
        geometry = _section(data, "geometry")
        if isinstance(geometry, dict):
            # what the bench believes defaults to the simulated truth
            geometry.setdefault("lever_arm_mm", truth.geometry.lever_arm_mm)
            geometry.setdefault("source_distance_mm", truth.geometry.source_distance_mm)
            data["geometry"] = geometry
        return data

    @model_validator(mode="after")
    def _check_consistency(self):
        problems: list[tuple[tuple[str, ...], str]] = []
        table, source = self.devices.table, self.devices.source
        if (self.devices.sensor.kind == "horizon") != (source.kind == "earth"):
            problems.append((("devices", "source", "kind"),
                             f"{source.kind!r} with a {self.devices.sensor.kind!r} sensor: the horizon sensor faces an "
                             "Earth simulator (sensor kind horizon with source kind earth), and only it does"))
        if self.simulation is not None:
            if table.kind == "manual":
                problems.append((("devices", "table", "kind"),
                                 "a manual table cannot be simulated: choose apt, smc100 or lx200, "
                                 "or remove the simulation: section"))
            elif table.kind != self.simulation.table:
                problems.append((("devices", "table", "kind"), f"{table.kind!r} does not match simulation.table "
                                                               f"{self.simulation.table!r}"))
            sensor = self.devices.sensor
            if sensor.kind in SIMULATED_SENSOR_KINDS and sensor.kind != self.simulation.family:
                problems.append((("devices", "sensor", "kind"), f"{sensor.kind!r} does not match simulation.family "
                                                                f"{self.simulation.family!r} (the simulated sensor; "
                                                                "a simulated bench simulates its own sensor's kind)"))
            if source.kind != self.simulation.source:
                problems.append((("devices", "source", "kind"), f"{source.kind!r} does not match simulation.source "
                                                                f"{self.simulation.source!r}"))
        else:
            missing = [loc for loc, url in self._urls() if url is None]
            for i, loc in enumerate(missing):
                # the hint once: a bare `simulation:` in YAML is null, which means "no simulation"
                hint = (" ('sim' or no URL needs a simulation: section; a bare `simulation:` counts as none, "
                        "`simulation: {}` is the default one)") if i == 0 else ""
                what = "a source (an OpenCV device index, path or file)" if loc[-1] == "source" else "a URL"
                problems.append((loc, f"{what} is needed: the file has no simulation{hint}"))
        if problems:
            raise _FieldProblems(problems)
        return self

    def _urls(self) -> list[tuple[tuple[str, ...], str | None]]:
        """(field, URL) of every device that is opened by URL."""
        out = []
        table = self.devices.table
        if table.kind == "lx200":
            out.append((("devices", "table", "url"), table.url))
        elif table.kind in ("apt", "smc100"):
            out += [(("devices", "table", axis, "url"), getattr(table, axis).url) for axis in ("azimuth", "zenith")]
        source = self.devices.source
        if source.kind == "xenon":
            out += [(("devices", "source", "lamp_url"), source.lamp_url),
                    (("devices", "source", "shutter_url"), source.shutter_url)]
        else:
            out.append((("devices", "source", "url"), source.url))
        if self.devices.sensor.kind in ("cmos", "qd", "css", "horizon"):
            out.append((("devices", "sensor", "url"), self.devices.sensor.url))
        else:
            out.append((("devices", "sensor", "source"), self.devices.sensor.source))
        return out

    def bench_geometry(self) -> BenchGeometry:
        """The geometry the bench believes, as :class:`calibration.design.BenchGeometry` (seed 003 eq. 8).

        The source diameter is not part of the belief (eq. 8 does not use it): the simulation's when
        simulated, else the design default.
        """
        if self.simulation is None:
            return self.geometry.bench_geometry()
        return self.geometry.bench_geometry(self.simulation.geometry.source_diameter_deg)

    @property
    def simulated(self) -> bool:
        """True when the file has a simulation (some devices may still be real, given by URL)."""
        return self.simulation is not None

    def canonical_json(self) -> str:
        """The validated file as canonical JSON: sorted keys, no spaces, every default spelled out."""
        return json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"), ensure_ascii=False)

    def config_hash(self) -> str:
        """SHA-256 (hex) of :meth:`canonical_json`, for run provenance: equal benches hash equal however
        their files are written (order, comments, defaults left out, ``url: sim`` or no URL)."""
        return hashlib.sha256(self.canonical_json().encode("utf-8")).hexdigest()


# -- reading --------------------------------------------------------------------------------------------
_UNION_TAGS = {"table": TABLE_KINDS, "source": SOURCE_KINDS, "sensor": SENSOR_KINDS}


def _field(loc) -> str:
    """Dotted field name, without the kind tags pydantic inserts for a tagged union."""
    parts = []
    for i, part in enumerate(loc):
        if i >= 2 and loc[i - 2] == "devices" and part in _UNION_TAGS.get(loc[i - 1], ()):
            continue
        parts.append(str(part))
    return ".".join(parts) or "(top level)"


def _describe(exc: ValidationError) -> list[str]:
    """One ``field a.b.c: message`` per problem."""
    out = []
    for error in exc.errors():
        loc, msg = tuple(error["loc"]), error["msg"]
        cause = (error.get("ctx") or {}).get("error")
        if isinstance(cause, _FieldProblems):
            out += [f"field {_field(loc + sub)}: {text}" for sub, text in cause.problems]
            continue
        if error["type"] == "union_tag_invalid":
            loc += ("kind",)  # the kind is what is wrong, not the whole section
            ctx = error.get("ctx") or {}
            msg = f"{ctx.get('tag')!r} is not a known kind (expected one of {ctx.get('expected_tags')})"
        msg = msg.removeprefix("Value error, ")
        out.append(f"field {_field(loc)}: {msg}")
    return out


def parse_bench_file(document: Any, source: str = "<bench file>") -> BenchFile:
    """Validate a bench file already read (a mapping, or None for an empty file).

    Parameters
    ----------
    document : dict or None
        The YAML document.
    source : str
        Name of the file in error messages.

    Raises
    ------
    BenchFileError
        Naming `source` and every bad field.
    """
    document = {} if document is None else document
    if not isinstance(document, dict):
        raise BenchFileError(f"{source}: expected a mapping at the top level")
    try:
        return BenchFile.model_validate(document)
    except ValidationError as exc:
        raise BenchFileError(f"{source}: {'; '.join(_describe(exc))}") from None


def load_bench_file(path) -> BenchFile:
    """Read and validate a bench YAML file.

    Raises
    ------
    BenchFileError
        Missing file, not YAML, or invalid content; the message names the file and the field.
    """
    return parse_bench_file(read_yaml(path, BenchFileError), str(path))
