"""Driver of the scanning Earth-horizon sensor module (seed 004), over the framed protocol of
:mod:`drivers.horizon_protocol`.

Replies are checked, and a bad exchange is raised as a typed error and asked again, by
:class:`~drivers.framed_protocol.FramedModule`: every command of this module is safe to repeat (READ_SCANS reports
fresh revolutions; SET_THRESHOLD sets an absolute value). An error frame from the module is a
:class:`HorizonSensorError` with its code; a motor that does not turn (no index mark) is its subclass
:class:`MotorStalled`.

Times come as integer microseconds from the revolution's index mark; :class:`~drivers.interfaces.HorizonScan` holds
them in seconds, NaN where the module found no edge (its flag clear). Nothing is corrected here (the cone angles, the
phase reference, the locator's threshold bias and the detector's lag are the calibration's job).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import horizon_protocol as wire
from .errors import LimitError
from .framed_protocol import FramedModule, ModuleError
from .interfaces import HorizonPulse, HorizonScan, HorizonSensor, SensorIdentity
from .transport import DEFAULT_RETRIES, Port


class HorizonSensorError(ModuleError):
    """The module answered with an error frame; `code` is its error code."""

    def __init__(self, device: str, code: int, message: str):
        super().__init__(device, code, message)
        if code in wire.ERROR_MESSAGES:  # the module's own codes, beyond the shared ones
            text = f"{device}: module error {code} ({wire.ERROR_MESSAGES[code]}): {message}"
            self.args = (text,)

    def __new__(cls, device: str, code: int, message: str):
        # the module's "no index mark" is a stalled motor: its own type, so a caller can tell it apart
        if cls is HorizonSensorError and code == wire.NO_INDEX:
            cls = MotorStalled
        return super().__new__(cls)


class MotorStalled(HorizonSensorError):
    """Error 6: no index mark within two nominal periods — the scan motor does not turn."""


@dataclass(frozen=True)
class HorizonIdentity(SensorIdentity):
    """What IDENTIFY reports, beyond model, serial and firmware.

    Attributes
    ----------
    cones : int
        Scan cones (2: the dual-cone scanner).
    adc_bits : int
    samples_per_revolution : int
        Samples of each cone's detector per revolution.
    nominal_period_s : float
        The scan period the motor is regulated to [s] (1 s: seed 004's 1 rev/s).
    gamma_deg : float
        The nominal half-cone angle γ [°] (the built one differs: the calibration measures it).
    ifov_half_angle_deg : float
        The detector's instantaneous field of view, half-angle [°].
    threshold : float
        The locator's threshold C1 as a fraction of the pulse (seed 004 eq. 2.1).
    max_scans : int
        The most revolutions one READ_SCANS returns.
    """

    cones: int
    adc_bits: int
    samples_per_revolution: int
    nominal_period_s: float
    gamma_deg: float
    ifov_half_angle_deg: float
    threshold: float
    max_scans: int

    @property
    def full_scale_counts(self) -> int:
        return (1 << self.adc_bits) - 1


@dataclass(frozen=True)
class HorizonStatus:
    """GET_STATUS: the threshold C1, the head's temperature [°C], whether the motor turns, the revolution counter
    and the last revolution's period [s]."""

    threshold: float
    temperature_c: float
    motor_turning: bool
    revolution: int
    period_s: float


def _f32(value: float) -> float:
    return float(np.float32(value))


class HorizonSensorModule(FramedModule, HorizonSensor):
    """The dual-cone scanning Earth-horizon sensor module.

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=115200)`` (the module's UART adapter, or a simulator URL).
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
    module_error = HorizonSensorError

    def __init__(self, port: Port, *, retries: int = DEFAULT_RETRIES, name: str | None = None):
        self._attach(port, retries=retries, name=name)
        self._identity: HorizonIdentity | None = None

    # -- identity ---------------------------------------------------------------------------------------
    def identify(self) -> HorizonIdentity:
        """Model, serial, firmware and the module's design (kept: :meth:`read_scans` sizes its waits on it)."""
        fields = self._unpack(wire.IDENTITY, self._exchange(wire.IDENTIFY), "IDENTIFY")
        model, serial, firmware, cones, bits, samples, period_us, gamma, ifov, threshold, max_scans = fields
        if not (cones == wire.N_CONES and 8 <= bits <= 16 and samples >= 16 and period_us > 0
                and 0 < gamma < 90 and 0 < ifov < 30 and 0 < threshold < 1 and 1 <= max_scans):
            self._fail(f"IDENTIFY reply is not a dual-cone horizon sensor's: {cones} cones, {bits} bits, {samples} "
                       f"samples per revolution, period {period_us} us, gamma {gamma} deg, IFOV {ifov} deg, "
                       f"threshold {threshold}, up to {max_scans} scans per read", b"")
        self._identity = HorizonIdentity(wire.unpad(model), wire.unpad(serial), wire.unpad(firmware), int(cones),
                                         int(bits), int(samples), period_us / 1e6, float(gamma), float(ifov),
                                         float(threshold), int(max_scans))
        return self._identity

    @property
    def identity(self) -> HorizonIdentity:
        """The module's identity, asked for once."""
        return self._identity or self.identify()

    # -- scans ------------------------------------------------------------------------------------------
    def read_scans(self, n: int = 1) -> list[HorizonScan]:
        """The next `n` complete revolutions (several READ_SCANS when `n` exceeds the module's largest count).

        Each request waits about (count + 1) scan periods; its timeout allows twice that plus the port's."""
        if not (isinstance(n, (int, np.integer)) and n >= 1):
            raise LimitError(self.name, f"the number of revolutions must be a positive integer, got {n!r}")
        ident = self.identity
        scans: list[HorizonScan] = []
        while len(scans) < n:
            count = min(n - len(scans), ident.max_scans)
            timeout_s = self.port.timeout_s + 2.0 * (count + 1) * ident.nominal_period_s
            payload = self._exchange(wire.READ_SCANS, wire.READ_REQUEST.pack(count), timeout_s=timeout_s)
            scans += self._parse_scans(payload, count, ident)
        return scans

    def _parse_scans(self, payload: bytes, count: int, ident: HorizonIdentity) -> list[HorizonScan]:
        expected = wire.READ_HEAD.size + count * wire.SCAN.size
        if len(payload) != expected or payload[0] != count:
            self._fail(f"READ_SCANS reply of {len(payload)} bytes for {payload[0] if payload else 0} revolutions; "
                       f"{count} asked for ({expected} bytes)", payload[:64])
        out = []
        full = ident.full_scale_counts
        for i in range(count):
            revolution, period_us, *cones, centi = wire.SCAN.unpack_from(payload, wire.READ_HEAD.size
                                                                         + i * wire.SCAN.size)
            if period_us == 0:
                self._fail(f"READ_SCANS revolution {revolution} has a period of 0 us", payload[:64])
            t_out, t_in, space, earth, saturated = [], [], [], [], []
            for k in range(wire.N_CONES):
                out_us, in_us, flags, low, high = cones[5 * k: 5 * k + 5]
                if flags >> 3 or (flags & wire.EDGE_OUT and out_us >= period_us) \
                        or (flags & wire.EDGE_IN and in_us >= period_us) or max(low, high) > full:
                    self._fail(f"READ_SCANS revolution {revolution}, cone {k + 1}: flags 0x{flags:02X}, t_out "
                               f"{out_us} us, t_in {in_us} us, levels {low}, {high} in a period of {period_us} us",
                               payload[:64])
                t_out.append(out_us / 1e6 if flags & wire.EDGE_OUT else math.nan)
                t_in.append(in_us / 1e6 if flags & wire.EDGE_IN else math.nan)
                space.append(float(low))
                earth.append(float(high))
                saturated.append(bool(flags & wire.EDGE_SATURATED))
            out.append(HorizonScan(int(revolution), period_us / 1e6, tuple(t_out), tuple(t_in), tuple(space),
                                   tuple(earth), centi / 100.0, tuple(saturated)))
        return out

    def pulse(self) -> HorizonPulse:
        """The last reported revolution's pulse of both cones (decimated by the module) and its thresholds."""
        payload = self._exchange(wire.GET_PULSE)
        if len(payload) < wire.PULSE_HEAD.size:
            self._fail(f"GET_PULSE reply of {len(payload)} bytes", payload[:64])
        period_us, decimation, n, *threshold = wire.PULSE_HEAD.unpack_from(payload)
        if len(payload) != wire.PULSE_HEAD.size + 2 * wire.N_CONES * n or period_us == 0 or decimation == 0:
            self._fail(f"GET_PULSE reply of {len(payload)} bytes for {n} samples per cone, period {period_us} us, "
                       f"decimation {decimation}", payload[:64])
        samples = np.frombuffer(payload, dtype="<u2", offset=wire.PULSE_HEAD.size).reshape(wire.N_CONES, n)
        return HorizonPulse(period_us / 1e6, samples.astype(float), np.array(threshold, dtype=float))

    # -- settings and status ----------------------------------------------------------------------------
    def set_threshold(self, fraction: float) -> float:
        """Set the locator's threshold C1 (seed 004 eq. 2.1) as a fraction of the pulse; returns it as set.

        Outside [0.1, 0.9] it is refused before anything is sent."""
        low, high = wire.THRESHOLD_RANGE
        if not (math.isfinite(fraction) and low <= fraction <= high):
            raise LimitError(self.name, f"threshold {fraction} is outside [{low}, {high}]")
        (now,) = self._unpack(wire.THRESHOLD, self._exchange(wire.SET_THRESHOLD, wire.THRESHOLD.pack(fraction)),
                              "SET_THRESHOLD")
        if now != _f32(fraction):
            self._fail(f"SET_THRESHOLD to {fraction} answered {now}", b"")
        return float(now)

    def status(self) -> HorizonStatus:
        """GET_STATUS: threshold, temperature, motor, revolution counter, last period."""
        threshold, centi, motor, revolution, period_us = self._unpack(
            wire.STATUS, self._exchange(wire.GET_STATUS), "GET_STATUS")
        return HorizonStatus(float(threshold), centi / 100.0, bool(motor), int(revolution), period_us / 1e6)

    def threshold(self) -> float:
        """The locator's threshold C1 now."""
        return self.status().threshold

    def temperature_c(self) -> float:
        """The head's temperature [°C]."""
        return self.status().temperature_c
