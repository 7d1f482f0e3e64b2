"""Protocol front of the simulated quadrant-photodiode (QD) sun-sensor module (wire format:
:mod:`drivers.qd_protocol`; physics: :mod:`drivers.sim.qd_optics`).

The module sees the world's sun direction in the body frame (the table's true pose), the world's
irradiance (lamp output through the shutter: zero when it is closed or the lamp off) and the world's
temperature as its ambient. A READ of N samples takes N × integration time + overhead on the simulated
clock: at time scale 0 the clock jumps there at once, otherwise the reply is held back until then, and any
command arriving meanwhile gets error 5 (not ready). At time scale 0, GET_TEMPERATURE — the query a bench
polls while it waits for the TEC — completes the settling (the clock jumps to the moment the die has
settled), as asking whether the lamp is warm completes its warm-up.

Back door (lewis style, never reachable over the wire): :attr:`faults` (the :class:`~drivers.sim.device.
WireFaults` of every simulator: no reply, garbled, truncated, disconnected), :attr:`corrupt_crc` (the next
replies carry a wrong CRC), :attr:`channel_faults` (stuck, dead or saturated channels; also
:meth:`stick_channel`, :meth:`kill_channel`, :meth:`saturate_channel`, :meth:`clear_faults`),
:meth:`mount` (another module on the fixture) and the world's temperature (ambient).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from .. import qd_protocol as wire
from ..framed_protocol import FramedResponder
from .device import ChannelFaults, SimDevice
from .qd_optics import QdChannels, QdOptics, QdTruth, TecModel
from .temperature import TemperatureResponder
from .world import SimWorld

MODEL = "SB-QD-SUN"
FIRMWARE = "1.0.0"

_D = QdTruth()
_Quad = tuple[float, float, float, float]


class QdSensorConfig(BaseModel):
    """The simulated QD module (the ``simulation.qd`` section of a bench file): its true build, photometry,
    dark current, electronics and TEC, and the effects a calibration does not model — the diaphragm's thickness,
    the housing's stray light (bore, window, wall reflectance) and the crosstalk between neighbouring channels
    (zero turns each off). Every field is :class:`~drivers.sim.qd_optics.QdTruth`'s, same name, same default;
    `serial` is the configured module's (other serials of a fleet are drawn around it)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    serial: str = _D.serial
    aperture_diameter_um: float = Field(_D.aperture_diameter_um, gt=0, le=1000)
    height_um: float = Field(_D.height_um, gt=0)
    diaphragm_thickness_um: float = Field(_D.diaphragm_thickness_um, ge=0)
    detector_side_mm: float = Field(_D.detector_side_mm, gt=0)
    gap_um: float = Field(_D.gap_um, ge=0)
    x0_um: float = _D.x0_um
    y0_um: float = _D.y0_um
    alpha0_deg: float = Field(_D.alpha0_deg, ge=-10, le=10)
    beta0_deg: float = Field(_D.beta0_deg, ge=-10, le=10)
    phi0_deg: float = Field(_D.phi0_deg, ge=-45, le=45)
    bore_radius_mm: float = Field(_D.bore_radius_mm, gt=0)
    bore_height_mm: float = Field(_D.bore_height_mm, gt=0)
    window_radius_mm: float = Field(_D.window_radius_mm, gt=0)
    wall_reflectance: float = Field(_D.wall_reflectance, ge=0, le=1)
    irradiance_w_m2: float = Field(_D.irradiance_w_m2, ge=0)
    responsivity_a_w: float = Field(_D.responsivity_a_w, gt=0)
    quadrant_response: _Quad = _D.quadrant_response
    crosstalk: _Quad = _D.crosstalk
    dark_na_at_25c: _Quad = _D.dark_na_at_25c
    dark_doubling_c: _Quad = _D.dark_doubling_c
    adc_bits: int = Field(_D.adc_bits, ge=8, le=24)
    full_scale_ua: float = Field(_D.full_scale_ua, gt=0)
    gain_error: _Quad = _D.gain_error
    pedestal_counts: int = Field(_D.pedestal_counts, ge=0)
    pedestal_error_counts: _Quad = _D.pedestal_error_counts
    amp_noise_pa: float = Field(_D.amp_noise_pa, ge=0)
    integration_ms: float = Field(_D.integration_ms, gt=0, le=1000)
    overhead_ms: float = Field(_D.overhead_ms, ge=0)
    max_average: int = Field(_D.max_average, ge=1, le=65535)
    tec_tau_s: float = Field(_D.tec_tau_s, gt=0)
    tec_range_c: tuple[float, float] = _D.tec_range_c
    thermometer_offset_c: float = _D.thermometer_offset_c
    thermometer_noise_c: float = Field(_D.thermometer_noise_c, ge=0)
    settle_tolerance_c: float = Field(_D.settle_tolerance_c, gt=0)

    @model_validator(mode="after")
    def _physical(self):
        self.truth()  # the truth's own checks at load time
        return self

    def truth(self) -> QdTruth:
        return QdTruth(**self.model_dump())


class QdSensorSimulator(TemperatureResponder, FramedResponder, SimDevice):
    """The QD module on the simulated bench (its frame loop: :class:`drivers.framed_protocol.FramedResponder`).

    Parameters
    ----------
    world : SimWorld
    truth : QdTruth or QdSensorConfig, optional
        The module's true build; default the example build.
    """

    name = "qd-sensor"
    frame_format = wire.FORMAT

    def __init__(self, world: SimWorld, truth: QdTruth | QdSensorConfig | None = None):
        super().__init__()
        self.world = world
        self.channel_faults = ChannelFaults()
        self._noise = world.rng("qd-noise")
        self.mount(truth.truth() if isinstance(truth, QdSensorConfig) else (truth or QdTruth()))

    # -- back door ---------------------------------------------------------------------------------------
    def mount(self, truth: QdTruth) -> None:
        """Put the module `truth` on the fixture: powered up fresh (TEC off, at ambient, counter 0)."""
        with self.lock:
            self.truth = truth
            self.optics = QdOptics(truth)
            self.channels = QdChannels(truth)
            self.tec = TecModel(truth, self.world.clock, lambda: self.world.temperature_c)
            self.samples = 0
            self._held.clear()

    def stick_channel(self, quadrant: int, counts: int) -> None:
        self.channel_faults.stuck[self._quadrant(quadrant)] = int(counts)

    def kill_channel(self, quadrant: int) -> None:
        self.channel_faults.dead.add(self._quadrant(quadrant))

    def saturate_channel(self, quadrant: int) -> None:
        self.channel_faults.saturated.add(self._quadrant(quadrant))

    def clear_faults(self) -> None:
        self.channel_faults.clear()
        self.faults.clear()
        self.corrupt_crc = 0

    @staticmethod
    def _quadrant(q: int) -> int:
        if q not in (1, 2, 3, 4):
            raise ValueError(f"quadrants are numbered 1 … 4, got {q}")
        return q

    # -- the physics seen from the world -------------------------------------------------------------------
    def photocurrents_a(self) -> np.ndarray:
        """Noise-free photocurrents of Q1 … Q4 now, from the world's sun direction and irradiance [A]."""
        irradiance = self.truth.irradiance_w_m2 * self.world.irradiance()
        if irradiance <= 0:
            return np.zeros(4)
        zenith, azimuth = self.world.sun_direction_body()
        return self.optics.photocurrents_a(zenith, azimuth, irradiance, self.world.bench.source_diameter_deg)

    # -- framing -------------------------------------------------------------------------------------------
    def _dispatch(self, frame: wire.Frame) -> bytes:
        if self._busy():
            return self._error(frame.sequence, wire.NOT_READY, "a READ is in progress")
        return super()._dispatch(frame)

    def _commands(self):
        return {wire.IDENTIFY: self._identify, wire.READ: self._read, **self._temperature_commands()}

    def _busy(self) -> bool:
        now = self.world.clock.now()
        return any(t > now for t, _ in self._held)

    # -- commands ------------------------------------------------------------------------------------------
    def _identify(self, frame):
        if frame.payload:
            return self._error(frame.sequence, wire.BAD_LENGTH, "IDENTIFY takes no payload")
        t = self.truth
        payload = wire.IDENTITY.pack(wire.pad(MODEL, 16), wire.pad(t.serial, 16), wire.pad(FIRMWARE, 8), t.adc_bits,
                                     t.pedestal_counts, *(float(a) for a in t.amperes_per_count),
                                     t.detector_side_mm * 1000.0, t.gap_um, round(t.integration_ms * 1000),
                                     t.max_average)
        return self._reply(frame.code, frame.sequence, payload)

    def _read(self, frame):
        if len(frame.payload) == 0:
            n = 1
        elif len(frame.payload) == wire.READ_REQUEST.size:
            (n,) = wire.READ_REQUEST.unpack(frame.payload)
        else:
            return self._error(frame.sequence, wire.BAD_LENGTH, "READ takes nothing or an averaging count u16")
        t = self.truth
        if not 1 <= n <= t.max_average:
            return self._error(frame.sequence, wire.OUT_OF_RANGE, f"averaging count {n} outside [1, {t.max_average}]")
        start = self.world.clock.now()
        duration_s = (n * t.integration_ms + t.overhead_ms) / 1000.0
        middle = start + 0.5 * n * t.integration_ms / 1000.0
        die_c = self.tec.true_c(middle)
        current = self.photocurrents_a() + self.optics.dark_current_a(die_c)
        counts = self.channels.sample_counts(current, n, self._noise, self.channel_faults)
        full = self.channels.full_scale_counts
        flags = 0
        for k in range(4):
            flags |= int((counts[:, k] == full).any()) << k
            flags |= int((counts[:, k] == 0).any()) << (k + 4)
        thermometer = die_c + t.thermometer_offset_c + t.thermometer_noise_c * self._noise.standard_normal()
        self.samples += n
        payload = wire.READ_REPLY.pack(n, flags, *(int(s) for s in counts.sum(axis=0)), wire.centi(thermometer),
                                       self.samples & 0xFFFFFFFF)
        return self._hold_until(start + duration_s, self._reply(frame.code, frame.sequence, payload))

    @property
    def temperature_settings(self):
        """Where TemperatureResponder finds the setpoint range and the thermometer's noise."""
        return self.truth
