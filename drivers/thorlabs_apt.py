"""Thorlabs APT / Kinesis binary protocol, and a K10CR1-class rotation stage that speaks it.

The module has two halves:

* pure, module-level helpers that pack and unpack APT frames (6-byte header, optional data packet, all
  little-endian; anchors-protocols §2.2) and the data packets a rotation stage uses (§2.3), shared by the
  driver and by the simulator in :mod:`drivers.sim.thorlabs_apt`;
* :class:`AptRotationStage`, a :class:`~drivers.interfaces.RotaryAxis` on a :class:`~drivers.transport.Port`.

Protocol decisions (anchors-protocols §2):

* Line: 115200 baud, 8N1, RTS/CTS; the init cycles RTS like pylablib and tolerates the ``OSError``
  (errno 25, ENOTTY) that a pseudo-terminal raises (§2.1, §6 item 4).
* The host is 0x01, the stage 0x50 (a stand-alone USB unit); rack 0x11 and bay 0x21 also exist (§2.2).
* Replies are taken by message id only: the driver never insists on the reply's source byte, because some
  controllers send 0 there (§2.2). It does check that the frame is addressed to the host, that its id and
  length are those of a device-to-host message it knows and that its channel field is the driver's, and it
  never decodes across a message boundary (:class:`AptFrameReader`): a frame cut short on the line is
  dropped, not completed with the next frame's header, and bytes before a valid header are skipped.
* The device volunteers MOVE_COMPLETED, MOVE_STOPPED, MOVE_HOMED and status updates (§2.3). Any of them
  that arrive while the driver waits for a reply are consumed and noted, never taken for the reply.
  MOVE_COMPLETED / MOVE_STOPPED are accepted in both the short and the long (14-byte status) form, since
  which one the K10CR1 sends is UNCONFIRMED (§7 item 5).
* Completion is decided by the status bits (moving / jogging / homing clear), polled with
  MOT_REQ_STATUSBITS, as QMI does for the K10CR1 (§2.3); volunteered messages are only hints.
* A reply that stops half way or is corrupted raises :class:`ProtocolError`, silence
  :class:`DeviceTimeout`; either way the request (a REQ_x, safe to repeat) is asked again from a clean input
  buffer, up to `retries` times (3). Commands without a reply are sent once.
"""

from __future__ import annotations

import errno
import logging
import math
import struct
import time
from dataclasses import dataclass
from enum import IntEnum

from .errors import DeviceDisconnected, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from .interfaces import AxisMotion, Limits, RotaryAxis
from .transport import DEFAULT_RETRIES, Port, ask_again, open_port

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

# -- addresses (anchors-protocols §2.2) -----------------------------------------------------------------
HOST = 0x01
RACK = 0x11
BAY0 = 0x21
USB_UNIT = 0x50  # generic USB unit: K-cubes, T-cubes, K10CR1

HEADER_SIZE = 6
LONG_FLAG = 0x80  # bit 7 of the destination byte: a data packet follows

# -- K10CR1 units (anchors-protocols §2.4) ----------------------------------------------------------------
K10CR1_COUNTS_PER_DEG = 409600.0 / 3.0  # µsteps per degree: 409600 µsteps per 3° worm turn
K10CR1_VELOCITY_SCALE = 7329109.0  # velocity counts per °/s
K10CR1_ACCEL_SCALE = 1502.0  # acceleration counts per °/s²
K10CR1_MAX_VELOCITY_DEG_S = 10.0
K10CR1_MAX_ACCEL_DEG_S2 = 20.0


class Msg(IntEnum):
    """APT message ids used with a rotation stage (anchors-protocols §2.3)."""

    HW_DISCONNECT = 0x0002
    HW_REQ_INFO = 0x0005
    HW_GET_INFO = 0x0006
    HW_START_UPDATEMSGS = 0x0011
    HW_STOP_UPDATEMSGS = 0x0012
    HW_NO_FLASH_PROGRAMMING = 0x0018
    HW_RESPONSE = 0x0080
    HW_RICHRESPONSE = 0x0081
    MOD_SET_CHANENABLESTATE = 0x0210
    MOD_REQ_CHANENABLESTATE = 0x0211
    MOD_GET_CHANENABLESTATE = 0x0212
    MOD_IDENTIFY = 0x0223
    MOT_SET_POSCOUNTER = 0x0410
    MOT_REQ_POSCOUNTER = 0x0411
    MOT_GET_POSCOUNTER = 0x0412
    MOT_SET_VELPARAMS = 0x0413
    MOT_REQ_VELPARAMS = 0x0414
    MOT_GET_VELPARAMS = 0x0415
    MOT_SET_JOGPARAMS = 0x0416
    MOT_REQ_JOGPARAMS = 0x0417
    MOT_GET_JOGPARAMS = 0x0418
    MOT_SET_LIMSWITCHPARAMS = 0x0423
    MOT_REQ_LIMSWITCHPARAMS = 0x0424
    MOT_GET_LIMSWITCHPARAMS = 0x0425
    MOT_REQ_STATUSBITS = 0x0429
    MOT_GET_STATUSBITS = 0x042A
    MOT_SET_GENMOVEPARAMS = 0x043A
    MOT_REQ_GENMOVEPARAMS = 0x043B
    MOT_GET_GENMOVEPARAMS = 0x043C
    MOT_SET_HOMEPARAMS = 0x0440
    MOT_REQ_HOMEPARAMS = 0x0441
    MOT_GET_HOMEPARAMS = 0x0442
    MOT_MOVE_HOME = 0x0443
    MOT_MOVE_HOMED = 0x0444
    MOT_SET_MOVERELPARAMS = 0x0445
    MOT_MOVE_RELATIVE = 0x0448
    MOT_SET_MOVEABSPARAMS = 0x0450
    MOT_MOVE_ABSOLUTE = 0x0453
    MOT_MOVE_VELOCITY = 0x0457
    MOT_MOVE_COMPLETED = 0x0464
    MOT_MOVE_STOP = 0x0465
    MOT_MOVE_STOPPED = 0x0466
    MOT_MOVE_JOG = 0x046A
    MOT_REQ_STATUSUPDATE = 0x0480
    MOT_GET_STATUSUPDATE = 0x0481
    MOT_REQ_DCSTATUSUPDATE = 0x0490
    MOT_GET_DCSTATUSUPDATE = 0x0491
    MOT_ACK_DCSTATUSUPDATE = 0x0492


#: Device-to-host messages the driver understands, with the data lengths they may carry (0 = short form).
DEVICE_MESSAGES: dict[int, frozenset[int]] = {
    Msg.HW_GET_INFO: frozenset({84}),
    Msg.HW_RESPONSE: frozenset({0}),
    Msg.HW_RICHRESPONSE: frozenset({68}),
    Msg.MOD_GET_CHANENABLESTATE: frozenset({0}),
    Msg.MOT_GET_POSCOUNTER: frozenset({6}),
    Msg.MOT_GET_VELPARAMS: frozenset({14}),
    Msg.MOT_GET_JOGPARAMS: frozenset({22}),
    Msg.MOT_GET_STATUSBITS: frozenset({6}),
    Msg.MOT_GET_GENMOVEPARAMS: frozenset({6}),
    Msg.MOT_GET_HOMEPARAMS: frozenset({14}),
    Msg.MOT_MOVE_HOMED: frozenset({0}),
    Msg.MOT_MOVE_COMPLETED: frozenset({0, 14}),  # short or long form: UNCONFIRMED for K10CR1 (§7 item 5)
    Msg.MOT_MOVE_STOPPED: frozenset({0, 14}),
    Msg.MOT_GET_STATUSUPDATE: frozenset({14}),
    Msg.MOT_GET_DCSTATUSUPDATE: frozenset({14}),
}


# -- status bits (anchors-protocols §2.3) -------------------------------------------------------------------
class Status(IntEnum):
    """Bits of the 32-bit motor status word (MOT_GET_STATUSBITS, STATUSUPDATE, DCSTATUSUPDATE).

    Limit-switch naming follows yaq and QMI (0x01 forward, 0x02 reverse); pylablib names them the other way
    round (anchors-protocols §2.3, CONFLICT).
    """

    FORWARD_LIMIT = 0x00000001
    REVERSE_LIMIT = 0x00000002
    FORWARD_SOFT_LIMIT = 0x00000004
    REVERSE_SOFT_LIMIT = 0x00000008
    MOVING_FORWARD = 0x00000010
    MOVING_REVERSE = 0x00000020
    JOGGING_FORWARD = 0x00000040
    JOGGING_REVERSE = 0x00000080
    MOTOR_CONNECTED = 0x00000100
    HOMING = 0x00000200
    HOMED = 0x00000400
    TRACKING = 0x00001000
    SETTLED = 0x00002000
    MOTION_ERROR = 0x00004000
    CURRENT_LIMIT = 0x01000000
    ACTIVE = 0x20000000
    ERROR = 0x40000000
    CHANNEL_ENABLED = 0x80000000


MOVING_MASK = (Status.MOVING_FORWARD | Status.MOVING_REVERSE | Status.JOGGING_FORWARD | Status.JOGGING_REVERSE
               | Status.HOMING)
LIMIT_MASK = Status.FORWARD_LIMIT | Status.REVERSE_LIMIT


@dataclass(frozen=True)
class AptStatus:
    """Decoded motor status word.

    Attributes
    ----------
    bits : int
        The raw 32-bit status word.
    position_counts : int or None
        Position [counts] when the message carried one (status update, long MOVE_COMPLETED).
    """

    bits: int
    position_counts: int | None = None

    def _has(self, mask: int) -> bool:
        return bool(self.bits & mask)

    @property
    def moving(self) -> bool:
        """Moving, jogging or homing."""
        return self._has(MOVING_MASK)

    @property
    def homing(self) -> bool:
        return self._has(Status.HOMING)

    @property
    def homed(self) -> bool:
        return self._has(Status.HOMED)

    @property
    def forward_limit(self) -> bool:
        return self._has(Status.FORWARD_LIMIT)

    @property
    def reverse_limit(self) -> bool:
        return self._has(Status.REVERSE_LIMIT)

    @property
    def motion_error(self) -> bool:
        return self._has(Status.MOTION_ERROR)

    @property
    def enabled(self) -> bool:
        return self._has(Status.CHANNEL_ENABLED)

    def faults(self) -> list[str]:
        """Names of the fault bits that are set (limit switches, motion error)."""
        names = {Status.FORWARD_LIMIT: "forward limit switch", Status.REVERSE_LIMIT: "reverse limit switch",
                 Status.MOTION_ERROR: "motion error"}
        return [text for bit, text in names.items() if self.bits & bit]


@dataclass(frozen=True)
class AptInfo:
    """Identity of an APT controller from HW_GET_INFO (anchors-protocols §2.3).

    Attributes
    ----------
    serial : int
    model : str
        e.g. ``"K10CR1"``.
    hw_type : int
    firmware : str
        ``"major.interim.minor"``.
    notes : str
    hw_version, mod_state, n_channels : int
    """

    serial: int
    model: str
    hw_type: int
    firmware: str
    notes: str
    hw_version: int
    mod_state: int
    n_channels: int


@dataclass(frozen=True)
class AptMessage:
    """One APT frame, split into its fields.

    Attributes
    ----------
    msg_id : int
    dest, source : int
        Addresses, with the long-form flag removed from `dest`.
    param1, param2 : int
        Parameter bytes of a short frame (0 for a long one).
    data : bytes
        Data packet of a long frame (``b""`` for a short one).
    """

    msg_id: int
    dest: int
    source: int
    param1: int = 0
    param2: int = 0
    data: bytes = b""

    @property
    def long(self) -> bool:
        return bool(self.data)

    @property
    def name(self) -> str:
        try:
            return Msg(self.msg_id).name
        except ValueError:
            return f"0x{self.msg_id:04X}"


# -- packing / unpacking (anchors-protocols §2.2) -------------------------------------------------------------
_SHORT = struct.Struct("<HBBBB")  # id, param1, param2, dest, source
_LONG = struct.Struct("<HHBB")  # id, data length, dest | 0x80, source
_CHAN_LONG = struct.Struct("<Hl")  # channel, signed 32-bit value (position, distance, backlash)
_VELPARAMS = struct.Struct("<Hlll")  # channel, min velocity, acceleration, max velocity
_STATUSBITS = struct.Struct("<HL")  # channel, status word
_STATUSUPDATE = struct.Struct("<HllL")  # channel, position, encoder count, status word
_DCSTATUS = struct.Struct("<HlhHL")  # channel, position, velocity, reserved, status word
_HOMEPARAMS = struct.Struct("<HHHll")  # channel, direction, limit switch, velocity, offset
_JOGPARAMS = struct.Struct("<HHllllH")  # channel, mode, step, min vel, accel, max vel, stop mode
_LIMSWITCHPARAMS = struct.Struct("<HHHllH")  # channel, CW hard, CCW hard, CW soft, CCW soft, soft limit mode
_HW_INFO = struct.Struct("<l8sH4B48s12sHHH")  # 84 bytes
_RICHRESPONSE = struct.Struct("<HH64s")


def pack_short(msg_id: int, param1: int = 0, param2: int = 0, *, dest: int = USB_UNIT, source: int = HOST) -> bytes:
    """A 6-byte header-only frame: ``id (LE u16), param1, param2, dest, source`` (anchors-protocols §2.2)."""
    return _SHORT.pack(msg_id, param1, param2, dest, source)


def pack_long(msg_id: int, data: bytes, *, dest: int = USB_UNIT, source: int = HOST) -> bytes:
    """A header with the long-form flag in ``dest`` followed by `data` (anchors-protocols §2.2)."""
    return _LONG.pack(msg_id, len(data), dest | LONG_FLAG, source) + bytes(data)


def header_length(header: bytes) -> int:
    """Length of the data packet announced by a 6-byte header (0 for a short frame)."""
    _, length, dest, _ = _LONG.unpack(header[:HEADER_SIZE])
    return length if dest & LONG_FLAG else 0


def unpack_message(frame: bytes) -> AptMessage:
    """Split a complete frame into an :class:`AptMessage`; raises ``ValueError`` on a length mismatch."""
    if len(frame) < HEADER_SIZE:
        raise ValueError(f"an APT frame has at least {HEADER_SIZE} bytes, got {len(frame)}")
    length = header_length(frame)
    if len(frame) != HEADER_SIZE + length:
        raise ValueError(f"header announces {length} data bytes, frame has {len(frame) - HEADER_SIZE}")
    if length:
        msg_id, _, dest, source = _LONG.unpack_from(frame)
        return AptMessage(msg_id, dest & ~LONG_FLAG, source, data=bytes(frame[HEADER_SIZE:]))
    msg_id, p1, p2, dest, source = _SHORT.unpack_from(frame)
    return AptMessage(msg_id, dest, source, p1, p2)


def deg_to_counts(angle_deg: float, counts_per_deg: float = K10CR1_COUNTS_PER_DEG) -> int:
    """Angle [°] → position counts (K10CR1: 409600/3 per degree, anchors-protocols §2.4)."""
    return int(round(angle_deg * counts_per_deg))


def counts_to_deg(counts: int, counts_per_deg: float = K10CR1_COUNTS_PER_DEG) -> float:
    """Position counts → angle [°]."""
    return counts / counts_per_deg


# message builders, host → device (anchors-protocols §2.3)
def move_absolute(position_counts: int, *, channel: int = 1, dest: int = USB_UNIT) -> bytes:
    """MOT_MOVE_ABSOLUTE, long form ``<H l>``: 90° on a K10CR1 is ``53 04 06 00 D0 01 01 00 00 80 BB 00``."""
    return pack_long(Msg.MOT_MOVE_ABSOLUTE, _CHAN_LONG.pack(channel, position_counts), dest=dest)


def move_relative(distance_counts: int, *, channel: int = 1, dest: int = USB_UNIT) -> bytes:
    """MOT_MOVE_RELATIVE, long form ``<H l>``."""
    return pack_long(Msg.MOT_MOVE_RELATIVE, _CHAN_LONG.pack(channel, distance_counts), dest=dest)


def set_velocity_params(accel_counts: int, max_velocity_counts: int, *, channel: int = 1,
                        dest: int = USB_UNIT) -> bytes:
    """MOT_SET_VELPARAMS ``<H l l l>``: channel, min velocity (always 0), acceleration, max velocity."""
    return pack_long(Msg.MOT_SET_VELPARAMS, _VELPARAMS.pack(channel, 0, accel_counts, max_velocity_counts), dest=dest)


def pack_velparams(channel: int, min_velocity: int, accel: int, max_velocity: int) -> bytes:
    """Data packet of MOT_GET/SET_VELPARAMS [counts/s, counts/s²]."""
    return _VELPARAMS.pack(channel, min_velocity, accel, max_velocity)


def pack_position(channel: int, position_counts: int) -> bytes:
    """Data packet ``<H l>`` of MOT_GET_POSCOUNTER, MOVE_ABSOLUTE, MOVE_RELATIVE, GENMOVEPARAMS."""
    return _CHAN_LONG.pack(channel, position_counts)


def pack_statusbits(channel: int, bits: int) -> bytes:
    """Data packet ``<H L>`` of MOT_GET_STATUSBITS."""
    return _STATUSBITS.pack(channel, bits & 0xFFFFFFFF)


def pack_statusupdate(channel: int, position_counts: int, encoder_counts: int, bits: int) -> bytes:
    """Data packet ``<H l l L>`` of MOT_GET_STATUSUPDATE (14 bytes)."""
    return _STATUSUPDATE.pack(channel, position_counts, encoder_counts, bits & 0xFFFFFFFF)


def pack_dcstatus(channel: int, position_counts: int, velocity: int, bits: int) -> bytes:
    """Data packet ``<H l h H L>`` of MOT_GET_DCSTATUSUPDATE and of long MOVE_COMPLETED / MOVE_STOPPED."""
    return _DCSTATUS.pack(channel, position_counts, velocity, 0, bits & 0xFFFFFFFF)


def pack_homeparams(channel: int, direction: int, limit_switch: int, velocity: int, offset: int) -> bytes:
    """Data packet ``<H H H l l>`` of MOT_GET/SET_HOMEPARAMS."""
    return _HOMEPARAMS.pack(channel, direction, limit_switch, velocity, offset)


def unpack_homeparams(data: bytes) -> tuple[int, int, int, int, int]:
    return _HOMEPARAMS.unpack(data[:_HOMEPARAMS.size])


def pack_jogparams(channel: int, mode: int, step: int, min_velocity: int, accel: int, max_velocity: int,
                   stop_mode: int) -> bytes:
    """Data packet ``<H H l l l l H>`` of MOT_GET/SET_JOGPARAMS (22 bytes)."""
    return _JOGPARAMS.pack(channel, mode, step, min_velocity, accel, max_velocity, stop_mode)


def unpack_jogparams(data: bytes) -> tuple[int, ...]:
    return _JOGPARAMS.unpack(data[:_JOGPARAMS.size])


def pack_limswitchparams(channel: int, cw_hard: int, ccw_hard: int, cw_soft: int, ccw_soft: int,
                         soft_mode: int) -> bytes:
    """Data packet ``<H H H l l H>`` of MOT_GET/SET_LIMSWITCHPARAMS (16 bytes): switch kinds, soft limits [counts]."""
    return _LIMSWITCHPARAMS.pack(channel, cw_hard, ccw_hard, cw_soft, ccw_soft, soft_mode)


def unpack_limswitchparams(data: bytes) -> tuple[int, ...]:
    return _LIMSWITCHPARAMS.unpack(data[:_LIMSWITCHPARAMS.size])


def pack_hw_info(serial: int, model: str, hw_type: int, firmware: tuple[int, int, int], notes: str = "",
                 hw_version: int = 1, mod_state: int = 0, n_channels: int = 1) -> bytes:
    """Data packet of HW_GET_INFO (84 bytes, ``<l 8s H 4B 48s 12s H H H>``); `firmware` is (major, interim, minor)."""
    major, interim, minor = firmware
    return _HW_INFO.pack(serial, model.encode("ascii"), hw_type, minor, interim, major, 0,
                         notes.encode("ascii"), b"", hw_version, mod_state, n_channels)


def pack_richresponse(msg_ident: int, code: int, notes: str) -> bytes:
    """Data packet ``<H H 64s>`` of HW_RICHRESPONSE: the message that failed, an error code, a text."""
    return _RICHRESPONSE.pack(msg_ident, code, notes.encode("ascii", "replace")[:64])


def parse_hw_info(data: bytes) -> AptInfo:
    """Decode a HW_GET_INFO data packet (anchors-protocols §2.3; firmware byte 0 = minor … byte 2 = major)."""
    serial, model, hw_type, minor, interim, major, _, notes, _, hw_version, mod_state, n_channels = (
        _HW_INFO.unpack(data[:_HW_INFO.size]))

    def text(raw: bytes) -> str:
        return raw.split(b"\0", 1)[0].decode("ascii", "replace").strip()

    return AptInfo(serial, text(model), hw_type, f"{major}.{interim}.{minor}", text(notes), hw_version,
                   mod_state, n_channels)


def parse_position(data: bytes) -> tuple[int, int]:
    """``(channel, counts)`` of a ``<H l>`` data packet (MOT_GET_POSCOUNTER, GENMOVEPARAMS)."""
    return _CHAN_LONG.unpack(data[:_CHAN_LONG.size])


def parse_velparams(data: bytes) -> tuple[int, int, int, int]:
    """``(channel, min velocity, acceleration, max velocity)`` of MOT_GET_VELPARAMS [counts]."""
    return _VELPARAMS.unpack(data[:_VELPARAMS.size])


def parse_status(message: AptMessage) -> AptStatus | None:
    """Status carried by a GET_STATUSBITS, GET_(DC)STATUSUPDATE or long MOVE_COMPLETED/STOPPED, else None."""
    if message.msg_id == Msg.MOT_GET_STATUSBITS and len(message.data) >= _STATUSBITS.size:
        return AptStatus(_STATUSBITS.unpack_from(message.data)[1])
    if message.msg_id == Msg.MOT_GET_STATUSUPDATE and len(message.data) >= _STATUSUPDATE.size:
        _, position, _, bits = _STATUSUPDATE.unpack_from(message.data)
        return AptStatus(bits, position)
    if (message.msg_id in (Msg.MOT_GET_DCSTATUSUPDATE, Msg.MOT_MOVE_COMPLETED, Msg.MOT_MOVE_STOPPED)
            and len(message.data) >= _DCSTATUS.size):
        _, position, _, _, bits = _DCSTATUS.unpack_from(message.data)
        return AptStatus(bits, position)
    return None


def parse_richresponse(data: bytes) -> tuple[int, int, str]:
    """``(failed message id, code, notes)`` of HW_RICHRESPONSE."""
    msg_ident, code, notes = _RICHRESPONSE.unpack(data[:_RICHRESPONSE.size])
    return msg_ident, code, notes.split(b"\0", 1)[0].decode("ascii", "replace")


# -- reading a stream of frames ---------------------------------------------------------------------------------
#: Addresses a controller answers from (§2.2): stand-alone unit, rack, bays 1–10, and 0 (some send it).
CONTROLLER_ADDRESSES = frozenset({0x00, RACK, USB_UNIT, *range(BAY0, BAY0 + 10)})
#: Device messages that name no channel; the short forms of the others carry it in param1, the long forms
#: in the first two bytes of the data packet (anchors-protocols §2.3).
_NO_CHANNEL_FIELD = frozenset({Msg.HW_GET_INFO, Msg.HW_RESPONSE, Msg.HW_RICHRESPONSE})


def frame_error(header: bytes, *, strict: bool = False) -> str | None:
    """Why 6 bytes cannot start a device-to-host frame the driver knows, or None if they can.

    The id must be known and the data length one that message has (a long-form flag with no data is not);
    the frame must be addressed to the host (0 is tolerated, like thorlabs-apt-device does). `strict` also
    asks for the host address exactly and a controller's source address: for bytes hunted through after a
    broken frame, or inside a data packet, where the lenient check would let chance patterns through.
    """
    msg_id = header[0] | header[1] << 8
    allowed = DEVICE_MESSAGES.get(msg_id)
    if allowed is None:
        return f"unknown message id 0x{msg_id:04X}"
    dest = header[4] & ~LONG_FLAG
    if dest not in (0x00, HOST) or (strict and dest != HOST):
        return f"frame 0x{msg_id:04X} addressed to 0x{dest:02X}, not to the host"
    length = header_length(header)
    if length not in allowed or (header[4] & LONG_FLAG and not length):
        return f"frame 0x{msg_id:04X} with {length} data bytes"
    if strict and header[5] not in CONTROLLER_ADDRESSES:
        return f"frame 0x{msg_id:04X} from 0x{header[5]:02X}, not from a controller"
    return None


class AptFrameReader:
    """Cuts the bytes a controller sends into frames, resynchronising on message headers.

    APT has no start byte and no checksum (§2.2): a frame ends where its header says, so a frame that lost
    bytes on the way swallows the start of the next one, and that header decoded as data is nonsense — a
    status word read from ``64 04 0E 00 81 50`` (a long MOVE_COMPLETED) says "reverse limit switch". So a
    frame is never decoded across a message boundary:

    * its header must be one the driver knows (:func:`frame_error`); otherwise one byte is dropped and the
      next tried (yaq's ``Unpacker``), with the strict check until a frame is found again (a HW_RESPONSE
      found that way must also have a header after it);
    * it must carry the driver's channel (param1 of a short frame, the first data bytes of a long one);
    * a strictly valid header (with the right channel) that starts inside the data packet, and whose own
      frame is followed by a header, means the frame was cut short there: its bytes are dropped and reading
      goes on at that header. "Followed" is taken on trust (part of a header, or nothing yet) only when the
      outer frame is itself in doubt (wrong channel, or junk after it) and more bytes may come; a frame that
      checks out keeps data that merely looks like a header (position 0x0444 then encoder 1 reads
      ``44 04 00 00 01 00``), and a HW_RESPONSE (no channel to check) needs a header after it. Of several
      such headers the last wins: a header-like pattern just before the real cut is always "followed";
    * what follows a frame must be a header, the start of one, or nothing yet: bytes that start no frame
      mean its end is no message boundary (a cut frame filled up with noise or another frame's middle);
    * a frame still incomplete when nothing more will come (the deadline) is dropped whole.

    A frame is judged by the bytes that have arrived when it completes (the driver reads whatever waits
    behind it first); a frame cut short whose window is filled, exactly, by the start of a frame whose rest
    has not arrived yet cannot be told from a whole one.

    Parameters
    ----------
    channel : int
        Channel ident the data packets must carry.

    Attributes
    ----------
    buffer : bytearray
        Bytes received and not yet taken.
    problems : list of (str, bytearray)
        What was dropped and why, oldest first; one entry per resynchronisation (the driver clears it).
    """

    def __init__(self, channel: int = 1):
        self.channel = channel
        self.buffer = bytearray()
        self.problems: list[tuple[str, bytearray]] = []
        self.hunting = False  # out of step after dropped bytes: headers are checked strictly

    def feed(self, data: bytes) -> None:
        self.buffer += data

    @property
    def need(self) -> int:
        """Bytes still missing from the frame at the front of the buffer (at least 1)."""
        if len(self.buffer) < HEADER_SIZE:
            return HEADER_SIZE - len(self.buffer)
        return max(HEADER_SIZE + header_length(self.buffer) - len(self.buffer), 1)  # 1: a look past the frame

    def next(self, *, final: bool = False) -> AptMessage | None:
        """The next whole frame, or None until more bytes arrive; `final`: none will (drop a cut-short front)."""
        buf = self.buffer
        while True:
            if len(buf) < HEADER_SIZE:
                if final and buf:
                    self._drop(len(buf), "truncated APT frame header", new=not self.hunting)
                return None
            why = frame_error(buf[:HEADER_SIZE], strict=self.hunting)
            if why:
                self._drop(1, why, new=not self.hunting)
                continue
            length = header_length(buf)
            size = HEADER_SIZE + length
            if self.hunting and size == HEADER_SIZE and self._channel(0, size) is None:
                # a HW_RESPONSE found in junk is only 4 bytes of evidence, and it raises a fault: believe it
                # only with a header after it
                if len(buf) < 2 * HEADER_SIZE and not final:
                    return None
                if not self._followed(HEADER_SIZE, partial_ok=False, end_ok=False):
                    self._drop(1, "HW_RESPONSE-like bytes in junk", new=False)
                    continue
            if len(buf) < size and not final:
                return None  # wait for the rest of the data packet
            name = _msg_name(buf)
            cut = self._cut(size, final)
            if cut is not None:
                self._drop(cut, f"truncated {name} frame: {cut - HEADER_SIZE} of {length} data bytes, then "
                                f"another frame", new=True)
                continue
            if len(buf) < size:
                self._drop(len(buf), f"truncated {name} frame: {len(buf) - HEADER_SIZE} of {length} data bytes",
                           new=True)
                return None
            channel = self._channel(0, size)
            if channel is not None and channel != self.channel:
                self._drop(1, f"{name} frame for channel {channel}, expected {self.channel}", new=True)
                continue
            if not self._followed(size):  # its end is no message boundary: it may hold another frame's bytes
                self._drop(1, f"{name} frame followed by bytes that start no frame", new=True)
                continue
            frame = bytes(buf[:size])
            del buf[:size]
            self.hunting = False
            return unpack_message(frame)

    def _drop(self, count: int, why: str, *, new: bool) -> None:
        dropped = self.buffer[:count]
        del self.buffer[:count]
        if new or not self.problems:
            self.problems.append((why, bytearray(dropped)))
        else:  # still hunting for a header: the same resynchronisation
            self.problems[-1][1].extend(dropped)
        self.hunting = True

    def _channel(self, start: int, end: int) -> int | None:
        """Channel named by the frame at `start` (ending at `end`); None if it names none or it has not arrived."""
        buf = self.buffer
        msg_id = buf[start] | buf[start + 1] << 8
        if msg_id in _NO_CHANNEL_FIELD:
            return None
        if end - start == HEADER_SIZE:
            return buf[start + 2]  # short form: param1
        if len(buf) < start + HEADER_SIZE + 2:
            return None
        return buf[start + HEADER_SIZE] | buf[start + HEADER_SIZE + 1] << 8

    def _followed(self, at: int, *, partial_ok: bool = True, end_ok: bool = True) -> bool:
        """Whether a frame can start at offset `at`: a valid header there, or nothing there yet (`end_ok`),
        or the start of one (`partial_ok`: a known id, or too few bytes to tell)."""
        rest = bytes(self.buffer[at:at + HEADER_SIZE])
        if len(rest) == HEADER_SIZE:
            end = at + HEADER_SIZE + header_length(rest)
            return frame_error(rest) is None and self._channel(at, end) in (None, self.channel)
        if not rest:
            return end_ok
        return partial_ok and (len(rest) < 2 or (rest[0] | rest[1] << 8) in DEVICE_MESSAGES)

    def _cut(self, size: int, final: bool) -> int | None:
        """Offset inside the frame at the front where another frame really starts, or None (see the class)."""
        buf = self.buffer
        whole = len(buf) >= size and self._channel(0, size) in (None, self.channel) and self._followed(size)
        found = None
        for at in range(HEADER_SIZE, min(size, len(buf) - HEADER_SIZE + 1)):
            header = bytes(buf[at:at + HEADER_SIZE])
            if frame_error(header, strict=True):
                continue
            end = at + HEADER_SIZE + header_length(header)
            channel = self._channel(at, end)
            if channel not in (None, self.channel):
                continue
            # a short frame naming no channel (HW_RESPONSE: 4 bytes of evidence, and it raises a fault) is
            # believed only with a header after it
            weak = end - at == HEADER_SIZE and channel is None
            if self._followed(end, partial_ok=not (whole or final or weak),
                              end_ok=not weak and (end >= size if whole else True)):
                found = at
        return found


def _msg_name(header) -> str:
    msg_id = header[0] | header[1] << 8
    try:
        return Msg(msg_id).name
    except ValueError:
        return f"0x{msg_id:04X}"


# -- the driver -----------------------------------------------------------------------------------------------
class AptRotationStage(RotaryAxis):
    """A Thorlabs K10CR1-class rotation stage on the APT protocol (anchors-protocols §2).

    The constructor does no I/O; :meth:`open` opens the port by URL and runs :meth:`initialize`.

    Parameters
    ----------
    port : Port
        Open port (115200 baud, RTS/CTS; see :meth:`open`).
    name : str, optional
        Name in errors and logs; default the port's name.
    limits : Limits
        Soft limits of the bench [°], checked before anything is sent.
    channel : int
        Channel ident (1 on single-channel units).
    dest : int
        Address of the controller: 0x50 for a stand-alone USB unit (K10CR1), 0x21 for a bay.
    counts_per_deg : float
        Position counts per degree (K10CR1: 409600/3).
    velocity_scale, accel_scale : float
        Velocity counts per °/s and acceleration counts per °/s² (K10CR1: 7329109, 1502; §2.4).
    max_velocity_deg_s, max_accel_deg_s2 : float
        Largest velocity [°/s] and acceleration [°/s²] :meth:`set_velocity_params` accepts (K10CR1: 10, 20).
    retries : int
        How many times a request is asked again after a garbled, cut or missing reply (default 3,
        :data:`~drivers.transport.DEFAULT_RETRIES`). Only requests (REQ_x) are repeated; commands that have
        no reply are sent once.

    Attributes
    ----------
    retry_count : int
        Requests asked again so far: how noisy the link is.
    """

    def __init__(self, port: Port, *, name: str | None = None, limits: Limits = Limits(-360.0, 360.0),
                 channel: int = 1, dest: int = USB_UNIT, counts_per_deg: float = K10CR1_COUNTS_PER_DEG,
                 velocity_scale: float = K10CR1_VELOCITY_SCALE, accel_scale: float = K10CR1_ACCEL_SCALE,
                 max_velocity_deg_s: float = K10CR1_MAX_VELOCITY_DEG_S,
                 max_accel_deg_s2: float = K10CR1_MAX_ACCEL_DEG_S2, retries: int = DEFAULT_RETRIES):
        self.port = port
        self.name = name or port.name
        self.limits = limits
        self.channel = channel
        self.dest = dest
        self.counts_per_deg = counts_per_deg
        self.velocity_scale = velocity_scale
        self.accel_scale = accel_scale
        self.max_velocity_deg_s = max_velocity_deg_s
        self.max_accel_deg_s2 = max_accel_deg_s2
        self.retries = retries
        self.retry_count = 0  # requests asked again since the driver was made (link quality)
        self._reader = AptFrameReader(channel)
        self.last_status: AptStatus | None = None  # latest status seen, asked for or volunteered
        self.events: list[str] = []  # volunteered completion messages seen (MOT_MOVE_COMPLETED …), oldest first
        self._homed_seen = False
        self._fault: DeviceFault | None = None

    @classmethod
    def open(cls, url: str, *, timeout_s: float = 1.0, dwell_s: float = 0.05, record=None,
             **kwargs) -> AptRotationStage:
        """Open the port at `url` (115200 baud, RTS/CTS), initialise the link and enable the channel.

        Parameters
        ----------
        url : str
            ``/dev/ttyUSB0``, ``sim://k10cr1``, a pty path …
        timeout_s : float
            Reply timeout [s].
        dwell_s : float
            Dwell of each step of the RTS cycle [s] (50 ms in the APT manual, anchors-protocols §2.1).
        record
            Passed to :func:`~drivers.transport.open_port`.
        kwargs
            Passed to the constructor.
        """
        port = open_port(url, baudrate=115200, rtscts=True, timeout_s=timeout_s, record=record,
                         name=kwargs.get("name"))
        stage = cls(port, **kwargs)
        try:
            stage.initialize(dwell_s=dwell_s)
        except Exception:
            port.close()
            raise
        return stage

    # -- link -------------------------------------------------------------------------------------------
    def initialize(self, *, dwell_s: float = 0.05) -> AptInfo:
        """Run the APT init: RTS cycle and purge, no-flash, stop update messages, identify, enable channel.

        The RTS cycle follows pylablib (anchors-protocols §2.1); a pseudo-terminal refuses the RTS ioctl
        with errno 25, which is logged and ignored so the same code runs against a pty simulator.

        Returns
        -------
        AptInfo
        """
        self._cycle_rts(dwell_s)
        self._send(pack_short(Msg.HW_NO_FLASH_PROGRAMMING, dest=self.dest))
        self._send(pack_short(Msg.HW_STOP_UPDATEMSGS, dest=self.dest))
        info = self.info()
        self.enable(True)
        return info

    def _cycle_rts(self, dwell_s: float) -> None:
        raw = self.port.raw
        try:
            raw.rts = True
            time.sleep(dwell_s)
            self.port.discard_input()
            time.sleep(dwell_s)
            raw.rts = False
            time.sleep(dwell_s)
        except OSError as exc:
            # a pty has no modem lines: ENOTTY (25) or EINVAL; anything else is a dead port
            if exc.errno not in (errno.ENOTTY, errno.EINVAL):
                raise DeviceDisconnected(self.name, f"cannot set RTS ({exc})") from None
            log.info("%s: RTS not settable (%s); assuming a pseudo-terminal", self.name, exc)
        self.port.discard_input()

    # -- exchanges --------------------------------------------------------------------------------------
    def _read_frame(self, deadline: float) -> AptMessage:
        """The next frame from the controller (see :class:`AptFrameReader`); DeviceTimeout at `deadline`."""
        reader = self._reader
        while True:
            message = reader.next()
            if message is not None:
                return message
            left = deadline - time.monotonic()
            if left > 0:  # checked here too: a stream of volunteered bytes must not hold the deadline off
                try:
                    data = self.port.read_exact(reader.need, timeout_s=left)
                except DeviceTimeout as exc:
                    reader.feed(exc.received)
                else:
                    # what has already arrived behind the frame shows where the next one starts
                    reader.feed(data + self.port.read_available())
                    continue
            message = reader.next(final=True)  # a frame cut short at the front is dropped here
            if message is not None:
                return message
            raise DeviceTimeout(self.name, "no APT reply within the timeout")

    def _note(self, message: AptMessage) -> None:
        """Handle a message the device volunteered (or a late reply): remember it, never take it as a reply."""
        status = parse_status(message)
        if status is not None:
            self.last_status = status
        if message.msg_id in (Msg.MOT_MOVE_COMPLETED, Msg.MOT_MOVE_STOPPED, Msg.MOT_MOVE_HOMED):
            self.events.append(message.name)
            del self.events[:-32]
            if message.msg_id == Msg.MOT_MOVE_HOMED:
                self._homed_seen = True
        elif message.msg_id == Msg.HW_RESPONSE:
            self._fault = DeviceFault(self.name, "controller reports an error (HW_RESPONSE)")
        elif message.msg_id == Msg.HW_RICHRESPONSE:
            failed, code, notes = parse_richresponse(message.data)
            self._fault = DeviceFault(self.name, f"controller reports error {code} on message 0x{failed:04X}: "
                                                 f"{notes}")
        else:
            log.debug("%s: ignored %s", self.name, message.name)

    def _drain(self) -> None:
        """Take in whatever waits before a new exchange: note complete frames, drop the rest."""
        reader = self._reader
        reader.feed(self.port.read_available())
        while (message := reader.next()) is not None:
            self._note(message)
        if reader.buffer:  # the start of a frame: its rest, if it ever comes, is hunted through
            reader.problems.append(("stale bytes", bytearray(reader.buffer)))
            reader.buffer.clear()
            reader.hunting = True
        for why, dropped in reader.problems:
            log.debug("%s: dropped %d stale bytes %s (%s)", self.name, len(dropped), dropped.hex(" "), why)
        reader.problems.clear()

    def _raise_fault(self) -> None:
        fault, self._fault = self._fault, None
        if fault is not None:
            raise fault

    def _send(self, frame: bytes, *, check_faults: bool = True) -> None:
        """Send a command that has no reply: sent once, never retried (there is no reply to judge it by)."""
        with self.port.transaction():
            self._drain()
            if check_faults:
                self._raise_fault()
            self.port.write(frame)

    def _query(self, request: bytes, reply_id: int) -> AptMessage:
        """Send `request`, return the first frame with id `reply_id`; volunteered frames are noted on the way.

        Every request sent here is a REQ_x, safe to repeat, so a garbled, cut or missing reply is asked again
        (:attr:`retries` times, :func:`~drivers.transport.ask_again`). APT has no sequence number: a late
        reply that arrives after the request was repeated is taken for the reply; it answers the same
        question, at most one timeout earlier.
        """
        def attempt() -> AptMessage:
            with self.port.transaction():
                self._drain()
                self.port.write(request)
                deadline = time.monotonic() + self.port.timeout_s
                while True:
                    try:
                        message = self._read_frame(deadline)
                    except DeviceTimeout:
                        if self._fault is not None:  # the device answered with an error instead
                            self._raise_fault()
                        problems = self._reader.problems
                        if problems:  # the reply came, broken: say how (the first problem is the cause)
                            why, dropped = problems[0]
                            more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
                            problems.clear()
                            raise ProtocolError(self.name, why + more, received=bytes(dropped)) from None
                        raise
                    if message.msg_id == reply_id:
                        break
                    self._note(message)
                for why, dropped in self._reader.problems:  # resynchronised, the reply is good
                    log.warning("%s: dropped %d bytes (%s)", self.name, len(dropped), why)
                self._reader.problems.clear()
            self._raise_fault()
            return message

        return ask_again(self.name, attempt, self.retries, on_retry=self._count_retry)

    def _count_retry(self, exc: Exception) -> None:
        self.retry_count += 1

    # -- identity ---------------------------------------------------------------------------------------
    def info(self) -> AptInfo:
        """Serial, model and firmware from HW_REQ_INFO → HW_GET_INFO."""
        return parse_hw_info(self._query(pack_short(Msg.HW_REQ_INFO, dest=self.dest), Msg.HW_GET_INFO).data)

    def identify(self) -> str:
        """``"Thorlabs K10CR1 s/n 55000123 fw 3.0.10"``."""
        info = self.info()
        return f"Thorlabs {info.model} s/n {info.serial} fw {info.firmware}"

    def blink(self) -> None:
        """Flash the front-panel LED (MOD_IDENTIFY)."""
        self._send(pack_short(Msg.MOD_IDENTIFY, self.channel, dest=self.dest))

    # -- channel ----------------------------------------------------------------------------------------
    def enable(self, on: bool = True) -> None:
        """Enable (hold) or disable (free) the motor channel (MOD_SET_CHANENABLESTATE, 1 = on, 2 = off)."""
        self._send(pack_short(Msg.MOD_SET_CHANENABLESTATE, self.channel, 1 if on else 2, dest=self.dest))

    def is_enabled(self) -> bool:
        """Channel enable state (MOD_REQ_CHANENABLESTATE)."""
        reply = self._query(pack_short(Msg.MOD_REQ_CHANENABLESTATE, self.channel, dest=self.dest),
                            Msg.MOD_GET_CHANENABLESTATE)
        if reply.param2 not in (1, 2):
            raise ProtocolError(self.name, f"channel enable state {reply.param2} is neither 1 nor 2")
        return reply.param2 == 1

    # -- state ------------------------------------------------------------------------------------------
    def status(self) -> AptStatus:
        """Motor status word (MOT_REQ_STATUSBITS → MOT_GET_STATUSBITS)."""
        reply = self._query(pack_short(Msg.MOT_REQ_STATUSBITS, self.channel, dest=self.dest), Msg.MOT_GET_STATUSBITS)
        self.last_status = parse_status(reply)
        return self.last_status

    def position_counts(self) -> int:
        """Position counter [counts] (MOT_REQ_POSCOUNTER → MOT_GET_POSCOUNTER)."""
        reply = self._query(pack_short(Msg.MOT_REQ_POSCOUNTER, self.channel, dest=self.dest),
                            Msg.MOT_GET_POSCOUNTER)
        return parse_position(reply.data)[1]

    def position_deg(self) -> float:
        """Measured position [°]: counter / counts per degree."""
        return counts_to_deg(self.position_counts(), self.counts_per_deg)

    def is_moving(self) -> bool:
        """True while moving, jogging or homing (status bits, anchors-protocols §2.3).

        Raises
        ------
        DeviceFault
            Motion error, or the axis stopped on a limit switch. A limit bit during homing or while the axis
            still moves (leaving the switch) is not a fault.
        """
        status = self.status()
        if status.motion_error or (status.faults() and not status.moving):
            raise DeviceFault(self.name, f"{', '.join(status.faults())} (status 0x{status.bits:08X})")
        return status.moving

    # -- motion -----------------------------------------------------------------------------------------
    def _start_move(self, angle_deg: float) -> None:
        # Always MOVE_ABSOLUTE: it is idempotent, so a bench layer that repeats a move after a link error
        # lands in the same place; MOVE_RELATIVE or MOVE_HOME repeated would move again or re-home.
        self._send(move_absolute(deg_to_counts(angle_deg, self.counts_per_deg), channel=self.channel,
                                 dest=self.dest))

    def stop(self, *, immediate: bool = False) -> None:
        """Stop (MOT_MOVE_STOP; profiled = 2 by default, immediate = 1). Sent even if a fault is pending."""
        self._send(pack_short(Msg.MOT_MOVE_STOP, self.channel, 1 if immediate else 2, dest=self.dest),
                   check_faults=False)

    def home(self, *, wait: bool = True, timeout_s: float = 300.0) -> None:
        """Run the homing sequence (MOT_MOVE_HOME); with `wait`, return once homed.

        Completion is read from the status bits; MOVE_HOMED, if volunteered, is taken as confirmation.

        Raises
        ------
        DeviceFault
            Homing ended without the homed bit or a MOVE_HOMED.
        DeviceTimeout
            Still homing after `timeout_s`.
        """
        self._homed_seen = False
        self._send(pack_short(Msg.MOT_MOVE_HOME, self.channel, dest=self.dest))
        if wait:
            self.wait_until_stopped(timeout_s=timeout_s)
            if not (self._homed_seen or self.status().homed):
                raise DeviceFault(self.name, "homing ended but the stage does not report homed")

    # -- velocity parameters ----------------------------------------------------------------------------
    def velocity_params(self) -> tuple[float, float]:
        """``(max velocity [°/s], acceleration [°/s²])`` (MOT_REQ_VELPARAMS, anchors-protocols §2.4 scales)."""
        reply = self._query(pack_short(Msg.MOT_REQ_VELPARAMS, self.channel, dest=self.dest), Msg.MOT_GET_VELPARAMS)
        _, _, accel, max_velocity = parse_velparams(reply.data)
        return max_velocity / self.velocity_scale, accel / self.accel_scale

    def expected_motion(self) -> AxisMotion:
        """The stage's move velocity and acceleration as the controller holds them (MOT_REQ_VELPARAMS)."""
        rate, accel = self.velocity_params()
        return AxisMotion(rate, accel)

    def set_velocity_params(self, max_velocity_deg_s: float, accel_deg_s2: float) -> None:
        """Set the move velocity [°/s] and acceleration [°/s²] (MOT_SET_VELPARAMS).

        Raises
        ------
        LimitError
            Outside (0, max] of the stage; nothing is sent.
        """
        if not (0 < max_velocity_deg_s <= self.max_velocity_deg_s and math.isfinite(max_velocity_deg_s)):
            raise LimitError(self.name, f"velocity {max_velocity_deg_s} °/s outside (0, {self.max_velocity_deg_s}]")
        if not (0 < accel_deg_s2 <= self.max_accel_deg_s2 and math.isfinite(accel_deg_s2)):
            raise LimitError(self.name, f"acceleration {accel_deg_s2} °/s² outside (0, {self.max_accel_deg_s2}]")
        self._send(set_velocity_params(int(round(accel_deg_s2 * self.accel_scale)),
                                       int(round(max_velocity_deg_s * self.velocity_scale)),
                                       channel=self.channel, dest=self.dest))

    def close(self) -> None:
        self.port.close()
