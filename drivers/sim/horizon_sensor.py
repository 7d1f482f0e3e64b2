"""Protocol front of the simulated scanning Earth-horizon sensor module (wire format: :mod:`drivers.horizon_protocol`;
physics: :mod:`drivers.sim.horizon_optics`, its own — nothing of calibration/).

The module on the table looks at the bench's Earth simulator (:class:`~drivers.sim.earth_simulator.
EarthSimulatorModel`): the table's true pose (the world's :meth:`~drivers.sim.world.SimWorld.sensor_pose`, the
fixture's mount tilts included) places the scan cones in the lab, the Earth simulator's sphere is centred on the
sensor's nominal point (the bench's `lever_arm_mm` out along lab +z from the axes) with radius `source_distance_mm`,
its iris sets the disc's true radius, its heater the disc's temperature and its cover whether the disc is in view.
At the table's zero the disc's centre lies along body +z (Z_s, nadir).

Each revolution the module samples both cones' detectors `samples_per_revolution` times (on the rotor's encoder) and
runs its locator. Timing on the world's clock: the rotor turns from power-up with the nominal period, each
revolution's own period jittered by `period_jitter` (relative rms); a READ_SCANS waits for the next index mark and
the n revolutions after it, and its reply is held back until then (at time scale 0 the clock jumps there at once);
meanwhile every command gets error 5 (not ready). The scene is taken when the request arrives (a bench reads with
the table at rest); each revolution draws its own noise and period.

Back door (lewis style, never reachable over the wire): :attr:`faults` (the :class:`~drivers.sim.device.WireFaults`
of every simulator), :attr:`corrupt_crc`, :meth:`stall_motor` (no index mark: READ_SCANS answers error 6 after two
nominal periods), :meth:`kill_detector` (a cone's bolometer is open: its pulse is the pedestal and noise, no edges),
:meth:`blind` (a hot source on the Earth simulator's sphere, e.g. the Sun or a lamp in the scan: it saturates the
pulse), :meth:`clear_faults`, and :meth:`mount` (another sensor on the fixture).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from .. import horizon_protocol as wire
from ..framed_protocol import FramedResponder
from .device import SimDevice
from .earth_simulator import KELVIN, EarthSimulatorConfig, EarthSimulatorModel
from .horizon_optics import (
    CONE_SIGNS,
    Edges,
    HorizonTruth,
    Revolution,
    Scene,
    band_radiance,
    detector_lag,
    draw_build,
    fleet_seed,
    ifov_radiance,
    locate_edges,
    scan_directions,
)
from .world import SimWorld

MODEL = "SB-HORIZON-DCS"
FIRMWARE = "1.0.0"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class HorizonBuildConfig(_Strict):
    """The configured sensor's true build: what a bench calibration should recover."""

    gamma_1_deg: float = Field(70.023, gt=30, lt=89)  # cone 1's true half-angle [°]
    gamma_2_deg: float = Field(69.981, gt=30, lt=89)
    phase_offset_1_deg: float = Field(0.084, ge=-10, le=10)  # where cone 1 looks at module phase 0 [°]
    phase_offset_2_deg: float = Field(-0.057, ge=-10, le=10)
    threshold_offset: float = Field(0.018, ge=-0.3, le=0.3)  # the comparator's offset, a fraction of the pulse
    time_constant_ms: float = Field(0.5, ge=0, le=50)  # the bolometer's time constant [ms]


class HorizonSensorConfig(_Strict):
    """The simulated horizon sensor (the ``simulation.horizon`` section of a bench file): its design, its true build,
    its detector chain and its fleet's spreads.

    The configured serial has `build`; any other serial of a fleet is a sensor of the same design whose build errors
    are drawn from its serial alone (:func:`horizon_fleet_truth`) with the `*_sd` spreads."""

    serial: str = "HZ-0001"
    gamma_deg: float = Field(70.0, gt=30, lt=89)  # the design's half-cone (IDENTIFY reports it)
    ifov_half_angle_deg: float = Field(2.0, gt=0, le=10)
    ifov_profile: Literal["tophat", "gaussian"] = "tophat"
    scan_rate_hz: float = Field(1.0, gt=0, le=50)
    samples_per_revolution: int = Field(3600, ge=360, le=36000)
    threshold: float = Field(0.5, ge=wire.THRESHOLD_RANGE[0], le=wire.THRESHOLD_RANGE[1])  # C1 at power-up
    build: HorizonBuildConfig = HorizonBuildConfig()
    gamma_sd_deg: float = Field(0.03, ge=0, le=2)
    phase_sd_deg: float = Field(0.1, ge=0, le=5)
    threshold_sd: float = Field(0.015, ge=0, le=0.1)
    time_constant_sd: float = Field(0.1, ge=0, le=0.5)  # relative
    adc_bits: int = Field(16, ge=10, le=16)
    pedestal_counts: float = Field(2000.0, ge=0)
    counts_per_radiance: float = Field(2000.0, gt=0)  # counts per W m⁻² sr⁻¹ of 14–16 µm radiance
    noise_counts: float = Field(15.0, ge=0)  # the detector chain's noise per sample, rms [counts]
    min_contrast_counts: float = Field(500.0, ge=0)  # a pulse with a smaller range has no edges
    period_jitter: float = Field(1e-4, ge=0, le=0.01)  # each revolution's period, relative rms
    max_scans: int = Field(32, ge=1, le=wire.max_scans_per_read())
    temperature_rise_c: float = 3.0  # the head above the room (its motor and electronics) [°C]
    thermometer_noise_c: float = Field(0.02, ge=0)

    def truth(self) -> HorizonTruth:
        """The sensor this section describes (its own serial)."""
        b = self.build
        return HorizonTruth(self.serial, (b.gamma_1_deg, b.gamma_2_deg), (b.phase_offset_1_deg, b.phase_offset_2_deg),
                            b.threshold_offset, b.time_constant_ms / 1000.0, self.ifov_half_angle_deg,
                            self.ifov_profile)


def horizon_fleet_truth(config: HorizonSensorConfig, serial: str) -> HorizonTruth:
    """The simulated sensor of serial `serial`: the configured one for its own serial, any other a sensor of the same
    design with its build drawn from the serial alone — reproducible in any process, whatever was mounted before."""
    if serial == config.serial:
        return config.truth()
    return draw_build(serial, fleet_seed(serial), gamma_deg=config.gamma_deg, gamma_sd_deg=config.gamma_sd_deg,
                      phase_sd_deg=config.phase_sd_deg, threshold_sd=config.threshold_sd,
                      time_constant_s=config.build.time_constant_ms / 1000.0,
                      time_constant_sd=config.time_constant_sd, ifov_half_angle_deg=config.ifov_half_angle_deg,
                      ifov_profile=config.ifov_profile)


#: A blinding source's default place: on cone 1 at phase 120° with the table at its zero
DEFAULT_BLIND_DIRECTION = (math.sin(math.radians(120)) * math.sin(math.radians(70)), math.cos(math.radians(70)),
                           math.cos(math.radians(120)) * math.sin(math.radians(70)))


class HorizonSensorSimulator(FramedResponder, SimDevice):
    """The horizon sensor module on the simulated bench (its frame loop: :class:`drivers.framed_protocol.
    FramedResponder`).

    Parameters
    ----------
    world : SimWorld
    config : HorizonSensorConfig, optional
    earth : EarthSimulatorModel, optional
        The Earth simulator it faces; default one of the default configuration on the world's clock (heater off,
        cover closed).
    """

    name = "horizon-sensor"
    frame_format = wire.FORMAT

    def __init__(self, world: SimWorld, config: HorizonSensorConfig | None = None,
                 earth: EarthSimulatorModel | None = None):
        super().__init__()
        self.world = world
        self.config = config or HorizonSensorConfig()
        self.earth = earth or EarthSimulatorModel(EarthSimulatorConfig(), world.clock,
                                                  lambda: world.temperature_c + KELVIN)
        self._noise = world.rng("horizon-noise")
        self.motor_stalled = False
        self.dead_cones: set[int] = set()
        self.blinding: tuple[np.ndarray, float, float] | None = None
        self.mount(self.config.truth())

    # -- back door ------------------------------------------------------------------------------------------
    def mount(self, truth: HorizonTruth) -> None:
        """Put the sensor `truth` on the fixture: powered up fresh (counter 0, threshold at its power-up value)."""
        with self.lock:
            self.truth = truth
            self.powered_at = self.world.clock.now()
            self.threshold = float(np.float32(self.config.threshold))
            self.last: Revolution | None = None
            self.last_revolution = -1
            self._held.clear()

    def stall_motor(self) -> None:
        """The scan motor stops: no index mark, no revolution."""
        self.motor_stalled = True

    def kill_detector(self, cone: int | None = None) -> None:
        """Cone `cone`'s bolometer (None: both) is open: pedestal and noise, no light."""
        if cone not in (None, 1, 2):
            raise ValueError(f"`cone` is 1, 2 or None, got {cone!r}")
        self.dead_cones |= {1, 2} if cone is None else {cone}

    def blind(self, direction=DEFAULT_BLIND_DIRECTION, *, radius_deg: float = 1.0, temperature_k: float = 1500.0):
        """A hot source of angular radius `radius_deg` on the Earth simulator's sphere, in the lab direction
        `direction` from the sensor's nominal point (default: on cone 1 at phase 120° with the table at zero)."""
        d = np.asarray(direction, float)
        self.blinding = (d / np.linalg.norm(d), float(radius_deg), float(temperature_k))

    def clear_faults(self) -> None:
        self.faults.clear()
        self.corrupt_crc = 0
        self.motor_stalled = False
        self.dead_cones.clear()
        self.blinding = None

    # -- the physics seen from the world --------------------------------------------------------------------
    @property
    def nominal_period_s(self) -> float:
        return 1.0 / self.config.scan_rate_hz

    def scene(self) -> Scene:
        """What the sensor faces now (module docstring)."""
        bench, earth = self.world.bench, self.earth
        blind = self.blinding
        return Scene(centre_mm=np.array([0.0, 0.0, bench.lever_arm_mm]), axis=np.array([0.0, 0.0, 1.0]),
                     sphere_radius_mm=bench.source_distance_mm, disc_radius_deg=earth.true_radius_deg(),
                     disc_k=earth.disc_k(), background_k=earth.config.background_k, cover_open=earth.cover_open(),
                     blind_direction=None if blind is None else blind[0],
                     blind_radius_deg=1.0 if blind is None else blind[1], blind_k=1500.0 if blind is None else blind[2])

    def clean_signal(self, scene: Scene | None = None, pose: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Both cones' noise-free detector signals over one nominal revolution [counts, unclipped], shape (2, N):
        the IFOV's radiance, lagged by the bolometer, through the amplifier. `scene` default what it faces now;
        `pose` the sensor's (rotation: body axes as columns in the lab, position [mm]), default the world's."""
        c, t = self.config, self.truth
        scene = scene or self.scene()
        rotation, position = pose if pose is not None else self.world.sensor_pose()
        n = c.samples_per_revolution
        phase = np.arange(n) * 360.0 / n
        out = np.empty((2, n))
        background = float(band_radiance(scene.background_k))
        for k in range(2):
            if k + 1 in self.dead_cones:
                out[k] = c.pedestal_counts
                continue
            true_phase = phase + t.phase_offset_deg[k]
            directions = scan_directions(true_phase, t.gamma_deg[k], CONE_SIGNS[k])
            radiance = ifov_radiance(rotation, position, directions, true_phase, t, scene)
            lagged = detector_lag(radiance, self.nominal_period_s / n, t.time_constant_s)
            # the amplifier is AC-referenced to the cold background: the pedestal is what the shroud gives
            out[k] = c.pedestal_counts + c.counts_per_radiance * (lagged - background)
        return out

    def revolution(self, clean: np.ndarray) -> Revolution:
        """One revolution from the noise-free signals: its period, noisy quantised samples, the locator's edges."""
        c = self.config
        full = float((1 << c.adc_bits) - 1)
        period = self.nominal_period_s * (1.0 + c.period_jitter * self._noise.standard_normal())
        samples = np.clip(np.round(clean + c.noise_counts * self._noise.standard_normal(clean.shape)), 0.0, full)
        level = self.threshold + self.truth.threshold_offset
        edges = tuple(locate_edges(samples[k], level, min_contrast=c.min_contrast_counts, full_scale=full,
                                   plateau_margin=self.plateau_margin_samples) for k in range(2))
        return Revolution(period, samples, edges, self.head_temperature_c())  # type: ignore[arg-type]

    @property
    def plateau_margin_samples(self) -> int:
        """How far from an edge the locator takes its levels [samples]: two IFOV diameters of the design along the
        scan, 2 · 2α / sin γ of phase (an oblique crossing's blur is wider than one diameter)."""
        c = self.config
        phase = 4.0 * c.ifov_half_angle_deg / math.sin(math.radians(c.gamma_deg))
        return math.ceil(phase / 360.0 * c.samples_per_revolution)

    def head_temperature_c(self) -> float:
        return self.world.temperature_c + self.config.temperature_rise_c

    # -- framing --------------------------------------------------------------------------------------------
    def _dispatch(self, frame: wire.Frame) -> bytes:
        if self._busy():
            return self._error(frame.sequence, wire.NOT_READY, "a READ_SCANS is in progress")
        return super()._dispatch(frame)

    def _busy(self) -> bool:
        now = self.world.clock.now()
        return any(t > now for t, _ in self._held)

    def _commands(self):
        return {wire.IDENTIFY: self._identify, wire.READ_SCANS: self._read_scans, wire.GET_PULSE: self._pulse,
                wire.SET_THRESHOLD: self._set_threshold, wire.GET_STATUS: self._status}

    # -- commands -------------------------------------------------------------------------------------------
    def _identify(self, frame):
        if frame.payload:
            return self._error(frame.sequence, wire.BAD_LENGTH, "IDENTIFY takes no payload")
        c = self.config
        payload = wire.IDENTITY.pack(wire.pad(MODEL, 16), wire.pad(self.truth.serial, 16), wire.pad(FIRMWARE, 8),
                                     wire.N_CONES, c.adc_bits, c.samples_per_revolution,
                                     round(self.nominal_period_s * 1e6), c.gamma_deg, c.ifov_half_angle_deg,
                                     self.threshold, c.max_scans)
        return self._reply(frame.code, frame.sequence, payload)

    def _read_scans(self, frame):
        if len(frame.payload) != wire.READ_REQUEST.size:
            return self._error(frame.sequence, wire.BAD_LENGTH, "READ_SCANS takes a count u8")
        (n,) = wire.READ_REQUEST.unpack(frame.payload)
        if not 1 <= n <= self.config.max_scans:
            return self._error(frame.sequence, wire.OUT_OF_RANGE,
                               f"count {n} outside [1, {self.config.max_scans}]")
        now = self.world.clock.now()
        period = self.nominal_period_s
        if self.motor_stalled:
            return self._hold_until(now + 2.0 * period, self._error(frame.sequence, wire.NO_INDEX,
                                                                    "no index mark: the motor does not turn"))
        first = max(math.ceil((now - self.powered_at) / period - 1e-9), self.last_revolution + 1)
        ready = self.powered_at + first * period
        clean = self.clean_signal()
        parts = [wire.READ_HEAD.pack(n)]
        for i in range(n):
            rev = self.revolution(clean)
            ready += rev.period_s
            parts.append(self._pack_scan(first + i, rev))
            self.last = rev
        self.last_revolution = first + n - 1
        return self._hold_until(ready, self._reply(frame.code, frame.sequence, b"".join(parts)))

    def _pack_scan(self, counter: int, rev: Revolution) -> bytes:
        period_us = max(round(rev.period_s * 1e6), 1)
        n = self.config.samples_per_revolution
        fields = []
        for e in rev.edges:
            flags = (wire.EDGE_OUT if math.isfinite(e.out_index) else 0) | (
                wire.EDGE_IN if math.isfinite(e.in_index) else 0) | (wire.EDGE_SATURATED if e.saturated else 0)
            t_out = round(e.out_index / n * rev.period_s * 1e6) % period_us if math.isfinite(e.out_index) else 0
            t_in = round(e.in_index / n * rev.period_s * 1e6) % period_us if math.isfinite(e.in_index) else 0
            fields += [t_out, t_in, flags, _u16(e.space), _u16(e.earth)]
        thermometer = rev.temperature_c + self.config.thermometer_noise_c * self._noise.standard_normal()
        return wire.SCAN.pack(counter & 0xFFFFFFFF, period_us, *fields, wire.centi(thermometer))

    def _pulse(self, frame):
        if frame.payload:
            return self._error(frame.sequence, wire.BAD_LENGTH, "GET_PULSE takes no payload")
        if self.last is None:
            return self._error(frame.sequence, wire.NOT_READY, "no revolution reported yet")
        d = wire.pulse_decimation(self.config.samples_per_revolution)
        samples = self.last.samples[:, ::d].astype("<u2")
        edges: tuple[Edges, Edges] = self.last.edges  # type: ignore[assignment]
        payload = wire.PULSE_HEAD.pack(max(round(self.last.period_s * 1e6), 1), d, samples.shape[1],
                                       *(_u16(e.threshold) for e in edges)) + samples.tobytes()
        return self._reply(frame.code, frame.sequence, payload)

    def _set_threshold(self, frame):
        if len(frame.payload) != wire.THRESHOLD.size:
            return self._error(frame.sequence, wire.BAD_LENGTH, "SET_THRESHOLD takes a threshold f32")
        (value,) = wire.THRESHOLD.unpack(frame.payload)
        low, high = wire.THRESHOLD_RANGE
        if not (math.isfinite(value) and low <= value <= high):
            return self._error(frame.sequence, wire.OUT_OF_RANGE, f"threshold {value} outside [{low}, {high}]")
        self.threshold = float(value)
        return self._reply(frame.code, frame.sequence, wire.THRESHOLD.pack(value))

    def _status(self, frame):
        if frame.payload:
            return self._error(frame.sequence, wire.BAD_LENGTH, "GET_STATUS takes no payload")
        period = self.last.period_s if self.last is not None else self.nominal_period_s
        thermometer = self.head_temperature_c() + self.config.thermometer_noise_c * self._noise.standard_normal()
        payload = wire.STATUS.pack(self.threshold, wire.centi(thermometer), int(not self.motor_stalled),
                                   max(self.last_revolution, 0) & 0xFFFFFFFF, round(period * 1e6))
        return self._reply(frame.code, frame.sequence, payload)


def _u16(value: float) -> int:
    return int(min(max(round(value), 0), 0xFFFF))
