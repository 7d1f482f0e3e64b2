"""Driver of the coarse-sun-sensor (CSS) head (seed 000), over the framed protocol of :mod:`drivers.css_protocol`.

Replies are checked, and a bad exchange is raised as a typed error and asked again, by
:class:`~drivers.framed_protocol.FramedModule`: every command of this module is safe to repeat (READ takes fresh
samples; SET_TEMPERATURE sets an absolute setpoint). An error frame from the module is a :class:`CssHeadError`
with its code.

Counts become signals with the module's own conversion, read once by IDENTIFY (a READ identifies first if
nothing has): ``signal = (mean counts − pedestal) × units per count`` of each channel — amperes for the photodiodes
(uv, vis), volts for the thermopiles (ir). IDENTIFY's channel names must be the documented order
(:data:`drivers.css_protocol.CHANNELS`), so every reading is in the head's channel order. Offsets (dark current,
front-end offset, the thermopile's view of the room) are *not* removed: that is the calibration's job.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import css_protocol as wire
from .errors import LimitError
from .framed_protocol import FramedModule, ModuleError
from .interfaces import CoarseSunHead, CssHeadReading, SensorIdentity
from .tec_protocol import TemperatureClient
from .transport import DEFAULT_RETRIES, Port

#: The thermal plate's setpoints the driver allows by default [°C]: the TPS 230's operating range starts at −20 °C,
#: the BPW 21's ends at 80 °C (digest §3.3, §3.4)
DEFAULT_SETPOINT_RANGE_C = (-20.0, 70.0)


class CssHeadError(ModuleError):
    """The module answered with an error frame; `code` is its error code."""


@dataclass(frozen=True)
class CssIdentity(SensorIdentity):
    """What IDENTIFY reports, beyond model, serial and firmware.

    Attributes
    ----------
    adc_bits : int
    channels : tuple of 18 str
        Channel names in the head's order (:data:`drivers.css_protocol.CHANNELS`).
    pedestal_counts : tuple of 18 int
        The ADC reading of a zero signal per channel (mid-scale on the thermopiles' bipolar ranges) [counts].
    units_per_count : tuple of 18 float
        Conversion of each channel [A/count] (uv, vis) or [V/count] (ir).
    max_average : int
        Largest averaging count READ accepts.
    sample_ms : float
        Time of one sample of all channels [ms].
    """

    adc_bits: int
    channels: tuple[str, ...]
    pedestal_counts: tuple[int, ...]
    units_per_count: tuple[float, ...]
    max_average: int
    sample_ms: float

    @property
    def full_scale_counts(self) -> int:
        return (1 << self.adc_bits) - 1

    @property
    def units(self) -> tuple[str, ...]:
        """"A" or "V" per channel."""
        return tuple(wire.UNITS[name.split("_", 1)[1]] for name in self.channels)

    @property
    def range(self) -> tuple[tuple[float, float], ...]:
        """(lowest, highest) signal each channel reads before it is under range or saturated [A or V]."""
        full = self.full_scale_counts
        return tuple((-p * u, (full - p) * u) for p, u in zip(self.pedestal_counts, self.units_per_count))


class CssHead(FramedModule, TemperatureClient, CoarseSunHead):
    """The coarse-sun-sensor head (18 channels: a UV, a visible and an IR detector on each face of a cube).

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=115200)`` (the head's UART adapter, or a simulator URL).
    setpoint_range_c : (float, float)
        Thermal-plate setpoints the bench allows [°C]; requests outside are refused before sending.
    retries : int
        How many times a command is sent again after a garbled, cut or missing reply (default 3,
        :data:`~drivers.transport.DEFAULT_RETRIES`).
    name : str, optional
        Name in errors; default the port's.

    Attributes
    ----------
    retry_count : int
        Commands sent again so far: how noisy the link is.
    """

    reports_serial = True  # IDENTIFY answers the head's own serial
    frame_format = wire.FORMAT
    module_error = CssHeadError
    controller, regulated, settle_timeout_s = "plate", "head", 1800.0  # TemperatureClient's messages

    def __init__(self, port: Port, *, setpoint_range_c=DEFAULT_SETPOINT_RANGE_C, retries: int = DEFAULT_RETRIES,
                 name: str | None = None):
        self._attach(port, retries=retries, name=name)
        low, high = setpoint_range_c
        if not low < high:
            raise ValueError(f"`setpoint_range_c` must satisfy low < high, got [{low}, {high}]")
        self.setpoint_range_c = (float(low), float(high))
        self._identity: CssIdentity | None = None

    # -- the interface ----------------------------------------------------------------------------------
    def identify(self) -> CssIdentity:
        """Model, serial, firmware, the channel list and the module's conversion constants (kept for :meth:`read`)."""
        fields = self._unpack(wire.IDENTITY, self._exchange(wire.IDENTIFY), "IDENTIFY")
        model, serial, firmware, bits, count, max_average, sample_us = fields[:7]
        per_channel = fields[7:]
        names = tuple(wire.unpad(n) for n in per_channel[0::3])
        pedestals = tuple(int(p) for p in per_channel[1::3])
        units = tuple(float(u) for u in per_channel[2::3])
        if not (1 <= bits <= 32 and count == wire.N_CHANNELS and max_average >= 1 and sample_us > 0
                and all(u > 0 for u in units) and all(p <= (1 << bits) - 1 for p in pedestals)):
            self._fail(f"IDENTIFY reply is not a CSS head's: {bits} bits, {count} channels, averaging up to "
                       f"{max_average}, {sample_us} us per sample, pedestals {pedestals}, units per count {units}", b"")
        if names != wire.CHANNELS:
            self._fail(f"IDENTIFY reports the channels {', '.join(names)}; a CSS head has "
                       f"{', '.join(wire.CHANNELS)} in that order", b"")
        self._identity = CssIdentity(wire.unpad(model), wire.unpad(serial), wire.unpad(firmware), int(bits), names,
                                     pedestals, units, int(max_average), sample_us / 1000.0)
        return self._identity

    @property
    def identity(self) -> CssIdentity:
        """The module's identity, asked for once."""
        return self._identity or self.identify()

    def read(self, average: int = 16) -> CssHeadReading:
        """One reading: the mean of `average` samples of the 18 channels, and the head temperature.

        A channel is flagged saturated when the module says one of its samples hit full scale or its mean is at
        full scale (its signal is then a lower bound), under range when one hit 0."""
        ident = self.identity
        if not 1 <= average <= ident.max_average:
            raise LimitError(self.name, f"averaging count {average} is outside [1, {ident.max_average}]")
        timeout_s = self.port.timeout_s + average * ident.sample_ms / 1000.0
        payload = self._exchange(wire.READ, wire.READ_REQUEST.pack(average), timeout_s=timeout_s)
        fields = self._unpack(wire.READ_REPLY, payload, "READ")
        n, flags, saturated_mask, under_mask = fields[:4]
        sums, (temperature, counter) = fields[4:4 + wire.N_CHANNELS], fields[4 + wire.N_CHANNELS:]
        if n != average:
            self._fail(f"READ reply holds {n} samples, {average} were asked for", payload[:64])
        full = ident.full_scale_counts
        if any(s > n * full for s in sums):
            self._fail(f"READ sums {sums} exceed {n} samples of {full} counts", payload[:64])
        if (saturated_mask | under_mask) >> wire.N_CHANNELS:
            self._fail(f"READ masks 0x{saturated_mask:08X}, 0x{under_mask:08X} name channels beyond "
                       f"{wire.N_CHANNELS}", payload[:64])
        counts = tuple(s / n for s in sums)
        signals = tuple((c - p) * u for c, p, u in zip(counts, ident.pedestal_counts, ident.units_per_count))
        saturated = tuple(bool(saturated_mask >> i & 1) or counts[i] >= full for i in range(wire.N_CHANNELS))
        under = tuple(bool(under_mask >> i & 1) or counts[i] <= 0 for i in range(wire.N_CHANNELS))
        return CssHeadReading(ident.channels, counts, signals, saturated, under, temperature / 100.0, int(n),
                              int(counter), plate_on=bool(flags & wire.FLAG_PLATE_ON),
                              plate_settled=bool(flags & wire.FLAG_SETTLED))
