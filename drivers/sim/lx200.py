"""Protocol front of a simulated Meade LX200 / Autostar alt-az mount (the bench's two-axis table).

Lewis style (style-anchors §3): the physics lives in two :class:`~drivers.sim.motion.AxisModel` (azimuth,
altitude) on the world's clock, this module only translates bytes, and faults come through a back door that
the wire cannot reach.

Device analysis (anchors-protocols §1, §6.3 "LX200 model"; Meade "Telescope Serial Command Protocol"
Revision L, 2002, called Rev L below; the 2010.10 revision as quoted in INDI's ``lx200driver.cpp``)
-----------------------------------------------------------------------------------------------------------
Framing: ``:``…``#``; the bare byte 0x06 (ACK) is a command of its own; a ``#`` outside a frame is skipped
(Meade's test program sends ``#:Mw#`` to flush a partial command, §1.1), and so is any other byte outside a
frame (line noise). Replies are in the current precision with 0xDF as degree sign (configurable ``*``) and
``:`` before the seconds, as a real LX200GPS answers (§1.1, STEL-818; configurable ``'``). Targets accept
``*``, 0xDF, ``:``, ``'`` as separators, with or without seconds.

==================  ==============================================================================
``0x06``            alignment char ``A``/``L``/``P`` (no ``#``)
``:AA#`` …          ``:AA#``/``:AL#``/``:AP#`` set the alignment mode, no reply
``:GA#``            altitude ``sDD*MM#`` / ``sDD*MM:SS#`` (altitude axis position)
``:GZ#``            azimuth ``DDD*MM#`` / ``DDD*MM:SS#`` (azimuth axis position modulo 360)
``:GR#`` ``:GD#``   RA ``HH:MM.T#`` / ``HH:MM:SS#``, Dec ``sDD*MM#`` / ``sDD*MM:SS#``, computed from the
                    pose, the site and the simulated time (below)
``:Gr#`` ``:Gd#``   target RA / Dec, same formats (``00:00…`` / ``+00*00…`` before one is set)
``:GS#``            local sidereal time ``HH:MM:SS#``
``:GL#`` ``:GC#``   local time ``HH:MM:SS#``, local date ``MM/DD/YY#``
``:GG#``            UTC offset ``sHH#`` or ``sHH.H#``: hours *added to local time* to give UTC (Rev L)
``:Gc#``            clock format ``24#``
``:Gt#`` ``:Gg#``   site latitude ``sDD*MM#``; longitude ``sDDD*MM#``, **east negative** (Rev L); always the
                    low-precision form Rev L lists
``:GM#`` … ``:GP#`` site 1…4 name ``<string>#``
``:GT#``            tracking frequency ``TT.T#`` (the sidereal 60.2 Hz of Rev L's 60 Hz-motor model)
``:GVP#`` …         ``:GVP#`` product, ``:GVN#`` firmware, ``:GVD#`` date ``mmm dd yyyy``, ``:GVT#`` time,
                    ``:GVF#`` full version
``:U#``             toggle precision, no reply
``:Sa…#``           target altitude; ok char of ``OK_CHARS["Sa"]`` if within [-90, 90] and the axis's
                    soft limits (the "slew range" of Rev L), else the refusal char
``:Sz…#``           target azimuth; ok char if in [0, 360)
``:MA#``            slew both axes to the alt-az target; ok char, or the fault char without a complete
                    target, outside alt-az mode, or when an axis refuses (soft limit, sitting on a limit switch)
``:SrHH:MM:SS#``    target RA (also ``HH:MM.T``); ``1`` valid / ``0`` invalid
``:SdsDD*MM#``      target Dec (also with seconds); ``1`` / ``0``
``:MS#``            slew to the RA/Dec target, converted to alt-az *now*: ``0``; ``1<msg>#`` below the
                    altitude range (Rev L "below horizon"), out of the azimuth range, or without a target;
                    ``2<msg>#`` above it (Rev L "below higher")
``:St`` ``:Sg``     site latitude ``sDD*MM``, longitude ``DDD*MM`` (west positive, 0–360, or signed); ``1``/``0``
``:SGsHH.H#``       UTC offset (Rev L sign); ``1``/``0``; the local time stays, so UTC moves
``:SLHH:MM:SS#``    local time; ``1``/``0``
``:SCMM/DD/YY#``    local date; ``1Updating Planetary Data#<32 spaces>#`` or ``0``
``:Mn#`` … ``:Mw#`` move at the current rate until stopped: in alt-az, N/S = altitude up/down, E/W =
                    azimuth increasing/decreasing; no reply
``:Q#``             stop both axes (gotos, moves, park), no reply
``:Qn#`` … ``:Qw#`` stop the move in that direction started by ``:Mn#`` …; no reply
``:RS#`` … ``:RG#`` rate of ``:Mn#``…: max (the axis's), find, centering, guide; no reply
``:hP#``            slew to the park pose (`park_deg`), no reply
``:h?#``            home status: ``2`` while parking, ``1`` when parked (and at power-up), ``0`` when the
                    park stopped short
``:D#``             ``<bar>#`` while either axis moves or settles, ``#`` when done
==================  ==============================================================================

A set command whose argument does not parse (``:Sr12:xx#``) answers its refusal char ``0`` (Rev L's
"Invalid"). Unknown commands are ignored silently, with no reply, so the host sees a timeout (and the
simulator records them in :attr:`unknown`). That the real mount does the same is the project's working
assumption; the research note does not document it (UNCONFIRMED). The ok/refusal characters come from
:data:`drivers.meade.OK_CHARS`, the same table the driver reads (anchors-protocols §1.3 recommendation). The
bar glyph of ``:D#`` is UNCONFIRMED (§7 q3); the default ``|`` is a stand-in and the driver accepts any
non-space byte.

Sky coordinates. The axes are always alt-az (also in land or polar mode, which only changes the ACK
reply). RA/Dec are *of date* (INDI's JNow, ``EQUATORIAL_EOD_COORD``), from the pose by the spherical
triangle of the site latitude, with local sidereal time = Greenwich mean sidereal time (Meeus eq. 12.4) of
the simulated UTC plus the east longitude; no refraction, no nutation, UTC taken for UT1 (< 1 s). Simulated
UTC = `start_utc` (default: the wall clock when the simulator is made) + the world clock, so a time scale of
10 turns the sky ten times faster and time scale 0 holds it still. The mount does **not track**: the bench
table must not follow the sky, so after a ``:MS#`` goto the pose holds and RA drifts at the sidereal rate (a
real Autostar tracks; UNCONFIRMED what it does in land mode). Azimuth runs from north through east.

UNCONFIRMED, chosen here (no manual or trace settles them): the power-up site (seed 003's NSU, Novosibirsk:
54°51′ N, 83°06′ E, whole minutes as ``:Gt#``/``:Gg#`` tell them; UTC+7) and time (the wall clock); the
``:MS#`` message strings; the 32 spaces after ``:SC``'s message (Rev L prints a long blank run, 10Micron
documents 32); whether ``:SG`` keeps the local time or UTC (kept: local, which makes INDI's ``:SL :SC :SG``
order of LX200GPS and ``:SG :SL :SC`` of Autostar both end consistent); the alt-az meaning of N/S/E/W (by
analogy with polar mode, §1.3); the rates of ``:RM# :RC# :RG#`` (1.5 °/s, 0.25 °/s, 2× sidereal, capped at
the axis's rate) and which rate the mount powers up with (max); ``:GVF#``'s text; the park pose of an alt-az
Autostar (default azimuth 0°, altitude 0°, the table's zero); what ``:h?#`` says before any park (``1``);
the site names; that ``:Qn#`` … halt only moves started by ``:Mn#`` …, not a goto.

Manual versus client (peer-clients.md, INDI indi-bin 1.9.9 ``lx200driver.cpp``). By default the simulator
answers as the manual says; with ``indi_compatible=True`` (``simulation: lx200: indi_compatible: true`` in a
bench file, ``sunbench sim --indi-compatible``) it answers as INDI expects:

* ``:MA#`` (CONFLICT): Rev L ``0`` = no fault, ``1`` = fault; INDI's ``slewToAltAz`` takes ``0`` as failure
  and reports "Slew is not possible" though the mount slews. Compatible: ``1`` = slewing, ``0`` = fault
  (:data:`drivers.meade.INDI_OK_CHARS`). The driver reads either (its ``slew_reply`` option).
* ``:Sa`` format: Rev L ``sDD*MM`` / ``sDD*MM'SS`` (sign and two digits); INDI writes ``:Sa%+02d*%02d#``, so
  5° goes out as ``+5*00`` (and −0.5° as ``+0*30``: INDI loses the sign of altitudes in (−1°, 0°)). By
  default a target without sign or with one digit is refused (``0``); compatible: accepted. ``:Sd`` follows
  the same rule (INDI writes it with ``%+03d``, which the manual's form takes). The *ok character* of ``:Sa``
  is no conflict here: Rev L says ``0`` = within range, the 2010.10 revision (quoted in INDI and in ASCOM
  Meade drivers) ``1``, which INDI and :data:`~drivers.meade.OK_CHARS` use.
* ``:h?#``: Rev L lists a bare ``0``/``1``/``2``; INDI reads up to a ``#`` (5 s timeout first).
  Compatible: ``#`` appended.

Azimuth axis coordinate = mount azimuth in [0, 360) without wrapping through 360 (a cable wrap): a target
is reached by turning inside [0, 360).

Back door: :attr:`faults` (:class:`~drivers.sim.device.WireFaults`: no_reply, garble, truncate,
disconnected), :attr:`busy_naks` (answer the next n commands with NAK 0x15 and ignore them, §1.1),
:attr:`indi_compatible` (switchable at any time), the site and time (:attr:`latitude_deg`,
:attr:`longitude_deg`, :meth:`set_utc`), and the axis models :attr:`azimuth` and :attr:`altitude`
(``stall()``, ``trip_limit()``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import UTC, date, datetime, time, timedelta

from ..meade import ACK, INDI_OK_CHARS, NAK, OK_CHARS, format_sexagesimal, refusal_char
from .device import SimDevice
from .motion import AxisLimitError, AxisModel, AxisSpec
from .world import SimWorld

_SEP = rb"[*\xdf:']"
_ANGLE = rb"(\d{1,3})" + _SEP + rb"(\d{1,2})(?:" + _SEP + rb"(\d{1,2}))?"
#: Rev L's ``sDD*MM`` / ``sDD*MM'SS``: a sign and two digits per field
_MANUAL_SIGNED = re.compile(rb"([+-])(\d{2})" + _SEP + rb"(\d{2})(?:" + _SEP + rb"(\d{2}))?")
#: what INDI writes with ``%+02d``: the sign counts in the width, so 5° is ``+5*00``; a lost sign is taken too
_LENIENT_SIGNED = re.compile(rb"([+-]?)(\d{1,2})" + _SEP + rb"(\d{1,2})(?:" + _SEP + rb"(\d{1,2}))?")

SIDEREAL_DAY_S = 86164.0905  # mean sidereal day [s]
SIDEREAL_RATE_DEG_S = 360.0 / SIDEREAL_DAY_S
_UNIX_EPOCH_JD, _J2000_JD = 2440587.5, 2451545.0

#: Rates of ``:Mn#``… after ``:RS# :RM# :RC# :RG#`` [°/s], each capped at the axis's own rate; None = the
#: axis's rate. UNCONFIRMED values (Autostar's speeds 9, ~7, ~5 and 2× sidereal, from memory, not a manual).
JOG_RATES_DEG_S: dict[str, float | None] = {"S": None, "M": 1.5, "C": 0.25, "G": 2.0 * SIDEREAL_RATE_DEG_S}

_BELOW_HORIZON = b"1Object Below Horizon#"  # :MS# refusals: message texts UNCONFIRMED
_ABOVE_LIMIT = b"2Object Above Higher Limit#"
_OUT_OF_RANGE = b"1Target Out Of Slew Range#"
_NO_TARGET = b"1No Target#"
_PLANETARY = b"1Updating Planetary Data#" + b" " * 32 + b"#"  # :SC accepted (Rev L); blank run UNCONFIRMED


def greenwich_sidereal_time_deg(utc: datetime) -> float:
    """Greenwich mean sidereal time [°] at `utc` (Meeus, Astronomical Algorithms, eq. 12.4; the T² and T³
    terms it drops stay below 0.01 s of time this century)."""
    jd = utc.timestamp() / 86400.0 + _UNIX_EPOCH_JD
    return (280.46061837 + 360.98564736629 * (jd - _J2000_JD)) % 360.0


def horizontal_to_equatorial(altitude_deg: float, azimuth_deg: float, latitude_deg: float,
                             sidereal_time_deg: float) -> tuple[float, float]:
    """(RA, Dec) [°] of the direction (altitude, azimuth from north through east) [°] at a site of latitude
    `latitude_deg` when the local sidereal time is `sidereal_time_deg`; RA in [0, 360)."""
    alt, az, lat = (math.radians(x) for x in (altitude_deg, azimuth_deg, latitude_deg))
    sin_dec = math.sin(alt) * math.sin(lat) + math.cos(alt) * math.cos(lat) * math.cos(az)
    dec = math.asin(max(-1.0, min(1.0, sin_dec)))
    hour_angle = math.atan2(-math.sin(az) * math.cos(alt),
                            math.sin(alt) * math.cos(lat) - math.cos(alt) * math.sin(lat) * math.cos(az))
    return (sidereal_time_deg - math.degrees(hour_angle)) % 360.0, math.degrees(dec)


def equatorial_to_horizontal(ra_deg: float, dec_deg: float, latitude_deg: float,
                             sidereal_time_deg: float) -> tuple[float, float]:
    """(altitude, azimuth) [°] of (RA, Dec) [°], the inverse of :func:`horizontal_to_equatorial`; azimuth in
    [0, 360) from north through east."""
    ha, dec, lat = (math.radians(x) for x in (sidereal_time_deg - ra_deg, dec_deg, latitude_deg))
    sin_alt = math.sin(lat) * math.sin(dec) + math.cos(lat) * math.cos(dec) * math.cos(ha)
    alt = math.asin(max(-1.0, min(1.0, sin_alt)))
    az = math.atan2(-math.sin(ha) * math.cos(dec),
                    math.cos(lat) * math.sin(dec) - math.sin(lat) * math.cos(dec) * math.cos(ha))
    return math.degrees(alt), math.degrees(az) % 360.0


@dataclass(frozen=True)
class Cmd:
    """One row of the command table: a handler name and the regex its frame body must match in full."""

    handler: str
    pattern: bytes


def _angle(sign: bytes | None, degrees: bytes, minutes: bytes, seconds: bytes | None) -> float | None:
    """Degrees from captured fields; None if minutes or seconds are 60 or more."""
    m, s = int(minutes), int(seconds) if seconds else 0
    if m >= 60 or s >= 60:
        return None
    value = int(degrees) + m / 60.0 + s / 3600.0
    return -value if sign == b"-" else value


class LX200Simulator(SimDevice):
    """Simulated Autostar / LX200GPS-class mount in alt-az use (see the module docstring).

    Parameters
    ----------
    world : SimWorld
        Shared truth; the simulator creates its two axes there and attaches them as the table.
    azimuth_spec, altitude_spec : AxisSpec
        Mechanics of the mount's azimuth and altitude axes.
    high_precision : bool
        Power-up precision: False = ``sDD*MM`` (1′), True = ``sDD*MM:SS`` (1″).
    degree_sign : bytes
        Degree sign in replies: 0xDF as the real mount (anchors-protocols §1.1) or ``*``.
    seconds_sign : bytes
        Separator before the seconds in replies: ``:`` (real LX200GPS) or ``'`` (Rev L).
    alignment : str
        Power-up alignment mode: ``A``, ``L`` or ``P``.
    product, firmware : str
        Answers to ``:GVP#`` and ``:GVN#`` (simulated values).
    bar : bytes
        The distance-bar glyph of ``:D#`` while slewing.
    indi_compatible : bool
        Answer where Rev L and INDI disagree as INDI expects (module docstring), not as the manual says.
    latitude_deg, longitude_deg : float
        Site [°]: latitude north positive, longitude **east positive** (the wire's ``:Gg#`` is east negative).
    utc_offset_h : float
        Rev L's UTC offset [h]: the hours added to local time to give UTC (UTC+7 is −7).
    start_utc : datetime, optional
        Simulated UTC now (timezone-aware); default the wall clock.
    park_deg : (float, float)
        (azimuth, altitude) that ``:hP#`` slews to [°].
    site_names : sequence of str
        Names of sites 1–4 (``:GM#`` … ``:GP#``).
    """

    name = "lx200"

    commands = (
        Cmd("set_alignment", rb"A([ALP])"),
        Cmd("get_altitude", rb"GA"),
        Cmd("get_azimuth", rb"GZ"),
        Cmd("get_ra", rb"GR"),
        Cmd("get_dec", rb"GD"),
        Cmd("get_target_ra", rb"Gr"),
        Cmd("get_target_dec", rb"Gd"),
        Cmd("get_sidereal_time", rb"GS"),
        Cmd("get_local_time", rb"GL"),
        Cmd("get_date", rb"GC"),
        Cmd("get_utc_offset", rb"GG"),
        Cmd("get_clock_format", rb"Gc"),
        Cmd("get_latitude", rb"Gt"),
        Cmd("get_longitude", rb"Gg"),
        Cmd("get_site_name", rb"G([MNOP])"),
        Cmd("get_tracking_frequency", rb"GT"),
        Cmd("get_version", rb"GV([PNDTF])"),
        Cmd("toggle_precision", rb"U"),
        Cmd("set_target_altitude", rb"Sa(.*)"),
        Cmd("set_target_azimuth", rb"Sz" + _ANGLE),
        Cmd("slew_alt_az", rb"MA"),
        Cmd("set_target_ra", rb"Sr ?(\d{2}):(\d{2})(?:\.(\d)|:(\d{2}))"),
        Cmd("set_target_dec", rb"Sd ?(.*)"),
        Cmd("slew_equatorial", rb"MS"),
        Cmd("set_latitude", rb"St ?([+-]?)" + _ANGLE),
        Cmd("set_longitude", rb"Sg ?([+-]?)" + _ANGLE),
        Cmd("set_utc_offset", rb"SG ?([+-]?\d{1,2}(?:\.\d)?)"),
        Cmd("set_local_time", rb"SL ?(\d{2}):(\d{2}):(\d{2})"),
        Cmd("set_date", rb"SC ?(\d{2})/(\d{2})/(\d{2})"),
        Cmd("invalid_argument", rb"(S[adgGLCrtz]).*"),  # a set command whose argument does not parse
        Cmd("move", rb"M([nsew])"),
        Cmd("set_rate", rb"R([SMCG])"),
        Cmd("park", rb"hP"),
        Cmd("home_status", rb"h\?"),
        Cmd("distance_bars", rb"D"),
        Cmd("stop", rb"Q([nsew]?)"),
    )

    def __init__(self, world: SimWorld, azimuth_spec: AxisSpec | None = None, altitude_spec: AxisSpec | None = None,
                 *, high_precision: bool = False, degree_sign: bytes = b"\xdf", seconds_sign: bytes = b":",
                 alignment: str = "A", product: str = "Autostar", firmware: str = "43Eg", bar: bytes = b"|",
                 indi_compatible: bool = False, latitude_deg: float = 54.85, longitude_deg: float = 83.1,
                 utc_offset_h: float = -7.0, start_utc: datetime | None = None,
                 park_deg: tuple[float, float] = (0.0, 0.0),
                 site_names: tuple[str, ...] = ("Bench", "Site 2", "Site 3", "Site 4")):
        super().__init__()
        if alignment not in ("A", "L", "P"):
            raise ValueError(f"`alignment` must be A, L or P, got {alignment!r}")
        if not (-90.0 <= latitude_deg <= 90.0 and -180.0 <= longitude_deg <= 180.0 and abs(utc_offset_h) <= 24.0):
            raise ValueError("`latitude_deg` must lie in [-90, 90], `longitude_deg` in [-180, 180] and "
                             "`utc_offset_h` in [-24, 24]")
        if len(site_names) != 4:
            raise ValueError("`site_names` must name 4 sites")
        self.world = world
        self.azimuth = world.new_axis(azimuth_spec or AxisSpec(soft_limits_deg=(0.0, 360.0)))
        self.altitude = world.new_axis(altitude_spec or AxisSpec(soft_limits_deg=(-90.0, 90.0)))
        world.attach_table(self.azimuth, self.altitude)
        self.high_precision = high_precision
        self.degree_sign = degree_sign.decode("latin-1")
        self.seconds_sign = seconds_sign.decode("latin-1")
        self.alignment = alignment
        self.product, self.firmware, self.bar = product, firmware, bar
        self.indi_compatible = indi_compatible
        self.latitude_deg, self.longitude_deg, self.utc_offset_h = latitude_deg, longitude_deg, utc_offset_h
        self.set_utc(start_utc or datetime.now(UTC))
        self.park_deg = park_deg
        self.site_names = list(site_names)
        self.target_azimuth_deg: float | None = None
        self.target_altitude_deg: float | None = None
        self.target_ra_h: float | None = None
        self.target_dec_deg: float | None = None
        self.rate = "S"  # of :Mn# ... (:RS# :RM# :RC# :RG#)
        self._moving: dict[str, str | None] = {"altitude": None, "azimuth": None}  # direction of :Mn# ...
        self._home_status = b"1"  # :h?#: 2 parking, 1 parked (or never asked to), 0 stopped short
        self.busy_naks = 0  # back door: NAK the next n commands
        self.received: list[bytes] = []  # every command handled, for tests and logs
        self.unknown: list[bytes] = []  # commands ignored as unknown (each costs a client a timeout)
        self._table = [(re.compile(cmd.pattern, re.DOTALL), getattr(self, cmd.handler)) for cmd in self.commands]

    # -- framing ---------------------------------------------------------------------------------------
    def handle(self, inbuf: bytearray) -> bytes:
        out = bytearray()
        while inbuf:
            if inbuf[:1] == ACK:
                del inbuf[0]
                out += self._dispatch(ACK)
            elif inbuf[:1] != b":":
                del inbuf[0]  # a flushing '#' or line noise outside a frame
            else:
                end = inbuf.find(b"#")
                if end < 0:
                    break  # wait for the rest of the frame
                body = bytes(inbuf[1:end])
                del inbuf[: end + 1]
                out += self._dispatch(body)
        return bytes(out)

    def _dispatch(self, body: bytes) -> bytes:
        self.received.append(body)
        if self.busy_naks > 0:
            self.busy_naks -= 1
            return NAK  # busy: the command is not executed (anchors-protocols §1.1)
        if body == ACK:
            return self.alignment.encode()
        for pattern, handler in self._table:
            match = pattern.fullmatch(body)
            if match:
                return handler(*match.groups())
        self.unknown.append(body)
        return b""  # unknown: ignored silently (see the module docstring)

    def _angle_reply(self, angle_deg: float, signed: bool, degree_digits: int, *, high: bool | None = None) -> bytes:
        high = self.high_precision if high is None else high
        text = format_sexagesimal(angle_deg, high_precision=high, signed=signed, degree_digits=degree_digits,
                                  degree_sign=self.degree_sign, seconds_sign=self.seconds_sign)
        if not signed and text.startswith("360"):  # 359.9999° rounds to a full turn
            text = format_sexagesimal(0.0, high_precision=high, signed=False, degree_digits=3,
                                      degree_sign=self.degree_sign, seconds_sign=self.seconds_sign)
        return text.encode("latin-1") + b"#"

    def _hours_reply(self, hours: float, *, high: bool | None = None) -> bytes:
        """``HH:MM:SS#`` (high precision) or ``HH:MM.T#`` (low, tenths of a minute), modulo 24 h."""
        if self.high_precision if high is None else high:
            h, rest = divmod(round(hours * 3600.0) % 86400, 3600)
            text = "{:02d}:{:02d}:{:02d}".format(h, *divmod(rest, 60))
        else:
            h, rest = divmod(round(hours * 600.0) % 14400, 600)
            text = "{:02d}:{:02d}.{}".format(h, *divmod(rest, 10))
        return text.encode() + b"#"

    @property
    def ok_chars(self) -> dict[str, bytes]:
        """The ok characters in use: :data:`~drivers.meade.OK_CHARS`, or INDI's in `indi_compatible` mode."""
        return INDI_OK_CHARS if self.indi_compatible else OK_CHARS

    def _refused(self, command: str) -> bytes:
        return refusal_char(command, self.ok_chars)

    # -- time and sky (also the back door) -----------------------------------------------------------------
    def utc(self) -> datetime:
        """Simulated UTC now."""
        return self._utc_at_zero + timedelta(seconds=self.world.clock.now())

    def set_utc(self, utc: datetime) -> None:
        """Set the simulated UTC now (timezone-aware); it then runs with the world clock."""
        if utc.tzinfo is None:
            raise ValueError("`utc` must be timezone-aware")
        self._utc_at_zero = utc.astimezone(UTC) - timedelta(seconds=self.world.clock.now())

    def local_time(self) -> datetime:
        """Simulated local time now (naive): UTC minus Rev L's UTC offset."""
        return (self.utc() - timedelta(hours=self.utc_offset_h)).replace(tzinfo=None)

    def _set_local_time(self, local: datetime) -> None:
        self.set_utc(local.replace(tzinfo=UTC) + timedelta(hours=self.utc_offset_h))

    def sidereal_time_deg(self) -> float:
        """Local mean sidereal time now [°]."""
        return (greenwich_sidereal_time_deg(self.utc()) + self.longitude_deg) % 360.0

    def pose_deg(self) -> tuple[float, float]:
        """(azimuth in [0, 360), altitude) the axes read [°]."""
        return self.azimuth.position_deg() % 360.0, self.altitude.position_deg()

    def equatorial_deg(self) -> tuple[float, float]:
        """(RA, Dec) of date [°] the mount points at now (module docstring)."""
        azimuth, altitude = self.pose_deg()  # first: at time scale 0, observing may complete a move
        return horizontal_to_equatorial(altitude, azimuth, self.latitude_deg, self.sidereal_time_deg())

    def horizontal_deg(self, ra_deg: float, dec_deg: float) -> tuple[float, float]:
        """(azimuth, altitude) [°] of (RA, Dec) of date now."""
        altitude, azimuth = equatorial_to_horizontal(ra_deg, dec_deg, self.latitude_deg, self.sidereal_time_deg())
        return azimuth, altitude

    # -- motion helpers ------------------------------------------------------------------------------------
    def _altitude_range(self) -> tuple[float, float]:
        low, high = self.altitude.spec.soft_limits_deg or (-90.0, 90.0)
        return max(low, -90.0), min(high, 90.0)

    def _slew_to(self, azimuth_deg: float, altitude_deg: float) -> bool:
        """Start both axes towards the pose; False (and nothing moves) if an axis refuses."""
        try:
            self.azimuth.move_to(azimuth_deg)
        except AxisLimitError:
            return False
        try:
            self.altitude.move_to(altitude_deg)
        except AxisLimitError:
            self.azimuth.stop()  # no half slews
            return False
        self._moving = {"altitude": None, "azimuth": None}  # a goto supersedes :Mn# ...
        if self._home_status == b"2":
            self._home_status = b"0"  # the park was interrupted
        return True

    def _axis(self, direction: str) -> tuple[str, AxisModel]:
        return ("altitude", self.altitude) if direction in "ns" else ("azimuth", self.azimuth)

    # -- command handlers --------------------------------------------------------------------------------
    def set_alignment(self, mode: bytes) -> bytes:
        self.alignment = mode.decode()
        return b""

    def get_altitude(self) -> bytes:
        return self._angle_reply(self.altitude.position_deg(), True, 2)

    def get_azimuth(self) -> bytes:
        return self._angle_reply(self.azimuth.position_deg() % 360.0, False, 3)

    def get_ra(self) -> bytes:
        return self._hours_reply(self.equatorial_deg()[0] / 15.0)

    def get_dec(self) -> bytes:
        return self._angle_reply(self.equatorial_deg()[1], True, 2)

    def get_target_ra(self) -> bytes:
        return self._hours_reply(self.target_ra_h or 0.0)

    def get_target_dec(self) -> bytes:
        return self._angle_reply(self.target_dec_deg or 0.0, True, 2)

    def get_sidereal_time(self) -> bytes:
        return self._hours_reply(self.sidereal_time_deg() / 15.0, high=True)

    def get_local_time(self) -> bytes:
        return self.local_time().strftime("%H:%M:%S").encode() + b"#"

    def get_date(self) -> bytes:
        return self.local_time().strftime("%m/%d/%y").encode() + b"#"

    def get_utc_offset(self) -> bytes:
        offset = self.utc_offset_h
        text = f"{offset:+03.0f}" if offset == round(offset) else f"{offset:+05.1f}"  # sHH or sHH.H (Rev L)
        return text.encode() + b"#"

    def get_clock_format(self) -> bytes:
        return b"24#"

    def get_latitude(self) -> bytes:
        return self._angle_reply(self.latitude_deg, True, 2, high=False)

    def get_longitude(self) -> bytes:
        return self._angle_reply(-self.longitude_deg, True, 3, high=False)  # Rev L: east negative

    def get_site_name(self, which: bytes) -> bytes:
        return self.site_names[b"MNOP".index(which)].encode("latin-1") + b"#"

    def get_tracking_frequency(self) -> bytes:
        return f"{60.0 * 86400.0 / SIDEREAL_DAY_S:04.1f}#".encode()  # 60 Hz = one turn per solar day (Rev L)

    def get_version(self, which: bytes) -> bytes:
        text = {b"P": self.product, b"N": self.firmware, b"D": "Nov 21 2025", b"T": "12:00:00",
                b"F": f"{self.product} {self.firmware}"}[which]
        return text.encode("latin-1") + b"#"

    def toggle_precision(self) -> bytes:
        self.high_precision = not self.high_precision
        return b""

    def _signed_target(self, text: bytes) -> float | None:
        """A signed ``:Sa``/``:Sd`` argument in the manual's form, or in INDI's too when compatible."""
        match = (_LENIENT_SIGNED if self.indi_compatible else _MANUAL_SIGNED).fullmatch(text)
        return _angle(*match.groups()) if match else None

    def set_target_altitude(self, text: bytes) -> bytes:
        value = self._signed_target(text)
        low, high = self._altitude_range()
        if value is None or not low <= value <= high:
            return self._refused("Sa")
        self.target_altitude_deg = value
        return self.ok_chars["Sa"]

    def set_target_azimuth(self, degrees, minutes, seconds) -> bytes:
        value = _angle(None, degrees, minutes, seconds)
        if value is None or not 0.0 <= value < 360.0:
            return self._refused("Sz")
        self.target_azimuth_deg = value
        return self.ok_chars["Sz"]

    def slew_alt_az(self) -> bytes:
        if self.alignment != "A" or self.target_azimuth_deg is None or self.target_altitude_deg is None:
            return self._refused("MA")
        if not self._slew_to(self.target_azimuth_deg, self.target_altitude_deg):
            return self._refused("MA")
        return self.ok_chars["MA"]

    def set_target_ra(self, hours, minutes, tenths, seconds) -> bytes:
        h, m = int(hours), int(minutes)
        s = int(seconds) if seconds is not None else 6 * int(tenths)
        if h >= 24 or m >= 60 or s >= 60:
            return b"0"
        self.target_ra_h = h + m / 60.0 + s / 3600.0
        return b"1"

    def set_target_dec(self, text: bytes) -> bytes:
        value = self._signed_target(text)
        if value is None or not -90.0 <= value <= 90.0:
            return b"0"
        self.target_dec_deg = value
        return b"1"

    def slew_equatorial(self) -> bytes:
        if self.target_ra_h is None or self.target_dec_deg is None:
            return _NO_TARGET
        azimuth, altitude = self.horizontal_deg(15.0 * self.target_ra_h, self.target_dec_deg)
        low, high = self._altitude_range()
        if altitude < low:
            return _BELOW_HORIZON
        if altitude > high:
            return _ABOVE_LIMIT
        return b"0" if self._slew_to(azimuth, altitude) else _OUT_OF_RANGE

    def set_latitude(self, sign, degrees, minutes, seconds) -> bytes:
        value = _angle(sign, degrees, minutes, seconds)
        if value is None or not -90.0 <= value <= 90.0:
            return b"0"
        self.latitude_deg = value
        return b"1"

    def set_longitude(self, sign, degrees, minutes, seconds) -> bytes:
        west = _angle(sign, degrees, minutes, seconds)  # Rev L: DDD*MM westward; INDI may send a sign
        if west is None or not -180.0 <= west < 360.0:
            return b"0"
        self.longitude_deg = -(west - 360.0 if west > 180.0 else west)
        return b"1"

    def set_utc_offset(self, text: bytes) -> bytes:
        value = float(text)
        if abs(value) > 24.0:
            return b"0"
        local = self.local_time()
        self.utc_offset_h = value
        self._set_local_time(local)  # the handbox keeps its local time (module docstring)
        return b"1"

    def set_local_time(self, hours, minutes, seconds) -> bytes:
        h, m, s = int(hours), int(minutes), int(seconds)
        if h >= 24 or m >= 60 or s >= 60:
            return b"0"
        self._set_local_time(datetime.combine(self.local_time().date(), time(h, m, s)))
        return b"1"

    def set_date(self, month, day, year) -> bytes:
        yy = int(year)
        try:
            new = date(1900 + yy if yy > 50 else 2000 + yy, int(month), int(day))  # INDI's century rule
        except ValueError:
            return b"0"
        self._set_local_time(datetime.combine(new, self.local_time().time()))
        return _PLANETARY

    def invalid_argument(self, command: bytes) -> bytes:
        name = command.decode()
        return self._refused(name) if name in OK_CHARS else b"0"

    def move(self, direction: bytes) -> bytes:
        d = direction.decode()
        key, axis = self._axis(d)
        up = d in "ne"
        if key == "altitude":
            low, high = self._altitude_range()
        else:
            here = axis.position_deg()
            low, high = axis.spec.soft_limits_deg or (here - 360.0, here + 360.0)
        target = high if up else low
        try:
            axis.move_to(target)  # the axis's own checks: soft limits, a closed limit switch
        except AxisLimitError:
            return b""  # nothing moves; the command has no reply
        rate = JOG_RATES_DEG_S[self.rate]
        if rate is not None and rate < axis.spec.max_rate_deg_s:
            # AxisModel.move_to always runs at the axis's rate; restarting at the same instant from the same
            # place changes only the rate (drivers/sim/motion.py has no public rate argument)
            axis._start(target, rate)
        self._moving[key] = d
        return b""

    def stop(self, direction: bytes = b"") -> bytes:
        if not direction:
            self.azimuth.stop()
            self.altitude.stop()
            self._moving = {"altitude": None, "azimuth": None}
            return b""
        d = direction.decode()
        key, axis = self._axis(d)
        if self._moving[key] == d:  # only a :M<d># move in that direction (Rev L "halt <d>ward slews")
            axis.stop()
            self._moving[key] = None
        return b""

    def set_rate(self, which: bytes) -> bytes:
        self.rate = which.decode()
        return b""

    def park(self) -> bytes:
        self._home_status = b"2" if self._slew_to(*self.park_deg) else b"0"
        return b""

    def home_status(self) -> bytes:
        if self._home_status == b"2" and not (self.azimuth.busy() | self.altitude.busy()):
            azimuth, altitude = self.pose_deg()
            d_az = (azimuth - self.park_deg[0] + 180.0) % 360.0 - 180.0
            parked = max(abs(d_az), abs(altitude - self.park_deg[1])) < 1.0 / 3600.0
            self._home_status = b"1" if parked else b"0"
        return self._home_status + (b"#" if self.indi_compatible else b"")

    def distance_bars(self) -> bytes:
        moving = self.azimuth.busy() | self.altitude.busy()  # both observed: in instant mode each completes
        return self.bar + b"#" if moving else b"#"
