"""Protocol front of a simulated Meade LX200 / Autostar alt-az mount (the bench's two-axis table).

Lewis style (style-anchors §3): the physics lives in two :class:`~drivers.sim.motion.AxisModel` (azimuth,
altitude) on the world's clock, this module only translates bytes, and faults come through a back door that
the wire cannot reach.

Device analysis (anchors-protocols §1, §6.3 "LX200 model")
-----------------------------------------------------------
Framing: ``:``…``#``; the bare byte 0x06 (ACK) is a command of its own; a ``#`` outside a frame is skipped
(Meade's test program sends ``#:Mw#`` to flush a partial command, §1.1), and so is any other byte outside a
frame (line noise). Replies are in the current precision with 0xDF as degree sign (configurable ``*``) and
``:`` before the seconds, as a real LX200GPS answers (§1.1, STEL-818; configurable ``'``). Targets accept
``*``, 0xDF, ``:``, ``'`` as separators, with or without seconds.

==============  ==============================================================================
``0x06``        alignment char ``A``/``L``/``P`` (no ``#``)
``:AA#`` …      ``:AA#``/``:AL#``/``:AP#`` set the alignment mode, no reply
``:GA#``        altitude ``sDD*MM#`` / ``sDD*MM:SS#`` (altitude axis position)
``:GZ#``        azimuth ``DDD*MM#`` / ``DDD*MM:SS#`` (azimuth axis position modulo 360)
``:U#``         toggle precision, no reply
``:Sa…#``       target altitude; ok char of ``OK_CHARS["Sa"]`` if within [-90, 90] and the axis's
                soft limits (the "slew range" of Rev L), else the refusal char
``:Sz…#``       target azimuth; ok char if in [0, 360)
``:MA#``        slew both axes to the target; ok char, or the fault char without a complete target,
                outside alt-az mode, or when an axis refuses (soft limit, sitting on a limit switch)
``:D#``         ``<bar>#`` while either axis moves or settles, ``#`` when done
``:Q#``         stop both axes, no reply
``:GVP#`` …     ``:GVP#`` product, ``:GVN#`` firmware, ``:GVD#`` date, ``:GVT#`` time
==============  ==============================================================================

Unknown commands are ignored silently, with no reply, so the host sees a timeout. That the real mount does
the same is the project's working assumption; the research note does not document it (UNCONFIRMED). The ok/refusal characters come from :data:`drivers.meade.OK_CHARS`, the
same table the driver reads (anchors-protocols §1.3 recommendation). The bar glyph of ``:D#`` is
UNCONFIRMED (§7 q3); the default ``|`` is a stand-in and the driver accepts any non-space byte.

Azimuth axis coordinate = mount azimuth in [0, 360) without wrapping through 360 (a cable wrap): a target
is reached by turning inside [0, 360).

Back door: :attr:`faults` (:class:`~drivers.sim.device.WireFaults`: no_reply, garble, truncate,
disconnected), :attr:`busy_naks` (answer the next n commands with NAK 0x15 and ignore them, §1.1), and the
axis models :attr:`azimuth` and :attr:`altitude` (``stall()``, ``trip_limit()``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..meade import ACK, NAK, OK_CHARS, format_sexagesimal, refusal_char
from .device import SimDevice
from .motion import AxisLimitError, AxisSpec
from .world import SimWorld

_SEP = rb"[*\xdf:']"
_ANGLE = rb"(\d{1,3})" + _SEP + rb"(\d{1,2})(?:" + _SEP + rb"(\d{1,2}))?"


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
    """

    name = "lx200"

    commands = (
        Cmd("set_alignment", rb"A([ALP])"),
        Cmd("get_altitude", rb"GA"),
        Cmd("get_azimuth", rb"GZ"),
        Cmd("toggle_precision", rb"U"),
        Cmd("set_target_altitude", rb"Sa([+-]?)" + _ANGLE),
        Cmd("set_target_azimuth", rb"Sz" + _ANGLE),
        Cmd("slew_alt_az", rb"MA"),
        Cmd("distance_bars", rb"D"),
        Cmd("stop", rb"Q"),
        Cmd("get_version", rb"GV([PNDT])"),
    )

    def __init__(self, world: SimWorld, azimuth_spec: AxisSpec | None = None, altitude_spec: AxisSpec | None = None,
                 *, high_precision: bool = False, degree_sign: bytes = b"\xdf", seconds_sign: bytes = b":",
                 alignment: str = "A", product: str = "Autostar", firmware: str = "43Eg", bar: bytes = b"|"):
        super().__init__()
        if alignment not in ("A", "L", "P"):
            raise ValueError(f"`alignment` must be A, L or P, got {alignment!r}")
        self.world = world
        self.azimuth = world.new_axis(azimuth_spec or AxisSpec(soft_limits_deg=(0.0, 360.0)))
        self.altitude = world.new_axis(altitude_spec or AxisSpec(soft_limits_deg=(-90.0, 90.0)))
        world.attach_table(self.azimuth, self.altitude)
        self.high_precision = high_precision
        self.degree_sign = degree_sign.decode("latin-1")
        self.seconds_sign = seconds_sign.decode("latin-1")
        self.alignment = alignment
        self.product, self.firmware, self.bar = product, firmware, bar
        self.target_azimuth_deg: float | None = None
        self.target_altitude_deg: float | None = None
        self.busy_naks = 0  # back door: NAK the next n commands
        self.received: list[bytes] = []  # every command handled, for tests and logs
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
        return b""  # unknown: ignored silently (see the module docstring)

    def _angle_reply(self, angle_deg: float, signed: bool, degree_digits: int) -> bytes:
        text = format_sexagesimal(angle_deg, high_precision=self.high_precision, signed=signed,
                                  degree_digits=degree_digits, degree_sign=self.degree_sign,
                                  seconds_sign=self.seconds_sign)
        if not signed and text.startswith("360"):  # 359.9999° rounds to a full turn
            text = format_sexagesimal(0.0, high_precision=self.high_precision, signed=False, degree_digits=3,
                                      degree_sign=self.degree_sign, seconds_sign=self.seconds_sign)
        return text.encode("latin-1") + b"#"

    # -- command handlers --------------------------------------------------------------------------------
    def set_alignment(self, mode: bytes) -> bytes:
        self.alignment = mode.decode()
        return b""

    def get_altitude(self) -> bytes:
        return self._angle_reply(self.altitude.position_deg(), True, 2)

    def get_azimuth(self) -> bytes:
        return self._angle_reply(self.azimuth.position_deg() % 360.0, False, 3)

    def toggle_precision(self) -> bytes:
        self.high_precision = not self.high_precision
        return b""

    def set_target_altitude(self, sign, degrees, minutes, seconds) -> bytes:
        value = _angle(sign, degrees, minutes, seconds)
        limits = self.altitude.spec.soft_limits_deg or (-90.0, 90.0)
        if value is None or not (-90.0 <= value <= 90.0 and limits[0] <= value <= limits[1]):
            return refusal_char("Sa")
        self.target_altitude_deg = value
        return OK_CHARS["Sa"]

    def set_target_azimuth(self, degrees, minutes, seconds) -> bytes:
        value = _angle(None, degrees, minutes, seconds)
        if value is None or not 0.0 <= value < 360.0:
            return refusal_char("Sz")
        self.target_azimuth_deg = value
        return OK_CHARS["Sz"]

    def slew_alt_az(self) -> bytes:
        if self.alignment != "A" or self.target_azimuth_deg is None or self.target_altitude_deg is None:
            return refusal_char("MA")
        try:
            self.azimuth.move_to(self.target_azimuth_deg)
        except AxisLimitError:
            return refusal_char("MA")
        try:
            self.altitude.move_to(self.target_altitude_deg)
        except AxisLimitError:
            self.azimuth.stop()  # no half slews
            return refusal_char("MA")
        return OK_CHARS["MA"]

    def distance_bars(self) -> bytes:
        moving = self.azimuth.busy() | self.altitude.busy()  # both observed: in instant mode each completes
        return self.bar + b"#" if moving else b"#"

    def stop(self) -> bytes:
        self.azimuth.stop()
        self.altitude.stop()
        return b""

    def get_version(self, which: bytes) -> bytes:
        text = {b"P": self.product, b"N": self.firmware, b"D": "Nov 21 2025", b"T": "12:00:00"}[which]
        return text.encode("latin-1") + b"#"
