"""Meade LX200 / Autostar alt-az mount used as the bench's two-axis rotary table (seed 002 §3.2.1).

Axis mapping
------------
* bench azimuth (sensor turned about its boresight) = mount **azimuth** (``:GZ#`` / ``:Sz``), [°];
* bench zenith-stage angle Ω = mount **altitude** (``:GA#`` / ``:Sa``), [°], signed.

The mount reports azimuth in [0, 360); soft limits may be given in any window (e.g. [-180, 180]): targets
are sent modulo 360 and readings are mapped back into the soft-limit window.

Device analysis (anchors-protocols §1; every fact below comes from there)
---------------------------------------------------------------------------
Line 9600 8N1, no handshake (§1.1). Commands are ASCII ``:``…``#`` except ACK, the bare byte 0x06 (§1.1).

=============  =======================================  ===============================================
command        reply                                    used for
=============  =======================================  ===============================================
``0x06``       ``A`` / ``L`` / ``P`` (``D`` downloader)  connection probe, alignment mode (§1.1, §1.3)
``:AA#``       nothing                                   set alt-az mode (§1.3)
``:GA#``       ``sDD*MM#`` or ``sDD*MM'SS#``              altitude (§1.2, §1.3)
``:GZ#``       ``DDD*MM#`` or ``DDD*MM'SS#``              azimuth (§1.2, §1.3)
``:U#``        nothing                                   toggle low/high precision (§1.2)
``:SasDD*MM#`` one char, no ``#``                        target altitude (§1.3, CONFLICT on the char)
``:SzDDD*MM#`` one char, no ``#``                        target azimuth (§1.3)
``:MA#``       one char, no ``#``                        slew to the alt-az target (§1.3, CONFLICT)
``:D#``        bars then ``#``; just ``#`` when done      slew in progress (§1.3)
``:Q#``        nothing                                   halt all slewing (§1.3)
``:GVP#``      ``<product>#``                            identify (§1.3)
``:GVN#``      ``<firmware>#``                           identify (§1.3)
=============  =======================================  ===============================================

Wire facts the parser honours: the degree sign ``*`` is byte 0xDF on the wire; the seconds separator is
``'`` in the manual but ``:`` on a real LX200GPS, so any of ``*``, 0xDF, ``:``, ``'`` separates fields
(§1.1). A busy LX200GPS may answer NAK 0x15 instead, within 10 ms of the ``#`` (§1.1); the driver waits and
resends a bounded number of times, then raises :class:`MountBusy`.

Protocol decisions of this driver (see also :data:`OK_CHARS`)
-------------------------------------------------------------
* Completion: :meth:`LX200Table.is_moving` uses the ``:D#`` distance bars, not position polling. A stalled
  mount that still answers keeps showing its bar, so the wait ends in :class:`~drivers.errors.DeviceTimeout`
  instead of accepting a frozen position as "arrived"; and one query per poll is enough. Because the bar
  format varies by model (§1.3), any non-space byte before ``#`` counts as a bar, and after the bars clear
  the driver checks the position against the target (§1.3 "poll position until within tolerance"): a mount
  that stopped short (limit, obstruction) raises :class:`~drivers.errors.DeviceFault`.
* The ``:MA#`` reply is read as the ``slew_reply`` option says: Rev L's (``0`` = no fault, the default), INDI's
  (``1`` = slewing; what the simulator answers in its ``indi_compatible`` mode) or ``"auto"``, which takes
  either character and judges the slew by the ``:D#`` bars or, once they are gone, by the position at the
  target. The bench (``bench/hardware.py``) uses ``"auto"``, so it drives a mount of either kind.
* Targets are sent in the current precision (``sDD*MM`` low, ``sDD*MM'SS`` high, as Rev L lists for
  ``:Sa``), with an ASCII ``*`` as degree sign like INDI; ``:Sz`` with seconds is UNCONFIRMED (Rev L shows
  only ``DDD*MM``), so a mount that refuses it can be driven in low precision (``high_precision=False``).
* A reply that arrived garbled or cut short (bytes received, frame not parsable) is re-queried once
  (``retries``): every query and set command used here is idempotent. A silent device is not retried (it
  would only double the wait), nor is a command without a reply (``:U#`` toggles). A truncated frame ends
  in :class:`~drivers.errors.DeviceTimeout` carrying the partial bytes (the base class's meaning of a
  timeout); a complete but unparsable one in :class:`~drivers.errors.ProtocolError` with the bytes.
"""

from __future__ import annotations

import logging
import math
import re
import time

from .errors import DeviceFault, DeviceTimeout, ProtocolError
from .interfaces import AxisMotion, Limits, RotaryTable
from .transport import Port

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

ACK = b"\x06"
NAK = b"\x15"
DEGREE_SIGN = "\xdf"  # what the mount sends for '*' (anchors-protocols §1.1); latin-1 encodes it as 0xDF
SEPARATORS = "*\xdf:'"  # any of these separates degrees, minutes, seconds (anchors-protocols §1.1)
ALIGNMENT_MODES = {"A": "alt-az", "L": "land", "P": "polar", "D": "firmware downloader"}

#: Reply character meaning "accepted / no fault" for each set or slew command (the frame body without
#: ``:`` and ``#``). Any other ``0``/``1`` is a refusal. The driver and the simulator both read this one
#: table so the pair stays consistent until real hardware settles it.
#:
#: CONFLICT (anchors-protocols §1.3, §7 q2): for ``:Sa`` Meade Rev L says ``0`` = within slew range while
#: INDI and python-lx200 take ``1`` = accepted; for ``:MA#`` Rev L and python-lx200 say ``0`` = no fault
#: while INDI treats ``0`` as failure. Defaults follow the research note's recommendation: ``:Sa`` → ``1``
#: (INDI), ``:Sz`` → ``1`` (Rev L and INDI agree), ``:MA#`` → ``0`` (Rev L). A refusal message names the
#: table, so a mount that disagrees is fixed here, in one place.
OK_CHARS: dict[str, bytes] = {"Sa": b"1", "Sz": b"1", "MA": b"0"}

#: The ok characters INDI's LX200 drivers expect (indi-bin 1.9.9, ``lx200driver.cpp``: ``setStandardProcedure``
#: reads one byte and takes ``0`` as failure, anything else as success; ``slewToAltAz`` sends ``:MA#`` through
#: it). They differ from :data:`OK_CHARS` on ``:MA#`` only: Rev L's ``0`` = no fault reads as "slew is not
#: possible" in INDI. The simulator answers from this table in its ``indi_compatible`` mode.
INDI_OK_CHARS: dict[str, bytes] = {**OK_CHARS, "MA": b"1"}

#: How :class:`LX200Table` reads the ``:MA#`` reply (its ``slew_reply`` option): ``"manual"`` with
#: :data:`OK_CHARS`, ``"indi"`` with :data:`INDI_OK_CHARS`, ``"auto"`` from what the mount does.
SLEW_REPLIES = ("manual", "indi", "auto")


def refusal_char(command: str, table: dict[str, bytes] = OK_CHARS) -> bytes:
    """The reply character that means "refused / fault" for `command` (a key of :data:`OK_CHARS`) in `table`."""
    return b"0" if table[command] == b"1" else b"1"


class MountBusy(DeviceTimeout):
    """The mount kept answering NAK (0x15, busy) after every retry (anchors-protocols §1.1)."""


# -- sexagesimal angles (pure) -----------------------------------------------------------------------------
_SEXAGESIMAL = re.compile(r"([+-]?)(\d{1,3})[*\xdf:'](\d{1,2})(?:[*\xdf:'](\d{1,2}(?:\.\d+)?))?")


def _split(text: bytes | str, signed: bool | None, degree_digits: int | None):
    if isinstance(text, (bytes, bytearray)):
        text = bytes(text).decode("latin-1")  # 0xDF stays one character
    body = text[:-1] if text.endswith("#") else text
    match = _SEXAGESIMAL.fullmatch(body)
    if not match:
        raise ValueError(f"not a sexagesimal angle: {text!r}")
    sign, degrees, minutes, seconds = match.groups()
    if signed is True and not sign:
        raise ValueError(f"expected a sign: {text!r}")
    if signed is False and sign:
        raise ValueError(f"expected no sign: {text!r}")
    if degree_digits is not None and len(degrees) != degree_digits:
        raise ValueError(f"expected {degree_digits} degree digits: {text!r}")
    if int(minutes) >= 60 or (seconds is not None and float(seconds) >= 60):
        raise ValueError(f"minutes or seconds out of range: {text!r}")
    return sign, degrees, minutes, seconds


def parse_sexagesimal(text: bytes | str, *, signed: bool | None = None, degree_digits: int | None = None) -> float:
    """Parse ``sDD*MM``, ``sDD*MM'SS``, ``DDD*MM#`` … into degrees.

    Any of ``*``, 0xDF, ``:``, ``'`` separates the fields and one trailing ``#`` is ignored
    (anchors-protocols §1.1 parser rule). The sign applies to the whole angle, so ``-00*30`` is −0.5°
    (the negative-zero case INDI special-cases, anchors-protocols §6.6e).

    Parameters
    ----------
    text : bytes or str
        The angle as the mount writes it (bytes are decoded as latin-1, so 0xDF is one character).
    signed : bool, optional
        True: a leading ``+``/``-`` is required (altitude); False: forbidden (azimuth); None: optional.
    degree_digits : int, optional
        Exact number of degree digits required (2 for altitude, 3 for azimuth); None: 1 to 3.

    Returns
    -------
    float
        The angle [°].

    Raises
    ------
    ValueError
        If `text` is not such an angle, or minutes or seconds are 60 or more.
    """
    sign, degrees, minutes, seconds = _split(text, signed, degree_digits)
    value = int(degrees) + int(minutes) / 60.0 + (float(seconds) / 3600.0 if seconds is not None else 0.0)
    return -value if sign == "-" else value


def has_seconds(text: bytes | str) -> bool:
    """True if `text` is a high-precision angle (with a seconds field), False for low precision.

    The precision mode of the mount shows in the reply format (anchors-protocols §1.2). Raises
    ``ValueError`` like :func:`parse_sexagesimal` if `text` is not an angle.
    """
    return _split(text, None, None)[3] is not None


def format_sexagesimal(angle_deg: float, *, high_precision: bool = False, signed: bool = True,
                       degree_digits: int = 2, degree_sign: str = "*", seconds_sign: str = "'") -> str:
    """Format an angle as ``sDD*MM`` (low precision) or ``sDD*MM'SS`` (high precision).

    The angle is rounded to the resolution first (1′ or 1″), then split, so 9.99999° never becomes
    ``09*60``. The sign is taken from the angle, not from the degrees, so −0.5° is ``-00*30``
    (anchors-protocols §6.6e); an angle that rounds to zero is ``+00*00``.

    Parameters
    ----------
    angle_deg : float
        Angle [°].
    high_precision : bool
        Include seconds (resolution 1″) instead of minutes only (resolution 1′) (anchors-protocols §1.2).
    signed : bool
        Write a leading ``+``/``-`` (altitude). Unsigned (azimuth) refuses negative angles.
    degree_digits : int
        Zero-padded width of the degrees field: 2 for altitude, 3 for azimuth.
    degree_sign, seconds_sign : str
        Separators: ``*`` or ``\\xdf`` after the degrees, ``'`` or ``:`` before the seconds.

    Returns
    -------
    str
        The formatted angle, without ``#`` (encode with latin-1 for the wire).

    Raises
    ------
    ValueError
        Non-finite angle, a negative unsigned angle, or degrees too wide for `degree_digits`.
    """
    if not math.isfinite(angle_deg):
        raise ValueError(f"`angle_deg` must be finite, got {angle_deg}")
    per_degree = 3600 if high_precision else 60
    units = round(abs(angle_deg) * per_degree)
    negative = angle_deg < 0 and units > 0
    if negative and not signed:
        raise ValueError(f"an unsigned angle cannot be negative, got {angle_deg}")
    degrees, rest = divmod(units, per_degree)
    if degrees >= 10**degree_digits:
        raise ValueError(f"{angle_deg}° does not fit {degree_digits} degree digits")
    text = f"{degrees:0{degree_digits}d}{degree_sign}"
    if high_precision:
        minutes, seconds = divmod(rest, 60)
        text += f"{minutes:02d}{seconds_sign}{seconds:02d}"
    else:
        text += f"{rest:02d}"
    return ("-" if negative else "+") + text if signed else text


def wrap_azimuth_deg(azimuth_deg: float) -> float:
    """Azimuth folded into [0, 360) [°], the mount's range."""
    return azimuth_deg % 360.0


# -- the driver ------------------------------------------------------------------------------------------
_NONE, _CHAR, _FRAME = "none", "char", "frame"  # reply kinds (anchors-protocols §1.1 "reply terminator")


class LX200Table(RotaryTable):
    """Meade LX200 / Autostar mount in alt-az mode as the bench's two-axis table (see the module docstring).

    No I/O happens in the constructor. Call :meth:`connect` once (ACK probe, alt-az mode, precision); a move
    before that detects the precision on its own.

    Parameters
    ----------
    port : Port
        Open port, e.g. ``open_port(url, baudrate=9600)`` (9600 8N1, anchors-protocols §1.1).
    azimuth_limits : Limits
        Soft limits of the bench azimuth = mount azimuth [°].
    zenith_limits : Limits
        Soft limits of the bench zenith-stage angle Ω = mount altitude [°], inside [-90, 90].
    name : str, optional
        Name in errors; default the port's name.
    high_precision : bool or None
        Precision :meth:`connect` switches to with ``:U#``: True = 1″ (default), False = 1′ (the 1-arc-minute
        table of seed 002), None = keep what the mount uses.
    degree_sign, seconds_sign : str
        Separators written in targets: ``*`` (as INDI sends) or ``\\xdf``; ``'`` (Rev L) or ``:``.
    nak_retries : int
        Resends after a NAK (busy) before :class:`MountBusy` is raised.
    nak_wait_s : float
        Wait after a NAK before resending [s].
    nak_window_s : float
        How long to listen for a NAK after a command that has no reply (``:U#``, ``:AA#``, ``:Q#``) [s];
        the LX200GPS sends it within 10 ms (anchors-protocols §1.1). 0 skips the check.
    retries : int
        Re-queries after a garbled or truncated reply (bytes arrived, nothing parsable).
    poll_s : float
        Interval of ``:D#`` polls while waiting for a move [s].
    arrival_tolerance_deg : float
        Largest difference between target and final reading accepted as arrived, per axis [°]; default 2′,
        twice the seed 002 table's 1′ pointing.
    home_deg : (float, float)
        (azimuth, zenith) pose that :meth:`home` moves to [°].
    slew_rate_deg_s, slew_accel_deg_s2 : float or None
        The mount's slew speed [°/s] and acceleration [°/s²] for duration estimates; the LX200 protocol cannot
        be asked for them (``:Sw`` only sets the largest rate on Autostar II mounts), so they are configured
        values; None = unknown.
    slew_reply : {"manual", "indi", "auto"}
        How the one-char reply to ``:MA#`` is read (the CONFLICT of :data:`OK_CHARS`): ``"manual"`` = Rev L,
        ``0`` no fault / ``1`` fault; ``"indi"`` = the reverse, as INDI expects and as the simulator answers
        in its ``indi_compatible`` mode (:data:`INDI_OK_CHARS`); ``"auto"`` takes either character and judges
        the slew by what the mount does: distance bars (``:D#``) or, once they are gone, the position at the
        target; a mount that neither moves nor is there refused (:class:`~drivers.errors.DeviceFault`). A mode
        that does not match the mount fails safe: a slew that started reads as refused (DeviceFault), and a
        refusal reads as "no fault" until the arrival check of :meth:`wait_until_stopped` raises.
    """

    def __init__(self, port: Port, azimuth_limits: Limits, zenith_limits: Limits, *, name: str | None = None,
                 high_precision: bool | None = True, degree_sign: str = "*", seconds_sign: str = "'",
                 nak_retries: int = 5, nak_wait_s: float = 0.05, nak_window_s: float = 0.015, retries: int = 1,
                 poll_s: float = 0.05, arrival_tolerance_deg: float = 2.0 / 60.0,
                 home_deg: tuple[float, float] = (0.0, 0.0), slew_rate_deg_s: float | None = None,
                 slew_accel_deg_s2: float | None = None, slew_reply: str = "manual"):
        if not (isinstance(azimuth_limits, Limits) and isinstance(zenith_limits, Limits)):
            raise TypeError("`azimuth_limits` and `zenith_limits` must be Limits")
        if zenith_limits.low_deg < -90 or zenith_limits.high_deg > 90:
            raise ValueError(f"`zenith_limits` (mount altitude) must lie in [-90, 90], got {zenith_limits}")
        if degree_sign not in ("*", DEGREE_SIGN) or seconds_sign not in ("'", ":"):
            raise ValueError("`degree_sign` must be '*' or '\\xdf' and `seconds_sign` \"'\" or ':'")
        if nak_retries < 0 or retries < 0 or nak_wait_s < 0 or nak_window_s < 0 or poll_s < 0:
            raise ValueError("retry counts, waits and poll interval must be >= 0")
        if not arrival_tolerance_deg > 0:
            raise ValueError(f"`arrival_tolerance_deg` must be > 0, got {arrival_tolerance_deg}")
        if slew_reply not in SLEW_REPLIES:
            raise ValueError(f"`slew_reply` must be one of {SLEW_REPLIES}, got {slew_reply!r}")
        self.port = port
        self.name = name or port.name
        self.azimuth_limits, self.zenith_limits = azimuth_limits, zenith_limits
        self.wanted_high_precision = high_precision
        self.degree_sign, self.seconds_sign = degree_sign, seconds_sign
        self.nak_retries, self.nak_wait_s, self.nak_window_s = nak_retries, nak_wait_s, nak_window_s
        self.retries, self.poll_s = retries, poll_s
        self.arrival_tolerance_deg = arrival_tolerance_deg
        self.home_deg = home_deg
        self.slew_rate_deg_s, self.slew_accel_deg_s2 = slew_rate_deg_s, slew_accel_deg_s2
        self.slew_reply = slew_reply
        self.ok_chars = INDI_OK_CHARS if slew_reply == "indi" else OK_CHARS
        self.high_precision: bool | None = None  # None until a :GA#/:GZ# reply shows the format
        self._target: tuple[float, float] | None = None  # (azimuth, zenith) of the move in progress
        self._sent_target: tuple[float, float] | None = None  # (azimuth, zenith) last sent with :Sz/:Sa

    # -- framing -----------------------------------------------------------------------------------------
    def _exchange_once(self, command: bytes, kind: str) -> bytes:
        """Send `command`, resend after NAK, return the raw reply (b"" for commands without one)."""
        with self.port.transaction():
            for attempt in range(self.nak_retries + 1):
                self.port.discard_input()  # a late NAK or a stale reply must not answer this command
                self.port.write(command)
                if kind == _NONE:
                    if not self.nak_window_s:
                        return b""
                    try:
                        first = self.port.read_exact(1, timeout_s=self.nak_window_s)
                    except DeviceTimeout:
                        return b""  # silence is the normal answer
                else:
                    first = self.port.read_exact(1)
                if first == NAK:
                    log.info("%s: NAK (busy) to %r, attempt %d", self.name, command, attempt + 1)
                    if attempt < self.nak_retries:
                        time.sleep(self.nak_wait_s)
                    continue
                if kind == _NONE:
                    raise ProtocolError(self.name, f"unexpected reply to {command!r}, which has none",
                                        received=first + self.port.discard_input())
                if kind == _CHAR or first == b"#":  # single char; or an empty frame (":D#" when done)
                    return first
                try:
                    return first + self.port.read_until(b"#")
                except DeviceTimeout as exc:
                    raise DeviceTimeout(self.name, f"reply to {command!r} not terminated by '#'",
                                        received=first + exc.received) from None
            raise MountBusy(self.name, f"busy (NAK) to {command!r} after {self.nak_retries + 1} attempts",
                            received=NAK)

    def _query(self, command: bytes, kind: str, parse=lambda reply: reply):
        """Exchange and parse; re-query after a garbled or truncated reply (see the module docstring)."""
        for attempt in range(self.retries + 1):
            try:
                reply = self._exchange_once(command, kind)
                try:
                    return parse(reply)
                except ValueError as exc:
                    raise ProtocolError(self.name, f"bad reply to {command!r}: {exc}", received=reply) from None
            except (ProtocolError, DeviceTimeout) as exc:
                # no retry: a silent device (nothing received), a busy one, or a command without a reply
                # (":U#" toggles, so sending it twice is not idempotent)
                if isinstance(exc, MountBusy) or not exc.received or kind == _NONE or attempt == self.retries:
                    raise
                log.warning("%s: retrying %r after %s", self.name, command, exc)
        raise AssertionError("unreachable")  # pragma: no cover

    def _set(self, command: str, argument: str = "") -> None:
        """Send a set/slew command whose reply is one char from :data:`OK_CHARS` (anchors-protocols §1.3)."""
        wire = f":{command}{argument}#".encode("latin-1")
        ok, refused = self.ok_chars[command], refusal_char(command, self.ok_chars)

        def parse(reply: bytes) -> bytes:
            if reply not in (ok, refused):
                raise ValueError(f"expected {ok!r} (ok) or {refused!r} (refused)")
            return reply

        if self._query(wire, _CHAR, parse) == refused:
            log.warning("%s: %r answered %r", self.name, wire, refused)  # verbatim, for the OK_CHARS conflict
            table = "OK_CHARS" if self.ok_chars is OK_CHARS else "INDI_OK_CHARS"
            raise DeviceFault(self.name, f"mount refused {wire!r} (reply {refused!r}; ok is {ok!r} in "
                                         f"drivers.meade.{table}, see the CONFLICT note of OK_CHARS)",
                              received=refused)

    def _string(self, command: bytes) -> str:
        return self._query(command, _FRAME).decode("latin-1")[:-1].strip()

    # -- connection, mode, precision -----------------------------------------------------------------
    def probe(self) -> str:
        """Get the alignment mode with ACK (0x06): ``A`` alt-az, ``L`` land, ``P`` polar, ``D`` downloader.

        Anchors-protocols §1.1: a single byte with no ``:``/``#``, answered by one char without ``#``.
        """
        def parse(reply: bytes) -> str:
            mode = reply.decode("latin-1")
            if mode not in ALIGNMENT_MODES:
                raise ValueError("expected one of A, L, P, D")
            return mode

        return self._query(ACK, _CHAR, parse)

    def set_alt_az_mode(self) -> None:
        """Set alt-az alignment with ``:AA#`` (no reply, anchors-protocols §1.3)."""
        self._query(b":AA#", _NONE)

    def connect(self) -> str:
        """Probe with ACK, switch to alt-az mode if needed, detect and set the precision.

        Returns
        -------
        str
            The alignment mode after connecting (``A``).

        Raises
        ------
        DeviceFault
            The firmware downloader is active, or the mount stays out of alt-az mode.
        """
        mode = self.probe()
        if mode == "D":
            raise DeviceFault(self.name, "the mount's firmware downloader is active")
        if mode != "A":
            log.info("%s: mount in %s mode, setting alt-az", self.name, ALIGNMENT_MODES[mode])
            self.set_alt_az_mode()
            mode = self.probe()
            if mode != "A":
                raise DeviceFault(self.name, f"mount stays in {ALIGNMENT_MODES[mode]} mode after :AA#")
        self.detect_precision()
        if self.wanted_high_precision is not None:
            self.set_precision(self.wanted_high_precision)
        return mode

    def detect_precision(self) -> bool:
        """Read ``:GA#`` and take the precision from its format; returns True for high precision."""
        self.altitude_deg()
        return self.high_precision

    def toggle_precision(self) -> None:
        """Send ``:U#`` (toggle low/high precision, no reply, anchors-protocols §1.2)."""
        known, self.high_precision = self.high_precision, None  # unknown if the exchange fails
        self._query(b":U#", _NONE)
        if known is not None:
            self.high_precision = not known

    def set_precision(self, high: bool) -> None:
        """Control the precision mode: True = ``sDD*MM'SS`` (1″), False = ``sDD*MM`` (1′).

        ``:U#`` only toggles, so the current mode is read first and the result is checked with ``:GA#``.
        """
        if self.high_precision is None:
            self.detect_precision()
        if self.high_precision == high:
            return
        self.toggle_precision()
        if self.detect_precision() != high:
            raise ProtocolError(self.name, f"precision did not change after :U# (still "
                                           f"{'high' if self.high_precision else 'low'})")

    # -- readings ----------------------------------------------------------------------------------------
    def _read_angle(self, command: bytes, signed: bool, degree_digits: int, low: float, high: float) -> float:
        def parse(reply: bytes) -> float:
            if not reply.endswith(b"#"):
                raise ValueError("no '#' terminator")
            value = parse_sexagesimal(reply, signed=signed, degree_digits=degree_digits)
            if not low <= value <= high:
                raise ValueError(f"{value}° outside [{low}, {high}]°")
            self.high_precision = has_seconds(reply)
            return value

        return self._query(command, _FRAME, parse)

    def altitude_deg(self) -> float:
        """Measure the mount altitude = bench zenith-stage angle Ω with ``:GA#`` [°]."""
        return self._read_angle(b":GA#", True, 2, -90.0, 90.0)

    def mount_azimuth_deg(self) -> float:
        """Measure the mount azimuth with ``:GZ#``, in [0, 360) as the mount reports it [°]."""
        return self._read_angle(b":GZ#", False, 3, 0.0, 360.0)

    def _unwrap_azimuth(self, azimuth_deg: float) -> float:
        for candidate in (azimuth_deg, azimuth_deg - 360.0, azimuth_deg + 360.0):
            if self.azimuth_limits.low_deg <= candidate <= self.azimuth_limits.high_deg:
                return candidate
        return azimuth_deg

    def position(self) -> tuple[float, float]:
        """Measure (azimuth_deg, zenith_deg) [°]: mount azimuth mapped into the soft-limit window, altitude."""
        return self._unwrap_azimuth(self.mount_azimuth_deg()), self.altitude_deg()

    def distance_bars(self) -> bytes:
        """Get the ``:D#`` distance bars, without the ``#`` (empty when no slew is in progress, §1.3)."""
        def parse(reply: bytes) -> bytes:
            if not reply.endswith(b"#"):
                raise ValueError("no '#' terminator")
            return reply[:-1]

        return self._query(b":D#", _FRAME, parse)

    def is_moving(self) -> bool:
        """True while ``:D#`` shows a bar: any non-space byte before ``#`` (INDI's rule, §1.3)."""
        return bool(self.distance_bars().strip(b" "))

    def identify(self) -> str:
        """Get the product name and firmware number (``:GVP#``, ``:GVN#``), e.g. ``"Autostar 43Eg"``."""
        return f"{self._string(b':GVP#')} {self._string(b':GVN#')}"

    # -- motion --------------------------------------------------------------------------------------------
    def check(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Raise :class:`~drivers.errors.LimitError` unless both angles are inside the soft limits."""
        self.azimuth_limits.check(f"{self.name} azimuth", azimuth_deg)
        self.zenith_limits.check(f"{self.name} zenith", zenith_deg)

    def _format(self, angle_deg: float, signed: bool, degree_digits: int) -> str:
        return format_sexagesimal(angle_deg, high_precision=bool(self.high_precision), signed=signed,
                                  degree_digits=degree_digits, degree_sign=self.degree_sign,
                                  seconds_sign=self.seconds_sign)

    def set_target(self, azimuth_deg: float, zenith_deg: float) -> None:
        """Set the slew target with ``:Sz`` (azimuth) then ``:Sa`` (altitude = Ω) [°]; limits checked first."""
        self.check(azimuth_deg, zenith_deg)
        if self.high_precision is None:
            self.detect_precision()
        azimuth = self._format(wrap_azimuth_deg(azimuth_deg), False, 3)
        if azimuth.startswith("360"):  # 359.9999° rounds up to a full turn
            azimuth = self._format(0.0, False, 3)
        self._sent_target = None
        self._set("Sz", azimuth)
        self._set("Sa", self._format(zenith_deg, True, 2))
        self._sent_target = (azimuth_deg, zenith_deg)

    def slew(self) -> None:
        """Slew to the alt-az target with ``:MA#`` (anchors-protocols §1.3), its reply read as `slew_reply` says."""
        if self.slew_reply != "auto":
            self._set("MA")
            return

        def parse(reply: bytes) -> bytes:
            if reply not in (b"0", b"1"):
                raise ValueError("expected b'0' or b'1'")
            return reply

        reply = self._query(b":MA#", _CHAR, parse)
        if self.is_moving():
            return
        # no bars: a slew that has already ended (a short one, or a simulator at time scale 0), or none at all
        if self._sent_target is not None and self._off_target(self.position(), self._sent_target) is None:
            return
        log.warning("%s: b':MA#' answered %r and the mount did not move", self.name, reply)
        raise DeviceFault(self.name, f"mount refused b':MA#' (reply {reply!r}, no slew in progress and not at the "
                                     f"target; slew_reply='auto')", received=reply)

    def move_to(self, azimuth_deg: float, zenith_deg: float, *, wait: bool = True, timeout_s: float = 120.0) -> None:
        """Move to (azimuth, Ω) [°]; both soft limits are checked before any byte is sent.

        With `wait`, returns once the bars clear and the position matches the target (see
        :meth:`wait_until_stopped`).
        """
        self.check(azimuth_deg, zenith_deg)
        self.set_target(azimuth_deg, zenith_deg)
        self.slew()
        self._target = (azimuth_deg, zenith_deg)
        if wait:
            self.wait_until_stopped(timeout_s=timeout_s)

    def wait_until_stopped(self, *, timeout_s: float = 120.0) -> tuple[float, float]:
        """Poll ``:D#`` until the slew ends, then check arrival; returns the position (azimuth, Ω) [°].

        Raises
        ------
        DeviceTimeout
            Still moving after `timeout_s` (a stalled mount that still answers); the mount is stopped.
        DeviceFault
            The mount stopped further than `arrival_tolerance_deg` from the target (limit, obstruction).
        """
        deadline = time.monotonic() + timeout_s
        while self.is_moving():
            if time.monotonic() > deadline:
                try:
                    where = "at ({:.4f}, {:.4f})°".format(*self.position())
                finally:
                    self.stop()
                raise DeviceTimeout(self.name, f"still moving after {timeout_s} s {where}: stalled?")
            time.sleep(self.poll_s)
        position = self.position()
        target, self._target = self._target, None
        if target is not None and self._off_target(position, target) is not None:
            raise DeviceFault(self.name, f"stopped at ({position[0]:.4f}, {position[1]:.4f})°, target "
                                         f"({target[0]:.4f}, {target[1]:.4f})°: limit or obstruction?")
        return position

    def _off_target(self, position: tuple[float, float], target: tuple[float, float]) -> float | None:
        """The larger axis error [°] if `position` misses `target` by more than the arrival tolerance, else None."""
        d_az = (position[0] - target[0] + 180.0) % 360.0 - 180.0  # azimuth compares modulo a turn
        error = max(abs(d_az), abs(position[1] - target[1]))
        return error if error > self.arrival_tolerance_deg else None

    def expected_motion(self) -> tuple[AxisMotion | None, AxisMotion | None]:
        """The configured slew speed for both axes (the mount slews them together); (None, None) if unknown."""
        if self.slew_rate_deg_s is None:
            return None, None
        motion = AxisMotion(self.slew_rate_deg_s, self.slew_accel_deg_s2)
        return motion, motion

    def stop(self) -> None:
        """Halt all slewing with ``:Q#`` (no reply, anchors-protocols §1.3)."""
        self._target = None
        self._query(b":Q#", _NONE)

    def home(self, *, timeout_s: float = 300.0) -> None:
        """Move to `home_deg`. The mount's alignment already references its axes, and the research note
        confirms no home-search command for alt-az use (only ``:hP#`` park, anchors-protocols §1.3)."""
        self.move_to(*self.home_deg, timeout_s=timeout_s)
