"""Protocol front of the simulated coarse-sun-sensor (CSS) head (wire format: :mod:`drivers.css_protocol`; physics:
:mod:`drivers.sim.css_optics`).

The head sees the world's sun direction in the body frame (the table's true pose; the cube's +Z face, ``pz``,
faces the source at the table's zero), the world's irradiance (lamp output through the shutter: zero when it is
closed or the lamp off) and the world's temperature as its ambient. The lab source's irradiance at the head is
``irradiance_w_m2`` at the world's irradiance 1, and each detector type sees it through a spectral-mismatch factor
K_lab/K_AM0 (digest §8.2 item 6: a xenon arc or a white LED is not the AM0 Sun the detectors' scales are quoted
for), so a detector's light term is ``css_optics`` signal at relative irradiance
``world irradiance × irradiance_w_m2 / 1366 W/m² × mismatch[type]``.

Noise. :meth:`~drivers.sim.css_optics.CssOptics.noise_sd` is the noise of one reading averaged over the head's
16 conversions (the thesis' ADuC842, digest §3.6); one wire sample is one conversion, so each sample draws that
noise × √16, and the module's ADC adds its own `adc_noise_counts` (the converter's transition and reference noise,
which also dithers the quantisation). A READ of N samples then has the physics' noise ÷ √N: N = 16 is the
thesis' reading. Each sample is quantised and clipped by :class:`~drivers.sim.css_optics.CssChannels`.

Timing as the QD module's: a READ of N samples takes N × sample time + overhead on the simulated clock: at time
scale 0 the clock jumps there at once, otherwise the reply is held back until then, and any command arriving
meanwhile gets error 5 (not ready). At time scale 0, GET_TEMPERATURE — the query a bench polls while it waits for
the plate — completes the settling (the clock jumps to the moment the head has settled). The head's thermal plate
is :class:`drivers.sim.qd_optics.TecModel` (first order towards the setpoint, regulating on the thermometer; off,
towards ambient) with this head's constants.

Back door (lewis style, never reachable over the wire): :attr:`faults` (the :class:`~drivers.sim.device.
WireFaults` of every simulator: no reply, garbled, truncated, disconnected), :attr:`corrupt_crc` (the next replies
carry a wrong CRC), :attr:`channel_faults` (:class:`~drivers.sim.device.ChannelFaults` by channel name; also
:meth:`stick_channel` (the ADC repeats a code), :meth:`kill_channel` (the detector is open: the channel reads its
offset and noise, no light), :meth:`saturate_channel` (the amplifier latched at its rail: full scale, the saturated
bit set), :meth:`clear_faults`), :meth:`mount` (another head on the fixture) and the world's temperature (ambient).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import replace
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .. import css_protocol as wire
from ..framed_protocol import FramedResponder
from .css_optics import CHANNELS, TYPES, CssChannels, CssOptics, CssTruth, css_truth
from .device import ChannelFaults, SimDevice
from .qd_optics import TecModel
from .temperature import TemperatureResponder
from .world import SimWorld

MODEL = "SB-CSS-HEAD"
FIRMWARE = "1.0.0"
#: The AM0 solar constant the detectors' nominal scales are quoted for [W/m²] (digest §2.1)
SOLAR_CONSTANT_W_M2 = 1366.0

# the simulator's physics and the wire name the channels alike (css_optics knows its names itself)
assert CHANNELS == wire.CHANNELS and TYPES == wire.TYPES


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SpectralMismatch(_Strict):
    """K_lab/K_AM0 of each detector type under one lab source: its response per W/m² of the lab source relative
    to its response per W/m² of the AM0 Sun (digest §2.3 eq. 3.1 with the lab spectrum over the AM0 one)."""

    uv: float = Field(ge=0, le=10)
    vis: float = Field(ge=0, le=10)
    ir: float = Field(ge=0, le=10)

    def factor(self, kind: str) -> float:
        return float(getattr(self, kind))


#: A xenon arc without an AM0 filter: a little less UV than the Sun (an ozone-free envelope cuts below ~250 nm),
#: about the Sun's visible share, and little beyond the thermopiles' 5.5 µm cut-on (the quartz envelope and the
#: condenser absorb the arc's far IR; what is left is the warm housing's). The simulated bench's own assumption:
#: the thesis gives no lab-source data (digest §8.2 item 6).
XENON_MISMATCH = SpectralMismatch(uv=0.85, vis=0.95, ir=0.30)
#: A white (phosphor) LED: no UV to speak of, no thermal IR; visible as the Sun's per W/m² (the BPW 21 is V(λ)-matched)
LED_MISMATCH = SpectralMismatch(uv=0.02, vis=1.0, ir=0.0)


class DiodeOverride(_Strict):
    """Explicit true values of one detector of the configured head, replacing the drawn ones (None keeps it)."""

    normal_zenith_deg: float | None = Field(None, ge=0, le=180)
    normal_azimuth_deg: float | None = None
    scale: float | None = Field(None, gt=0)  # [A] or [V] at normal incidence, 1366 W/m², 25 °C
    bias: float | None = None  # [A] or [V] at 25 °C


class CssHeadConfig(_Strict):
    """The simulated CSS head (the ``simulation.css`` section of a bench file): its true build, the lab source's
    photometry as it sees it, its electronics and its thermal plate.

    Build: the detectors follow :func:`drivers.sim.css_optics.css_truth` — `response` law, build errors drawn from
    `build_seed` (normal tilts of `tilt_sd_deg` per axis, relative scale spread `scale_sd`, offsets around their
    nominal values; None: the nominal head), then `overrides` by channel name replace single values. `serial` is
    the configured head's; other serials of a fleet are drawn from their serial (:func:`css_fleet_truth`).
    """

    serial: str = "CSS-0001"
    response: Literal["fresnel", "kelly", "power", "thesis"] = "fresnel"
    build_seed: int | None = Field(1, ge=0)
    tilt_sd_deg: float = Field(1.0, ge=0, le=10)
    scale_sd: float = Field(0.03, ge=0, lt=0.3)
    overrides: dict[str, DiodeOverride] = Field(default_factory=dict)
    irradiance_w_m2: float = Field(1000.0, ge=0)  # at the head, normal incidence, world irradiance 1
    xenon_mismatch: SpectralMismatch = XENON_MISMATCH  # used when simulation.source is xenon
    led_mismatch: SpectralMismatch = LED_MISMATCH  # used when simulation.source is led
    adc_bits: int = Field(16, ge=12, le=24)
    adc_noise_counts: float = Field(0.7, ge=0)  # the ADC's own noise per conversion, rms [counts]
    sample_ms: float = Field(1.0, gt=0, le=1000)  # one conversion of all 18 channels [ms]
    overhead_ms: float = Field(0.5, ge=0)  # a READ's fixed conversion and reply time [ms]
    max_average: int = Field(1024, ge=1, le=65535)
    tec_tau_s: float = Field(60.0, gt=0)  # the head's time constant on its thermal plate [s]
    tec_range_c: tuple[float, float] = (-20.0, 70.0)  # setpoints the plate accepts [°C]
    settle_tolerance_c: float = Field(0.05, gt=0)  # |true − target| that counts as settled [°C]
    thermometer_offset_c: float = 0.2  # thermometer reading minus the head's true temperature [°C]
    thermometer_noise_c: float = Field(0.02, ge=0)  # rms noise of one temperature reading [°C]

    @field_validator("overrides")
    @classmethod
    def _known_channels(cls, value: dict) -> dict:
        unknown = sorted(set(value) - set(CHANNELS))
        if unknown:
            raise ValueError(f"no channel {', '.join(unknown)} (channels: {', '.join(CHANNELS)})")
        return value

    @model_validator(mode="after")
    def _consistent(self):
        low, high = self.tec_range_c
        if not low < high:
            raise ValueError(f"`tec_range_c` must satisfy low < high, got [{low}, {high}]")
        if self.max_average * ((1 << self.adc_bits) - 1) >= 1 << 32:
            raise ValueError(f"`max_average` {self.max_average} × {(1 << self.adc_bits) - 1} counts overflows "
                             f"READ's u32 sums: at most {((1 << 32) - 1) // ((1 << self.adc_bits) - 1)} for "
                             f"{self.adc_bits} bits")
        return self

    def truth(self) -> CssTruth:
        """The head this section describes."""
        head = css_truth(self.serial, self.build_seed, self.response, tilt_sd_deg=self.tilt_sd_deg,
                         scale_sd=self.scale_sd)
        if not self.overrides:
            return head
        diodes = tuple(replace(d, **{k: v for k, v in self.overrides[d.channel].model_dump().items()
                                     if v is not None}) if d.channel in self.overrides else d for d in head.diodes)
        return replace(head, diodes=diodes)

    def mismatch(self, source: str) -> SpectralMismatch:
        """The spectral mismatch under the bench's source (``xenon`` or ``led``)."""
        return self.led_mismatch if source == "led" else self.xenon_mismatch


def css_fleet_truth(config: CssHeadConfig, serial: str) -> CssTruth:
    """The simulated head of serial `serial`: the configured head for its own serial, any other a head of the same
    design (the configured response law and spreads, no overrides) whose build errors are drawn from the serial
    alone — reproducible in any process, whatever was mounted before."""
    if serial == config.serial:
        return config.truth()
    seed = zlib.crc32(f"css-build:{serial}".encode())
    return css_truth(serial, seed, config.response, tilt_sd_deg=config.tilt_sd_deg, scale_sd=config.scale_sd)


class CssHeadSimulator(TemperatureResponder, FramedResponder, SimDevice):
    """The CSS head on the simulated bench (its frame loop: :class:`drivers.framed_protocol.FramedResponder`).

    Parameters
    ----------
    world : SimWorld
    config : CssHeadConfig, optional
        The head's build, photometry, electronics and plate; default the example head.
    """

    name = "css-head"
    frame_format = wire.FORMAT
    controller = "plate"  # TemperatureResponder's messages

    def __init__(self, world: SimWorld, config: CssHeadConfig | None = None):
        super().__init__()
        self.world = world
        self.config = config = config or CssHeadConfig()
        self.channels = CssChannels(config.adc_bits)
        self._units_per_count = self.channels.units_per_count()
        self._kinds = [c.split("_", 1)[1] for c in CHANNELS]
        self.channel_faults = ChannelFaults()
        self._noise = world.rng("css-noise")
        self.mount(config.truth())

    # -- back door ---------------------------------------------------------------------------------------
    def mount(self, truth: CssTruth) -> None:
        """Put the head `truth` on the fixture: powered up fresh (plate off, at ambient, counter 0)."""
        with self.lock:
            self.truth = truth
            self.optics = CssOptics(truth)
            self.tec = TecModel(self.config, self.world.clock, lambda: self.world.temperature_c)
            self.samples = 0
            self._held.clear()

    def stick_channel(self, channel: str, counts: int) -> None:
        """The channel's ADC repeats `counts` whatever the light."""
        self.channel_faults.stuck[self._channel(channel)] = int(counts)

    def kill_channel(self, channel: str) -> None:
        """The channel's detector is open: it reads its offset and noise, no light."""
        self.channel_faults.dead.add(self._channel(channel))

    def saturate_channel(self, channel: str) -> None:
        """The channel's amplifier is latched at its rail: it reads full scale."""
        self.channel_faults.saturated.add(self._channel(channel))

    def clear_faults(self) -> None:
        self.channel_faults.clear()
        self.faults.clear()
        self.corrupt_crc = 0

    @staticmethod
    def _channel(name: str) -> str:
        if name not in CHANNELS:
            raise ValueError(f"no channel {name!r} (channels: {', '.join(CHANNELS)})")
        return name

    # -- the physics seen from the world -------------------------------------------------------------------
    def sun_vector(self) -> np.ndarray:
        """Unit vector to the source in the head's body frame, from the table's true pose."""
        zenith, azimuth = (math.radians(a) for a in self.world.sun_direction_body())
        return np.array([math.sin(zenith) * math.cos(azimuth), math.sin(zenith) * math.sin(azimuth),
                         math.cos(zenith)])

    def relative_irradiance(self) -> np.ndarray:
        """Each detector's irradiance now relative to the AM0 Sun its scale is quoted for (module docstring), (18,)."""
        mismatch = self.config.mismatch(self.world.lamp.spec.kind)
        base = self.world.irradiance() * self.config.irradiance_w_m2 / SOLAR_CONSTANT_W_M2
        return base * np.array([mismatch.factor(k) for k in self._kinds])

    def signals(self, temperature_c: float | None = None) -> np.ndarray:
        """Noise-free signals of the 18 detectors now [A or V]: offsets plus the source's light (none on a dead
        channel), the head at `temperature_c` (default its true temperature now)."""
        head_c = self.tec.true_c() if temperature_c is None else float(temperature_c)
        sun = self.sun_vector()
        dark = self.optics.signals(sun, 0.0, head_c)
        light = (self.optics.signals(sun, 1.0, head_c) - dark) * self.relative_irradiance()
        for name in self.channel_faults.dead:
            light[CHANNELS.index(name)] = 0.0  # the detector is open; its front end's offset stays
        return dark + light

    def sample_counts(self, n: int, temperature_c: float) -> np.ndarray:
        """ADC codes of `n` samples of the 18 channels, faults applied, shape (n, 18) (module docstring)."""
        clean = self.signals(temperature_c)
        per_sample = self.optics.noise_sd(clean, temperature_c) * math.sqrt(self.truth.samples_averaged)
        sd = np.hypot(per_sample, self.config.adc_noise_counts * self._units_per_count)
        noisy = clean + sd * self._noise.standard_normal((n, len(CHANNELS)))
        return self.channels.counts(noisy, self.channel_faults)  # a dead channel's light is gone already (signals)

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
        c = self.config
        per_channel = []
        for name, pedestal, units in zip(CHANNELS, self.channels.pedestals(), self._units_per_count):
            per_channel += [wire.pad(name, 8), int(pedestal), float(units)]
        payload = wire.IDENTITY.pack(wire.pad(MODEL, 16), wire.pad(self.truth.serial, 16), wire.pad(FIRMWARE, 8),
                                     c.adc_bits, len(CHANNELS), c.max_average, round(c.sample_ms * 1000),
                                     *per_channel)
        return self._reply(frame.code, frame.sequence, payload)

    def _read(self, frame):
        if len(frame.payload) == 0:
            n = 1
        elif len(frame.payload) == wire.READ_REQUEST.size:
            (n,) = wire.READ_REQUEST.unpack(frame.payload)
        else:
            return self._error(frame.sequence, wire.BAD_LENGTH, "READ takes nothing or an averaging count u16")
        c = self.config
        if not 1 <= n <= c.max_average:
            return self._error(frame.sequence, wire.OUT_OF_RANGE, f"averaging count {n} outside [1, {c.max_average}]")
        start = self.world.clock.now()
        duration_s = (n * c.sample_ms + c.overhead_ms) / 1000.0
        middle = start + 0.5 * n * c.sample_ms / 1000.0
        head_c = self.tec.true_c(middle)
        counts = self.sample_counts(n, head_c)
        full = self.channels.full_scale_counts
        saturated = sum(1 << i for i in range(len(CHANNELS)) if (counts[:, i] == full).any())
        under = sum(1 << i for i in range(len(CHANNELS)) if (counts[:, i] == 0).any())
        flags = (wire.FLAG_PLATE_ON if self.tec.enabled else 0) | (wire.FLAG_SETTLED if self.tec.settled(middle)
                                                                   else 0)
        thermometer = head_c + c.thermometer_offset_c + c.thermometer_noise_c * self._noise.standard_normal()
        self.samples += n
        payload = wire.READ_REPLY.pack(n, flags, saturated, under, *(int(s) for s in counts.sum(axis=0)),
                                       wire.centi(thermometer), self.samples & 0xFFFFFFFF)
        return self._hold_until(start + duration_s, self._reply(frame.code, frame.sequence, payload))

    @property
    def temperature_settings(self):
        """Where TemperatureResponder finds the setpoint range and the thermometer's noise."""
        return self.config
