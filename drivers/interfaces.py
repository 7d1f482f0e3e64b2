"""The small interfaces the bench talks to: a rotary table, a sun simulator, a sun sensor.

Every concrete driver (Meade LX200, Thorlabs APT, Newport SMC100, manual axis; Oriel 69907, SCPI LED supply;
CMOS pinhole module, USB camera; quadrant-photodiode module; coarse-sun-sensor head) implements one of these, so
the run engine never knows which hardware — or which simulator — it drives.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .errors import DeviceFault, DeviceTimeout, LimitError


@dataclass(frozen=True)
class Limits:
    """Soft limits of one axis [°], checked before anything moves."""

    low_deg: float
    high_deg: float

    def __post_init__(self) -> None:
        if not self.low_deg < self.high_deg:
            raise ValueError(f"soft limits must satisfy low < high, got [{self.low_deg}, {self.high_deg}]")

    def check(self, device: str, angle_deg: float) -> None:
        if not np.isfinite(angle_deg) or not self.low_deg <= angle_deg <= self.high_deg:
            raise LimitError(device, f"{angle_deg}° is outside the soft limits [{self.low_deg}, {self.high_deg}]°")


@dataclass(frozen=True)
class AxisMotion:
    """How fast an axis moves, for estimating how long a plan takes.

    Attributes
    ----------
    rate_deg_s : float
        Top speed of a move [°/s].
    accel_deg_s2 : float or None
        Acceleration [°/s²]; None when the controller does not say.
    """

    rate_deg_s: float
    accel_deg_s2: float | None = None


class RotaryAxis(ABC):
    """One rotation axis of a bench table (Thorlabs APT stage, Newport SMC100, manual stage …).

    Units are degrees in the controller's coordinate (after homing, 0 is the home position).
    `limits` are the *software* soft limits of the bench, checked before any byte is sent.
    """

    name: str
    limits: Limits
    poll_s: float = 0.02

    def check(self, angle_deg: float) -> None:
        """Raise :class:`~drivers.errors.LimitError` if `angle_deg` is outside the soft limits."""
        self.limits.check(self.name, angle_deg)

    def move_to(self, angle_deg: float, *, wait: bool = True, timeout_s: float = 120.0) -> None:
        """Move to `angle_deg` [°]; checks the soft limits first. With `wait`, returns once stopped."""
        self.check(angle_deg)
        self._start_move(angle_deg)
        if wait:
            self.wait_until_stopped(timeout_s=timeout_s)

    @abstractmethod
    def _start_move(self, angle_deg: float) -> None:
        """Command the move; limits are already checked."""

    @abstractmethod
    def position_deg(self) -> float:
        """Measured position [°]."""

    @abstractmethod
    def is_moving(self) -> bool:
        """True while the axis moves, homes or settles."""

    @abstractmethod
    def stop(self) -> None:
        """Stop now."""

    @abstractmethod
    def home(self, *, wait: bool = True, timeout_s: float = 300.0) -> None:
        """Run the homing sequence."""

    @abstractmethod
    def identify(self) -> str:
        """Model, serial and firmware as the controller reports them."""

    def expected_motion(self) -> AxisMotion | None:
        """Speed and acceleration of the axis's moves, from the controller or its configuration; None when the
        axis cannot say (a manual stage). Used only for estimates: nothing moves."""
        return None

    def wait_until_stopped(self, *, timeout_s: float = 120.0) -> float:
        """Poll until the axis stops; a stalled axis that still answers raises :class:`DeviceTimeout`."""
        deadline = time.monotonic() + timeout_s
        while self.is_moving():
            if time.monotonic() > deadline:
                position = self.position_deg()
                self.stop()
                raise DeviceTimeout(self.name, f"still moving after {timeout_s} s (at {position:.4f}°): stalled?")
            time.sleep(self.poll_s)
        return self.position_deg()


class RotaryTable(ABC):
    """A two-axis bench table: azimuth (sensor turned about its boresight) and zenith stage angle Ω."""

    name: str

    @abstractmethod
    def check(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Raise :class:`LimitError` unless both angles are inside the soft limits."""

    @abstractmethod
    def move_to(self, azimuth_deg: float, zenith_deg: float, *, wait: bool = True, timeout_s: float = 120.0) -> None:
        """Move both axes; both limits are checked before either moves."""

    @abstractmethod
    def position(self) -> tuple[float, float]:
        """(azimuth_deg, zenith_deg) as measured."""

    @abstractmethod
    def is_moving(self) -> bool: ...

    @abstractmethod
    def stop(self) -> None: ...

    @abstractmethod
    def home(self) -> None: ...

    @abstractmethod
    def identify(self) -> str: ...

    def expected_motion(self) -> tuple[AxisMotion | None, AxisMotion | None]:
        """(azimuth, zenith) speed and acceleration of moves, each None when the table cannot say."""
        return None, None


class TwoAxisTable(RotaryTable):
    """A table made of two independent :class:`RotaryAxis` (two APT stages, two SMC100s, manual stages …)."""

    def __init__(self, azimuth: RotaryAxis, zenith: RotaryAxis, name: str = "table"):
        self.azimuth, self.zenith, self.name = azimuth, zenith, name

    def check(self, azimuth_deg: float, zenith_deg: float) -> None:
        self.azimuth.check(azimuth_deg)
        self.zenith.check(zenith_deg)

    def move_to(self, azimuth_deg, zenith_deg, *, wait=True, timeout_s=120.0):
        self.check(azimuth_deg, zenith_deg)
        self.azimuth.move_to(azimuth_deg, wait=False)
        self.zenith.move_to(zenith_deg, wait=False)
        if wait:
            self.azimuth.wait_until_stopped(timeout_s=timeout_s)
            self.zenith.wait_until_stopped(timeout_s=timeout_s)

    def position(self):
        return self.azimuth.position_deg(), self.zenith.position_deg()

    def is_moving(self):
        return self.azimuth.is_moving() or self.zenith.is_moving()

    def stop(self):
        errors = []
        for axis in (self.azimuth, self.zenith):  # try both even if one fails
            try:
                axis.stop()
            except Exception as exc:  # noqa: BLE001 - re-raised below
                errors.append(exc)
        if errors:
            raise errors[0]

    def home(self):
        self.azimuth.home(wait=False)
        self.zenith.home(wait=False)
        self.azimuth.wait_until_stopped(timeout_s=300.0)
        self.zenith.wait_until_stopped(timeout_s=300.0)

    def identify(self):
        return f"azimuth: {self.azimuth.identify()}; zenith: {self.zenith.identify()}"

    def expected_motion(self):
        return self.azimuth.expected_motion(), self.zenith.expected_motion()


@dataclass(frozen=True)
class SourceStatus:
    """State of a sun simulator.

    Attributes
    ----------
    lamp_on : bool
    warm : bool
        Output has settled after ignition / switch-on.
    shutter_open : bool
    fault : bool
        The supply reports a fault or an interlock.
    output : float
        Output as the supply reports it, in its unit (`output_unit`).
    output_unit : str
    """

    lamp_on: bool
    warm: bool
    shutter_open: bool
    fault: bool
    output: float
    output_unit: str


class SunSimulator(ABC):
    """A sun simulator: a lamp (or LED) behind a shutter."""

    name: str

    @abstractmethod
    def lamp_on(self) -> None: ...

    @abstractmethod
    def standby(self) -> None:
        """Safe state between runs: shutter closed, lamp at standby (off or at its idle setting)."""

    @abstractmethod
    def lamp_off(self) -> None:
        """Put the light out without relying on the shutter: an arc lamp's supply stopped (the next run strikes
        it again and waits for its warm-up), an LED switched off. The fallback when the shutter cannot be
        closed; raises only when the lamp could not be switched off."""

    @abstractmethod
    def open_shutter(self) -> None: ...

    @abstractmethod
    def close_shutter(self) -> None: ...

    @abstractmethod
    def status(self) -> SourceStatus: ...

    @abstractmethod
    def identify(self) -> str: ...

    def wait_until_warm(self, *, timeout_s: float = 3600.0, poll_s: float = 0.5, pause=time.sleep) -> None:
        """Poll until the lamp is warm; a lamp fault raises :class:`DeviceFault`.

        `pause(poll_s)` waits between polls; a caller that must be able to cancel the wait (the run engine, on
        an abort) passes one that raises."""
        deadline = time.monotonic() + timeout_s
        while True:
            status = self.status()
            if status.fault:
                raise DeviceFault(self.name, "lamp fault while warming up")
            if status.warm:
                return
            if not status.lamp_on:
                raise DeviceFault(self.name, "lamp is off: it cannot warm up (switch it on first)")
            if time.monotonic() > deadline:
                raise DeviceTimeout(self.name, f"lamp not warm after {timeout_s} s")
            pause(poll_s)


@dataclass(frozen=True)
class SensorIdentity:
    model: str
    serial: str
    firmware: str


class ImageSensor(ABC):
    """A sun sensor that delivers frames (the CMOS pinhole module, a USB camera)."""

    name: str
    #: True when :meth:`identify`'s serial is the sensor's own (the run checks it is the sensor it expects)
    reports_serial: bool = False

    @abstractmethod
    def identify(self) -> SensorIdentity: ...

    @abstractmethod
    def set_exposure_ms(self, exposure_ms: float) -> None: ...

    @abstractmethod
    def exposure_ms(self) -> float: ...

    @abstractmethod
    def capture(self) -> np.ndarray:
        """One frame, 2-D uint16 [DN]."""

    @abstractmethod
    def temperature_c(self) -> float: ...


@dataclass(frozen=True)
class QuadrantReading:
    """One READ of a quadrant-photodiode sun sensor (seed 002): four photocurrents and the die temperature.

    Per-quadrant fields are in the order Q1, Q2, Q3, Q4 of seed 002's eq. 2.1: Q1 at (−x, −y), Q2 at (+x, +y),
    Q3 at (+x, −y), Q4 at (−x, +y) in the detector frame.

    Attributes
    ----------
    counts : tuple of 4 float
        Mean raw ADC reading of each quadrant over the samples [counts].
    currents_a : tuple of 4 float
        The same as currents, pedestal removed [A]: photocurrent plus dark current (dark not removed).
    saturated : tuple of 4 bool
        A sample of the quadrant was at the ADC's full scale: its current is a lower bound.
    under_range : tuple of 4 bool
        A sample of the quadrant was at 0 counts.
    temperature_c : float
        Die temperature from the module's thermometer, mean over the read [°C].
    n_samples : int
        Samples averaged.
    sample_counter : int
        Samples the module has taken since power-up, this read's included.
    """

    counts: tuple[float, float, float, float]
    currents_a: tuple[float, float, float, float]
    saturated: tuple[bool, bool, bool, bool]
    under_range: tuple[bool, bool, bool, bool]
    temperature_c: float
    n_samples: int
    sample_counter: int

    @property
    def any_saturated(self) -> bool:
        return any(self.saturated)

    @property
    def total_a(self) -> float:
        """Sum of the four currents [A]."""
        return float(sum(self.currents_a))


@dataclass(frozen=True)
class TecStatus:
    """State of a sensor module's thermo-electric cooler.

    Attributes
    ----------
    enabled : bool
        The TEC regulates; when off the die drifts to ambient.
    setpoint_c : float or None
        Regulation setpoint [°C]; None when the TEC is off.
    temperature_c : float
        Die temperature now [°C].
    settled : bool
        The die is within the module's tolerance of the setpoint (or of ambient, TEC off).
    """

    enabled: bool
    setpoint_c: float | None
    temperature_c: float
    settled: bool


class QuadrantSensor(ABC):
    """A sun sensor that delivers four photocurrents (the quadrant-photodiode module of seed 002)."""

    name: str
    #: True when :meth:`identify`'s serial is the sensor's own (the run checks it is the sensor it expects)
    reports_serial: bool = False

    @abstractmethod
    def identify(self) -> SensorIdentity: ...

    @abstractmethod
    def read(self, average: int = 1) -> QuadrantReading:
        """One reading, the mean of `average` samples."""

    @abstractmethod
    def set_temperature_setpoint_c(self, setpoint_c: float | None) -> TecStatus:
        """Regulate the die at `setpoint_c` [°C]; None switches the TEC off."""

    @abstractmethod
    def temperature_status(self) -> TecStatus: ...

    def temperature_setpoint_c(self) -> float | None:
        """The TEC setpoint [°C]; None when the TEC is off."""
        return self.temperature_status().setpoint_c

    def temperature_c(self) -> float:
        """Die temperature [°C]."""
        return self.temperature_status().temperature_c


@dataclass(frozen=True)
class CssHeadReading:
    """One READ of a coarse-sun-sensor head (seed 000): one signal per detector, and the head's temperature.

    Per-channel fields are in the head's channel order (``channels``): ``<face>_<type>``, face-major — faces px,
    py, mx, my, pz, mz (outward normals +X, +Y, −X, −Y, +Z, −Z; the thesis' faces 1 … 6), types uv (EPD-365 UV
    photodiode), vis (BPW 21 visible photodiode), ir (TPS 230 thermopile) within each face (drivers.css_protocol).

    Attributes
    ----------
    channels : tuple of 18 str
        ``px_uv``, ``px_vis``, ``px_ir``, ``py_uv`` … ``mz_ir``.
    counts : tuple of 18 float
        Mean raw ADC reading of each channel over the samples [counts].
    signals : tuple of 18 float
        The same, pedestal removed and converted: photocurrent [A] for uv and vis, voltage [V] for ir. Offsets
        (dark current, front-end offset, the thermopile's scene) are *not* removed: that is the calibration's job.
    saturated : tuple of 18 bool
        A sample of the channel was at the ADC's full scale: its signal is a lower bound.
    under_range : tuple of 18 bool
        A sample of the channel was at 0 counts: its signal is an upper bound.
    temperature_c : float
        Head temperature from the module's thermometer, mean over the read [°C].
    n_samples : int
        Samples averaged.
    sample_counter : int
        Samples the module has taken since power-up, this read's included.
    plate_on : bool
        The head's thermal plate was regulating.
    plate_settled : bool
        The head was within the module's tolerance of the plate's setpoint.
    """

    channels: tuple[str, ...]
    counts: tuple[float, ...]
    signals: tuple[float, ...]
    saturated: tuple[bool, ...]
    under_range: tuple[bool, ...]
    temperature_c: float
    n_samples: int
    sample_counter: int
    plate_on: bool = False
    plate_settled: bool = False

    @property
    def any_saturated(self) -> bool:
        return any(self.saturated)

    @property
    def units(self) -> tuple[str, ...]:
        """The unit of each signal: "A" (uv, vis photodiodes) or "V" (ir thermopile)."""
        return tuple("V" if name.endswith("_ir") else "A" for name in self.channels)

    def signal(self, channel: str) -> float:
        """The signal of `channel` (``"px_vis"`` …) [A or V]; KeyError naming the channels otherwise."""
        try:
            return self.signals[self.channels.index(channel)]
        except ValueError:
            raise KeyError(f"no channel {channel!r} (channels: {', '.join(self.channels)})") from None

    def as_dict(self) -> dict[str, float]:
        """Channel name → signal [A or V], in channel order."""
        return dict(zip(self.channels, self.signals))


class CoarseSunHead(ABC):
    """A coarse sun sensor head that delivers one signal per detector (the UV/visible/IR cube of seed 000) and has
    a thermal plate that holds its temperature."""

    name: str
    #: True when :meth:`identify`'s serial is the sensor's own (the run checks it is the sensor it expects)
    reports_serial: bool = False

    @abstractmethod
    def identify(self) -> SensorIdentity: ...

    @abstractmethod
    def read(self, average: int = 16) -> CssHeadReading:
        """One reading, the mean of `average` samples of every channel (16: the thesis' ADC averaging)."""

    @abstractmethod
    def set_temperature_setpoint_c(self, setpoint_c: float | None) -> TecStatus:
        """Regulate the head at `setpoint_c` [°C]; None switches the thermal plate off."""

    @abstractmethod
    def temperature_status(self) -> TecStatus: ...

    def temperature_setpoint_c(self) -> float | None:
        """The plate's setpoint [°C]; None when it is off."""
        return self.temperature_status().setpoint_c

    def temperature_c(self) -> float:
        """Head temperature [°C]."""
        return self.temperature_status().temperature_c


@dataclass(frozen=True)
class HorizonScan:
    """One revolution of a dual-cone scanning Earth-horizon sensor (seed 004), as the module reports it.

    Times are measured by the module from its index mark (the scan's phase reference, δ = 0 towards body +z in
    the package's conventions, calibration/horizon/__init__.py), so a phase is ``360° · t / period_s``; the
    module's locator is the normalised constant-threshold one (seed 004 eq. 2.1) with linear interpolation
    between samples.

    Attributes
    ----------
    revolution : int
        The module's revolution counter (revolutions since power-up; a gap means revolutions were skipped).
    period_s : float
        This revolution's period, index mark to index mark, as the module measured it [s].
    t_out_s : (float, float)
        Per cone (1, 2): time after the index mark of the falling edge (Earth → space) [s]; NaN when the
        module found none.
    t_in_s : (float, float)
        Per cone: time after the index mark of the rising edge (space → Earth) [s]; NaN when none.
    level_space, level_earth : (float, float)
        Per cone: the pulse's space (low) and Earth (high) levels the locator normalised with [counts].
    temperature_c : float
        The head's temperature [°C].
    saturated : (bool, bool)
        Per cone: a sample of the pulse was at the ADC's full scale (something far hotter than the Earth, a
        blinding source, was in view): its edges are not to be trusted.
    """

    revolution: int
    period_s: float
    t_out_s: tuple[float, float]
    t_in_s: tuple[float, float]
    level_space: tuple[float, float]
    level_earth: tuple[float, float]
    temperature_c: float
    saturated: tuple[bool, bool] = (False, False)

    @property
    def phase_out_deg(self) -> tuple[float, float]:
        """Per cone: the falling edge's phase, 360° · t_out / period [°] (NaN when not found)."""
        return tuple(360.0 * t / self.period_s for t in self.t_out_s)  # type: ignore[return-value]

    @property
    def phase_in_deg(self) -> tuple[float, float]:
        """Per cone: the rising edge's phase, 360° · t_in / period [°] (NaN when not found)."""
        return tuple(360.0 * t / self.period_s for t in self.t_in_s)  # type: ignore[return-value]

    @property
    def valid(self) -> tuple[bool, bool]:
        """Per cone: both edges were found and the pulse was not saturated."""
        return tuple(bool(np.isfinite(o) and np.isfinite(i) and not s)  # type: ignore[return-value]
                     for o, i, s in zip(self.t_out_s, self.t_in_s, self.saturated))


@dataclass(frozen=True)
class HorizonPulse:
    """The last revolution's sampled pulse of each cone, for the live view (decimated by the module).

    Attributes
    ----------
    period_s : float
        The revolution's period [s]; sample j of N lies at ``j · period_s / N`` after the index mark.
    samples : ndarray, shape (2, N)
        The detector's level per cone [counts].
    threshold : ndarray, shape (2,)
        The level the locator compared against per cone [counts].
    """

    period_s: float
    samples: np.ndarray
    threshold: np.ndarray

    @property
    def phase_deg(self) -> np.ndarray:
        """The phase of each sample [°], shape (N,)."""
        return np.arange(self.samples.shape[1]) * 360.0 / self.samples.shape[1]


class HorizonSensor(ABC):
    """A scanning Earth-horizon sensor (seed 004's dual-cone scanner): horizon crossing times per revolution."""

    name: str
    #: True when :meth:`identify`'s serial is the sensor's own (the run checks it is the sensor it expects)
    reports_serial: bool = False

    @abstractmethod
    def identify(self) -> SensorIdentity: ...

    @abstractmethod
    def read_scans(self, n: int = 1) -> list[HorizonScan]:
        """The next `n` complete revolutions (blocks about `n` scan periods)."""

    @abstractmethod
    def pulse(self) -> HorizonPulse:
        """The last revolution's sampled pulse per cone."""

    @abstractmethod
    def temperature_c(self) -> float:
        """The head's temperature [°C]."""


class EarthSimulator(SunSimulator):
    """An IR Earth simulator as the bench's source: a warm disc (heater) behind an iris, a cold cover before it.

    As a :class:`SunSimulator`: ``lamp_on`` = heater on to the disc setpoint, ``status().warm`` = the disc's
    temperature has settled, ``open_shutter``/``close_shutter`` = the cold cover, ``standby`` = cover closed and
    heater at its standby setpoint, ``lamp_off`` = heater off. The iris sets the disc's angular radius.

    Its two motions (the iris, the cover) take seconds to a minute, so each can be started without waiting
    (``wait=False``) and polled (:meth:`disc_settled`, :meth:`cover_state`): the run engine starts a motion under its
    lock and waits for it outside, so an emergency stop never waits for an iris or a cover.

    Attributes
    ----------
    cover_timeout_s : float
        How long the cover may take to open or close before it counts as stuck [s].
    """

    cover_timeout_s: float

    @property
    @abstractmethod
    def radius_limits_deg(self) -> tuple[float, float]:
        """The iris's soft limits (low, high) [°]: the disc radii the bench allows."""

    def check_disc_radius(self, radius_deg: float) -> None:
        """Raise :class:`~drivers.errors.LimitError` for a disc radius outside :attr:`radius_limits_deg` (as
        :meth:`set_disc_radius_deg` would, before anything is sent); a preflight checks a plan's radii with it."""
        Limits(*self.radius_limits_deg).check(self.name, radius_deg)

    @abstractmethod
    def set_disc_radius_deg(self, radius_deg: float, *, wait: bool = True, timeout_s: float | None = None) -> None:
        """Move the iris to `radius_deg` [°]; the soft limits are checked first (:class:`~drivers.errors.LimitError`,
        nothing sent). With `wait`, returns once it has settled (:meth:`disc_settled`), and a move not done within
        `timeout_s` (default: the driver's, from :meth:`expected_iris_move_s`) raises
        :class:`~drivers.errors.DeviceTimeout`; without, returns once the move is started."""

    @abstractmethod
    def expected_iris_move_s(self, radius_deg: float) -> float:
        """How long a move from where the iris stands to `radius_deg` should take [s]."""

    @abstractmethod
    def stop_iris(self) -> None:
        """Stop the iris where it is (its target becomes its position)."""

    @abstractmethod
    def open_shutter(self, *, wait: bool = True, timeout_s: float | None = None) -> None:
        """Open the cold cover; with `wait`, return once it reads OPEN (a cover stuck past `timeout_s`, default
        :attr:`cover_timeout_s`, raises :class:`~drivers.errors.DeviceFault`); without, once it is told to open."""

    @abstractmethod
    def cover_state(self) -> str:
        """The cold cover: ``"OPEN"``, ``"CLOSED"`` or ``"MOVING"``."""

    @abstractmethod
    def disc_radius_deg(self) -> float:
        """The disc's angular radius as the iris reports it [°]."""

    @abstractmethod
    def disc_settled(self) -> bool:
        """The iris has stopped, at its target (within the driver's tolerance): a controller that reports its motion
        late must not end a wait at once."""

    @abstractmethod
    def set_disc_temperature_k(self, kelvin: float) -> None:
        """The heater's setpoint for the disc [K] (used from the next :meth:`lamp_on`, at once when on)."""

    @abstractmethod
    def disc_temperature_k(self) -> float:
        """The disc's measured temperature [K]."""
