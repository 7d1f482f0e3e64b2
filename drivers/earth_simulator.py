"""Driver of the IR Earth simulator (a heated disc behind an iris, a cold cover before it), the horizon bench's
source, over its SCPI-style line protocol (documented in :mod:`drivers.sim.earth_simulator`, whose simulator serves
it).

As a :class:`~drivers.interfaces.SunSimulator` (so the run engine's safety holds unchanged): ``lamp_on`` switches the
heater on to the disc setpoint, ``status().warm`` is "the disc's temperature has settled", the shutter is the cold
cover, ``standby`` closes the cover and sets the heater to its standby setpoint, ``lamp_off`` switches the heater
off. The iris sets the disc's angular radius (:meth:`EarthSimulatorSource.set_disc_radius_deg`).

Line framing as :mod:`drivers.scpi_supply`: commands end with LF, replies are read up to LF (a CR before it is
dropped). Every set is followed by ``SYST:ERR?`` read until empty; an entry raises :class:`EarthSimulatorError` with
its codes. Queries are asked again once after a garbled or cut reply (not ``SYST:ERR?``, which pops what it reads);
sets are never re-sent. Limits (the iris's soft limits, the heater's setpoints) are checked before anything is
sent; a motion (iris, cover) that does not finish within twice its expected time plus a margin raises a typed
error naming where it stopped. Either motion can be started without waiting (``wait=False``) and polled
(:meth:`EarthSimulatorSource.disc_settled`, :meth:`~EarthSimulatorSource.cover_state`), so the run engine never waits
for one with its lock held; ``IRIS:STOP`` stops the iris where it is (:meth:`~EarthSimulatorSource.stop_iris`). The
iris counts as settled once its controller says it stopped AND it reads within a tolerance of the target this driver
sent: a controller that raises its moving flag late cannot end a wait at once.

A client of other people's (PyVISA with pyvisa-py) reaches the simulator at ``TCPIP0::<host>::<port>::SOCKET`` with
read and write termination ``"\\n"`` (``sunbench sim`` prints it).
"""

from __future__ import annotations

import logging
import math
import time

from .errors import DeviceError, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from .interfaces import EarthSimulator, Limits, SourceStatus
from .scpi_protocol import NUMBER, ScpiError, ScpiErrorQueue
from .transport import Port, ask_again

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TERMINATOR = b"\n"
#: The iris's soft limits the bench allows by default [°]: the disc radii of altitudes from ~150 km to ~2000 km
#: (seed 004 eq. 2.3)
DEFAULT_RADIUS_LIMITS_DEG = (50.0, 78.0)
#: The heater setpoints the driver sends by default [K]
DEFAULT_TEMPERATURE_LIMITS_K = (230.0, 350.0)
DEFAULT_DISC_K = 290.0  # the disc's setpoint at lamp_on [K]: a warm Earth's 14–16 µm brightness temperature
DEFAULT_STANDBY_K = 260.0
MOTION_MARGIN_S = 5.0  # added to twice a motion's expected time before it counts as stuck [s]
#: How close to its target a stopped iris must read to count as settled [°]: the simulated controller takes a target
#: to 1e-4°; a real iris's deadband is of that order
DEFAULT_IRIS_TOLERANCE_DEG = 0.005

STATUS_HEATER, STATUS_SETTLED, STATUS_IRIS_MOVING, STATUS_COVER_OPEN = 0x01, 0x02, 0x04, 0x08
STATUS_COVER_MOVING, STATUS_HEATER_FAULT = 0x10, 0x20



class EarthSimulatorError(ScpiError):
    """The controller's error queue held entries after a command: `errors` [(code, text)], oldest first."""


class EarthSimulatorSource(ScpiErrorQueue, EarthSimulator):
    """The IR Earth simulator as the bench's source (module docstring).

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=9600)`` (the controller's RS-232, or a simulator URL).
    radius_limits_deg : (float, float)
        Soft limits of the disc's angular radius [°]; requests outside raise LimitError before anything is sent.
    temperature_limits_k : (float, float)
        Heater setpoints the bench allows [K].
    disc_temperature_k : float
        The disc's setpoint when the heater is on [K].
    standby_temperature_k : float
        The heater's setpoint in standby [K].
    retries : int
        How many times a query is asked again after a garbled or cut reply.
    poll_s : float
        Pause between polls while a motion runs [s].
    cover_timeout_s : float
        How long the cover may take to open or close before it counts as stuck [s].
    iris_tolerance_deg : float
        How close to its target the stopped iris must read to count as settled [°].
    pause : callable
        ``pause(poll_s)`` between polls (``time.sleep``; a test may pass one that counts).
    clock : callable
        The time [s] motion deadlines are measured on (``time.monotonic``).
    name : str
    """

    queue_error = EarthSimulatorError

    def __init__(self, port: Port, *, radius_limits_deg=DEFAULT_RADIUS_LIMITS_DEG,
                 temperature_limits_k=DEFAULT_TEMPERATURE_LIMITS_K, disc_temperature_k: float = DEFAULT_DISC_K,
                 standby_temperature_k: float = DEFAULT_STANDBY_K, retries: int = 1, poll_s: float = 0.05,
                 cover_timeout_s: float = 10.0, iris_tolerance_deg: float = DEFAULT_IRIS_TOLERANCE_DEG,
                 pause=time.sleep, clock=time.monotonic, name: str | None = None):
        self.port = port
        self.name = name or port.name
        self.radius_limits = Limits(*radius_limits_deg)
        low, high = temperature_limits_k
        if not (0 < low < high):
            raise ValueError(f"`temperature_limits_k` must satisfy 0 < low < high, got [{low}, {high}]")
        self.temperature_limits_k = (float(low), float(high))
        self.disc_setpoint_k = self._check_temperature(disc_temperature_k)
        self.standby_k = self._check_temperature(standby_temperature_k)
        self.retries = int(retries)
        self.poll_s = float(poll_s)
        self.cover_timeout_s = float(cover_timeout_s)
        if not (math.isfinite(iris_tolerance_deg) and iris_tolerance_deg > 0):
            raise ValueError(f"`iris_tolerance_deg` must be > 0, got {iris_tolerance_deg}")
        self.iris_tolerance_deg = float(iris_tolerance_deg)
        self.pause = pause
        self.clock = clock
        self._speed_deg_s: float | None = None
        self._iris_target_deg: float | None = None  # the radius this driver last sent; None: ask the controller

    # -- exchanges ------------------------------------------------------------------------------------------
    def _write(self, command: str) -> None:
        with self.port.transaction():
            self.port.discard_input()
            self.port.write(command.encode("ascii") + TERMINATOR)

    def _ask(self, command: str, parse=None, *, retry: bool = True):
        def attempt():
            reply = self.port.query(command.encode("ascii") + TERMINATOR, TERMINATOR)
            text = reply[:-1].removesuffix(b"\r").decode("ascii", errors="replace")
            return parse(command, text) if parse else text

        return ask_again(self.name, attempt, self.retries if retry else 0)

    def _float(self, command: str, text: str) -> float:
        if not NUMBER.match(text):
            raise ProtocolError(self.name, f"{command!r}: expected a number, got {text!r}")
        return float(text)

    def _pair(self, command: str, text: str) -> tuple[float, float]:
        parts = text.split(",")
        if len(parts) != 2:
            raise ProtocolError(self.name, f"{command!r}: expected <low>,<high>, got {text!r}")
        low, high = (self._float(command, p) for p in parts)
        return low, high

    def _flag(self, command: str, text: str) -> bool:
        if text not in ("0", "1"):
            raise ProtocolError(self.name, f"{command!r}: expected 0 or 1, got {text!r}")
        return text == "1"

    def _set(self, command: str) -> None:
        """Send a set and read the error queue empty; entries raise :class:`EarthSimulatorError`."""
        self._write(command)
        self.check_errors(command)

    def _check_temperature(self, kelvin: float) -> float:
        low, high = self.temperature_limits_k
        if not (math.isfinite(kelvin) and low <= kelvin <= high):
            raise LimitError(self.name, f"disc setpoint {kelvin} K is outside [{low}, {high}] K")
        return float(kelvin)

    def _wait(self, done, what: str, timeout_s: float, where, error: type[DeviceError] = DeviceTimeout) -> None:
        """Poll `done()` until true; past `timeout_s` raise `error` saying `what` and `where()` it stopped."""
        deadline = self.clock() + timeout_s
        while not done():
            if self.clock() > deadline:
                raise error(self.name, f"{what} not finished after {timeout_s:.1f} s ({where()}): stuck?")
            self.pause(self.poll_s)

    # -- identity -------------------------------------------------------------------------------------------
    def identify(self) -> str:
        """``*IDN?`` → maker, model, serial, firmware."""
        def parse(command, text):
            if text.count(",") != 3 or not text.isprintable():
                raise ProtocolError(self.name, f"{command!r}: expected four comma-separated fields, got {text!r}")
            return text
        return self._ask("*IDN?", parse)

    # -- the heater (the "lamp") ----------------------------------------------------------------------------
    def lamp_on(self) -> None:
        """Heater to the disc setpoint, then on; a heater fault raises :class:`DeviceFault` first."""
        if self.status_word() & STATUS_HEATER_FAULT:
            raise DeviceFault(self.name, "cannot switch the heater on: heater fault")
        self._set(f"HEAT:TEMP {self.disc_setpoint_k:.3f}")
        self._set("HEAT ON")

    def lamp_off(self) -> None:
        """Heater off, then close the cover if it does (a cover that fails is logged: the disc cools anyway)."""
        self._set("HEAT OFF")
        try:
            self.close_shutter()
        except Exception as exc:  # noqa: BLE001 - see the docstring
            log.warning("%s: heater off, but the cover did not close: %s", self.name, exc)

    def standby(self) -> None:
        """Close the cover, and hold the disc at the standby setpoint (heater on unless it is faulted)."""
        self.close_shutter()
        self._set(f"HEAT:TEMP {self.standby_k:.3f}")

    def set_disc_temperature_k(self, kelvin: float) -> None:
        """The disc's setpoint [K]: sent at once, and used by the next :meth:`lamp_on`."""
        self.disc_setpoint_k = self._check_temperature(kelvin)
        self._set(f"HEAT:TEMP {self.disc_setpoint_k:.3f}")

    def disc_temperature_k(self) -> float:
        """The disc's measured temperature [K] (``MEAS:TEMP?``)."""
        return self._ask("MEAS:TEMP?", self._float)

    def background_temperature_k(self) -> float:
        """The cold background's temperature [K] (``MEAS:BACK?``)."""
        return self._ask("MEAS:BACK?", self._float)

    # -- the cover (the "shutter") --------------------------------------------------------------------------
    def _cover(self, state: str, *, timeout_s: float | None, wait: bool = True) -> None:
        timeout_s = self.cover_timeout_s if timeout_s is None else timeout_s
        self._set(f"COV {'OPEN' if state == 'OPEN' else 'CLOS'}")
        if wait:
            self._wait(lambda: self.cover_state() == state, f"cover {'opening' if state == 'OPEN' else 'closing'}",
                       timeout_s, lambda: f"the cover reads {self.cover_state()}", DeviceFault)

    def open_shutter(self, *, wait: bool = True, timeout_s: float | None = None) -> None:
        """Open the cold cover; with `wait`, until it reads OPEN (a stuck cover raises :class:`DeviceFault`), without,
        return once it is told to (then poll :meth:`cover_state`)."""
        self._cover("OPEN", timeout_s=timeout_s, wait=wait)

    def close_shutter(self, *, timeout_s: float | None = None) -> None:
        """Close the cold cover and wait until it reads CLOSED (a stuck cover raises :class:`DeviceFault`)."""
        self._cover("CLOSED", timeout_s=timeout_s)

    def cover_state(self) -> str:
        """OPEN, CLOSED or MOVING (``COV?``)."""
        def parse(command, text):
            if text not in ("OPEN", "CLOSED", "MOVING"):
                raise ProtocolError(self.name, f"{command!r}: expected OPEN, CLOSED or MOVING, got {text!r}")
            return text
        return self._ask("COV?", parse)

    # -- status ---------------------------------------------------------------------------------------------
    def status_word(self) -> int:
        """``STAT?``: bit 0 heater on, 1 disc settled, 2 iris moving, 3 cover open, 4 cover moving, 5 heater
        fault."""
        def parse(command, text):
            if not text.isdigit() or int(text) > 0xFF:
                raise ProtocolError(self.name, f"{command!r}: expected a status word 0 … 255, got {text!r}")
            return int(text)
        return self._ask("STAT?", parse)

    def status(self) -> SourceStatus:
        """``lamp_on`` = heater on, ``warm`` = disc settled at the setpoint, ``shutter_open`` = cover open,
        ``fault`` = heater fault; ``output`` the disc's temperature [K]."""
        word = self.status_word()
        return SourceStatus(lamp_on=bool(word & STATUS_HEATER), warm=bool(word & STATUS_SETTLED),
                            shutter_open=bool(word & STATUS_COVER_OPEN), fault=bool(word & STATUS_HEATER_FAULT),
                            output=self.disc_temperature_k(), output_unit="K")

    # -- the iris -------------------------------------------------------------------------------------------
    def iris_speed_deg_s(self) -> float:
        """The iris's speed [°/s] (``IRIS:SPE?``, asked once); a speed that is not positive raises
        :class:`ProtocolError` (no move time can be told from it)."""
        if self._speed_deg_s is None:
            speed = self._ask("IRIS:SPE?", self._float)
            if not speed > 0:
                raise ProtocolError(self.name, f"'IRIS:SPE?': the iris's speed must be positive, the controller "
                                               f"answered {speed:g} deg/s")
            self._speed_deg_s = speed
        return self._speed_deg_s

    @property
    def radius_limits_deg(self) -> tuple[float, float]:
        """The iris's soft limits (low, high) [°] (the `radius_limits_deg` this driver was given)."""
        return self.radius_limits.low_deg, self.radius_limits.high_deg

    def iris_limits_deg(self) -> tuple[float, float]:
        """The iris's own limits [°] (``IRIS:LIM?``)."""
        return self._ask("IRIS:LIM?", self._pair)

    def expected_iris_move_s(self, radius_deg: float) -> float:
        """How long a move from where the iris stands to `radius_deg` should take [s] (speed only)."""
        return abs(radius_deg - self.disc_radius_deg()) / self.iris_speed_deg_s()

    def set_disc_radius_deg(self, radius_deg: float, *, wait: bool = True, timeout_s: float | None = None) -> None:
        """Move the iris to `radius_deg` [°]; soft limits first (:class:`LimitError`, nothing sent). With `wait`,
        returns once it has settled at the target; a move not done within `timeout_s` (default twice the expected
        time plus 5 s) raises :class:`DeviceTimeout` naming the iris's position."""
        self.radius_limits.check(self.name, radius_deg)
        if wait and timeout_s is None:
            timeout_s = 2.0 * self.expected_iris_move_s(radius_deg) + MOTION_MARGIN_S
        self._iris_target_deg = None  # unknown until the controller has taken it
        self._set(f"IRIS {radius_deg:.4f}")
        self._iris_target_deg = float(radius_deg)
        if wait:
            self._wait(self.disc_settled, f"iris move to {radius_deg:.4f} deg", timeout_s,
                       lambda: f"at {self.disc_radius_deg():.4f} deg")

    def disc_radius_deg(self) -> float:
        """The disc's angular radius as the iris reports it [°] (``IRIS?``)."""
        return self._ask("IRIS?", self._float)

    def iris_target_deg(self) -> float:
        """The target the controller holds [°] (``IRIS:TARG?``)."""
        return self._ask("IRIS:TARG?", self._float)

    def disc_settled(self) -> bool:
        """The iris has stopped (``IRIS:MOV?`` is 0) and reads (``IRIS?``) within `iris_tolerance_deg` of its target:
        the radius this driver last sent, else (none sent, or stopped since) the one the controller holds."""
        if self._ask("IRIS:MOV?", self._flag):
            return False
        target = self._iris_target_deg if self._iris_target_deg is not None else self.iris_target_deg()
        return abs(self.disc_radius_deg() - target) <= self.iris_tolerance_deg

    def stop_iris(self) -> None:
        """Stop the iris where it is (``IRIS:STOP``: the controller's target becomes its position)."""
        self._iris_target_deg = None
        self._set("IRIS:STOP")
