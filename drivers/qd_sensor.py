"""Driver of the quadrant-photodiode (QD) sun-sensor module (seed 002), over the framed protocol of
:mod:`drivers.qd_protocol`.

Replies are checked, and a bad exchange is raised as a typed error and asked again, by
:class:`~drivers.framed_protocol.FramedModule`: every command of this module is safe to repeat (READ takes fresh
samples; SET_TEMPERATURE sets an absolute setpoint). An error frame from the module is a :class:`QdSensorError`
with its code.

Counts become amperes with the module's own conversion, read once by IDENTIFY (a READ identifies first if
nothing has): ``I = (mean counts − pedestal) × amperes per count`` of each quadrant. The dark current is
*not* removed: that is the calibration's job (seed 002 §2.1).
"""

from __future__ import annotations

from dataclasses import dataclass

from . import qd_protocol as wire
from .errors import LimitError
from .framed_protocol import FramedModule, ModuleError
from .interfaces import QuadrantReading, QuadrantSensor, SensorIdentity
from .tec_protocol import TemperatureClient
from .transport import DEFAULT_RETRIES, Port


class QdSensorError(ModuleError):
    """The module answered with an error frame; `code` is its error code."""


@dataclass(frozen=True)
class QdIdentity(SensorIdentity):
    """What IDENTIFY reports, beyond model, serial and firmware.

    Attributes
    ----------
    adc_bits : int
    pedestal_counts : int
        The ADC reading of zero current [counts].
    amperes_per_count : tuple of 4 float
        Conversion of each quadrant's channel (Q1 … Q4) [A/count].
    detector_side_um : float
        Side L of the square active area (seed 002 eq. 2.1) [µm].
    gap_um : float
        Width of the dead cross between the quadrants [µm].
    integration_ms : float
        Integration time of one sample [ms].
    max_average : int
        Largest averaging count READ accepts.
    """

    adc_bits: int
    pedestal_counts: int
    amperes_per_count: tuple[float, float, float, float]
    detector_side_um: float
    gap_um: float
    integration_ms: float
    max_average: int

    @property
    def full_scale_counts(self) -> int:
        return (1 << self.adc_bits) - 1

    @property
    def full_scale_a(self) -> tuple[float, ...]:
        """Largest current each channel reads before it saturates [A]."""
        return tuple((self.full_scale_counts - self.pedestal_counts) * a for a in self.amperes_per_count)


class QdSunSensor(FramedModule, TemperatureClient, QuadrantSensor):
    """The quadrant-photodiode sun-sensor module.

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=115200)`` (RS-485 adapter, or a simulator URL).
    setpoint_range_c : (float, float)
        TEC setpoints the bench allows [°C]; requests outside are refused before sending.
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

    reports_serial = True  # IDENTIFY answers the module's own serial
    frame_format = wire.FORMAT
    module_error = QdSensorError

    def __init__(self, port: Port, *, setpoint_range_c=(-40.0, 70.0), retries: int = DEFAULT_RETRIES,
                 name: str | None = None):
        self._attach(port, retries=retries, name=name)
        self.setpoint_range_c = setpoint_range_c
        self._identity: QdIdentity | None = None

    # -- the interface ----------------------------------------------------------------------------------
    def identify(self) -> QdIdentity:
        """Model, serial, firmware and the module's conversion constants (kept for :meth:`read`)."""
        (model, serial, firmware, bits, pedestal, a1, a2, a3, a4, side_um, gap_um, integration_us,
         max_average) = self._unpack(wire.IDENTITY, self._exchange(wire.IDENTIFY), "IDENTIFY")
        amperes = (a1, a2, a3, a4)
        if not (1 <= bits <= 32 and all(a > 0 for a in amperes) and integration_us > 0 and max_average >= 1):
            self._fail(f"IDENTIFY reply is not a module's: {bits} bits, {amperes} A/count, {integration_us} us, "
                       f"averaging up to {max_average}", b"")
        self._identity = QdIdentity(wire.unpad(model), wire.unpad(serial), wire.unpad(firmware), int(bits),
                                    int(pedestal), tuple(float(a) for a in amperes), float(side_um), float(gap_um),
                                    integration_us / 1000.0, int(max_average))
        return self._identity

    @property
    def identity(self) -> QdIdentity:
        """The module's identity, asked for once."""
        return self._identity or self.identify()

    def read(self, average: int = 1) -> QuadrantReading:
        """One reading: the mean of `average` samples of the four quadrants, and the die temperature.

        A quadrant is flagged saturated when the module says one of its samples hit full scale or its mean is
        at full scale; its current is then only a lower bound."""
        ident = self.identity
        if not 1 <= average <= ident.max_average:
            raise LimitError(self.name, f"averaging count {average} is outside [1, {ident.max_average}]")
        timeout_s = self.port.timeout_s + average * ident.integration_ms / 1000.0
        n, flags, s1, s2, s3, s4, temperature, counter = self._unpack(
            wire.READ_REPLY, self._exchange(wire.READ, wire.READ_REQUEST.pack(average), timeout_s=timeout_s), "READ")
        if n != average:
            self._fail(f"READ reply holds {n} samples, {average} were asked for", wire.READ_REPLY.pack(
                n, flags, s1, s2, s3, s4, temperature, counter))
        full = ident.full_scale_counts
        sums = (s1, s2, s3, s4)
        if any(s > n * full for s in sums):
            self._fail(f"READ sums {sums} exceed {n} samples of {full} counts", b"")
        counts = tuple(s / n for s in sums)
        currents = tuple((c - ident.pedestal_counts) * a for c, a in zip(counts, ident.amperes_per_count))
        saturated = tuple(bool(flags >> k & 1) or counts[k] >= full for k in range(4))
        under = tuple(bool(flags >> (k + 4) & 1) or counts[k] <= 0 for k in range(4))
        return QuadrantReading(counts, currents, saturated, under, temperature / 100.0, int(n), int(counter))
