"""Wire-level simulator of a Thorlabs K10CR1 rotation stage (APT protocol, anchors-protocols §2, §6 item 3).

Split the lewis way: the physics is an :class:`~drivers.sim.motion.AxisModel` on the world's clock; this
module is the protocol front (bytes in, bytes out); the back door is :attr:`AptStageSimulator.faults`
(wire faults) and :attr:`AptStageSimulator.axis` (``stall()``, ``trip_limit()``), never the wire.

Device analysis (what the front does):

* Framing: 6-byte header, long form when bit 7 of the destination byte is set (§2.2). Frames addressed to
  0x50 (USB unit), 0x11 (rack) or 0x21 (bay 0) are served, other addresses are ignored; an unknown message
  id loses one byte and the parser tries again at the next byte (yaq's ``Unpacker`` resync).
* Replies come from the host's point of view: destination 0x01, source 0x50.
* HW_REQ_INFO → HW_GET_INFO (84 bytes, model ``K10CR1``); MOD_SET/REQ_CHANENABLESTATE; MOT_MOVE_HOME →
  MOVE_HOMED when the axis reaches the home switch; MOT_MOVE_ABSOLUTE / RELATIVE (long form, or short
  form with the stored parameters) → MOVE_COMPLETED when the move ends, MOVE_STOPPED when it ends on a
  limit switch; MOT_MOVE_STOP → MOVE_STOPPED; MOT_REQ_POSCOUNTER, MOT_REQ_STATUSBITS,
  MOT_REQ_(DC)STATUSUPDATE, MOT_REQ/SET_VELPARAMS, JOGPARAMS, GENMOVEPARAMS, HOMEPARAMS.
* MOVE_COMPLETED / MOVE_STOPPED are sent in the long form (14-byte status block ``<H l h H L>``) by
  default. Which form a K10CR1 sends is UNCONFIRMED (§7 item 5); §6 suggested short by default, but both
  public peers that parse it (QMI's ``_AptMsgMoveCompleted`` and thorlabs-apt-device's
  ``mot_move_completed``) expect the long form, and the latter's reader dies on the short one. The short
  form stays selectable (``completion_form="short"``).
* After HW_START_UPDATEMSGS the stage volunteers MOT_GET_STATUSUPDATE every `update_period_s` of simulated
  time (the real rate is UNCONFIRMED, §7 item 5); in instant mode, where simulated time stands still,
  it volunteers one whenever the position or the status word changed.
* Status word (§2.3): motor connected always; forward/reverse limit from the axis model's ``limit_hit``
  ("high"/"low"); while busy **both** moving bits (QMI observed this on a K10CR1) and "active", plus
  "homing" during homing; "homed"; "settled" at rest; "channel enabled".
* A move the axis model refuses (soft limits, or into the limit switch it sits on) is answered with
  HW_RICHRESPONSE naming MOT_MOVE_ABSOLUTE — the real device's reply is UNCONFIRMED, so this is ours.
  Motion commands on a disabled channel are ignored (also UNCONFIRMED).
"""

from __future__ import annotations

import dataclasses
import struct

from ..thorlabs_apt import (
    BAY0,
    HEADER_SIZE,
    HOST,
    K10CR1_ACCEL_SCALE,
    K10CR1_COUNTS_PER_DEG,
    K10CR1_VELOCITY_SCALE,
    RACK,
    USB_UNIT,
    Msg,
    Status,
    header_length,
    pack_dcstatus,
    pack_homeparams,
    pack_hw_info,
    pack_jogparams,
    pack_long,
    pack_position,
    pack_richresponse,
    pack_short,
    pack_statusbits,
    pack_statusupdate,
    pack_velparams,
    unpack_homeparams,
    unpack_jogparams,
    unpack_message,
)
from .device import SimDevice
from .motion import AxisLimitError, AxisSpec

#: Addresses the stage answers to (anchors-protocols §2.2: thorlabs-apt-device's TDC001 uses 0x11 / 0x21).
ADDRESSES = (USB_UNIT, RACK, BAY0)

# Host-to-device messages the front knows: allowed data lengths (0 = short form).
_COMMANDS: dict[int, frozenset[int]] = {
    Msg.HW_DISCONNECT: frozenset({0}),
    Msg.HW_REQ_INFO: frozenset({0}),
    Msg.HW_START_UPDATEMSGS: frozenset({0}),
    Msg.HW_STOP_UPDATEMSGS: frozenset({0}),
    Msg.HW_NO_FLASH_PROGRAMMING: frozenset({0}),
    Msg.MOD_SET_CHANENABLESTATE: frozenset({0}),
    Msg.MOD_REQ_CHANENABLESTATE: frozenset({0}),
    Msg.MOD_IDENTIFY: frozenset({0}),
    Msg.MOT_REQ_POSCOUNTER: frozenset({0}),
    Msg.MOT_SET_VELPARAMS: frozenset({14}),
    Msg.MOT_REQ_VELPARAMS: frozenset({0}),
    Msg.MOT_SET_JOGPARAMS: frozenset({22}),
    Msg.MOT_REQ_JOGPARAMS: frozenset({0}),
    Msg.MOT_REQ_STATUSBITS: frozenset({0}),
    Msg.MOT_SET_GENMOVEPARAMS: frozenset({6}),
    Msg.MOT_REQ_GENMOVEPARAMS: frozenset({0}),
    Msg.MOT_SET_HOMEPARAMS: frozenset({14}),
    Msg.MOT_REQ_HOMEPARAMS: frozenset({0}),
    Msg.MOT_MOVE_HOME: frozenset({0}),
    Msg.MOT_SET_MOVERELPARAMS: frozenset({6}),
    Msg.MOT_MOVE_RELATIVE: frozenset({0, 6}),
    Msg.MOT_SET_MOVEABSPARAMS: frozenset({6}),
    Msg.MOT_MOVE_ABSOLUTE: frozenset({0, 6}),
    Msg.MOT_MOVE_STOP: frozenset({0}),
    Msg.MOT_REQ_STATUSUPDATE: frozenset({0}),
    Msg.MOT_REQ_DCSTATUSUPDATE: frozenset({0}),
    Msg.MOT_ACK_DCSTATUSUPDATE: frozenset({0}),
}

_MAX_DATA = 255  # "no data packet exceeds 255 bytes" (APT manual, via thorlabs-apt-device's unpacker)


class AptStageSimulator(SimDevice):
    """Protocol front of one simulated K10CR1 driving one axis of the world.

    Parameters
    ----------
    world : SimWorld
        The shared truth; the stage creates its axis with ``world.new_axis(spec)`` (attach it to the table
        with ``world.attach_table`` if the sensor should see it).
    spec : AxisSpec
        Mechanics of the axis; its `max_rate_deg_s`, `accel_deg_s2` and `home_rate_deg_s` are what
        MOT_GET_VELPARAMS / HOMEPARAMS report, and MOT_SET_VELPARAMS / HOMEPARAMS change them.
    serial_number : int
        Serial in HW_GET_INFO (K10CR1 serials start with 55, e.g. 55000123).
    model : str
        Model string in HW_GET_INFO.
    firmware : (int, int, int)
        (major, interim, minor).
    counts_per_deg, velocity_scale, accel_scale : float
        APT units of the stage (K10CR1 defaults, anchors-protocols §2.4).
    completion_form : {"long", "short"}
        Form of MOVE_COMPLETED / MOVE_STOPPED (see the module docstring).
    update_period_s : float
        Period of volunteered status updates after HW_START_UPDATEMSGS [s of simulated time].
    channel : int

    Attributes
    ----------
    axis : AxisModel
        The physics, and half of the back door (``stall()``, ``trip_limit()``).
    enabled : bool
    host_disconnected : bool
        Set when the host sent HW_DISCONNECT.
    blinks : int
        Number of MOD_IDENTIFY received.
    """

    name = "thorlabs-k10cr1"

    def __init__(self, world, spec: AxisSpec, serial_number: int, *, model: str = "K10CR1",
                 firmware: tuple[int, int, int] = (3, 0, 10), counts_per_deg: float = K10CR1_COUNTS_PER_DEG,
                 velocity_scale: float = K10CR1_VELOCITY_SCALE, accel_scale: float = K10CR1_ACCEL_SCALE,
                 completion_form: str = "long", update_period_s: float = 0.1, channel: int = 1):
        super().__init__()
        if completion_form not in ("long", "short"):
            raise ValueError(f"`completion_form` must be 'long' or 'short', got {completion_form!r}")
        self.world = world
        self.axis = world.new_axis(spec)
        self.serial_number = int(serial_number)
        self.model = model
        self.firmware = firmware
        self.counts_per_deg = counts_per_deg
        self.velocity_scale = velocity_scale
        self.accel_scale = accel_scale
        self.completion_form = completion_form
        self.update_period_s = update_period_s
        self.channel = channel
        self.enabled = True  # K10CR1 channels are enabled at power-up (QMI k10crx)
        self.updates = False
        self.host_disconnected = False
        self.blinks = 0
        self.abs_params_counts = 0
        self.rel_params_counts = 0
        self.backlash_counts = 0
        self.home_dir, self.home_limit_switch, self.home_offset_counts = 2, 1, 0
        self.jog_params = (2, self.counts(1.0), 0, self._accel_counts(), self._velocity_counts(), 2)
        self._pending: str | None = None  # "move" / "home": a completion message is owed
        self._last_update_t: float | None = None
        self._last_update_state: tuple[int, int] | None = None

    # -- units --------------------------------------------------------------------------------------------
    def counts(self, angle_deg: float) -> int:
        return int(round(angle_deg * self.counts_per_deg))

    def _velocity_counts(self) -> int:
        return int(round(self.axis.spec.max_rate_deg_s * self.velocity_scale))

    def _accel_counts(self) -> int:
        return int(round(self.axis.spec.accel_deg_s2 * self.accel_scale))

    def position_counts(self) -> int:
        return self.counts(self.axis.position_deg())

    def status_bits(self) -> int:
        """Status word of the stage now (anchors-protocols §2.3)."""
        axis = self.axis
        busy = axis.busy()
        bits = Status.MOTOR_CONNECTED
        if axis.limit_hit == "high":
            bits |= Status.FORWARD_LIMIT
        elif axis.limit_hit == "low":
            bits |= Status.REVERSE_LIMIT
        if busy:
            bits |= Status.MOVING_FORWARD | Status.MOVING_REVERSE | Status.ACTIVE  # both, as QMI saw on K10CR1
            if axis.homing:
                bits |= Status.HOMING
        else:
            bits |= Status.SETTLED
        if axis.homed:
            bits |= Status.HOMED
        if self.enabled:
            bits |= Status.CHANNEL_ENABLED
        return int(bits)

    # -- frames out ---------------------------------------------------------------------------------------
    def _short(self, msg_id: int, p1: int = 0, p2: int = 0) -> bytes:
        return pack_short(msg_id, p1, p2, dest=HOST, source=USB_UNIT)

    def _long(self, msg_id: int, data: bytes) -> bytes:
        return pack_long(msg_id, data, dest=HOST, source=USB_UNIT)

    def _completion(self, msg_id: int) -> bytes:
        if self.completion_form == "short":
            return self._short(msg_id, self.channel)
        return self._long(msg_id, pack_dcstatus(self.channel, self.position_counts(), 0, self.status_bits()))

    def _status_update(self) -> bytes:
        position = self.position_counts()
        return self._long(Msg.MOT_GET_STATUSUPDATE, pack_statusupdate(self.channel, position, position,
                                                                      self.status_bits()))

    # -- frames in ----------------------------------------------------------------------------------------
    def handle(self, inbuf: bytearray) -> bytes:
        out = bytearray()
        while len(inbuf) >= HEADER_SIZE:
            msg_id = inbuf[0] | inbuf[1] << 8
            allowed = _COMMANDS.get(msg_id)
            length = header_length(bytes(inbuf[:HEADER_SIZE]))
            if allowed is None or length > _MAX_DATA:
                del inbuf[0]  # resync: drop one byte and look again (yaq Unpacker)
                continue
            if len(inbuf) < HEADER_SIZE + length:
                break  # wait for the rest of the data packet
            frame = bytes(inbuf[:HEADER_SIZE + length])
            del inbuf[:HEADER_SIZE + length]
            message = unpack_message(frame)
            if message.dest not in ADDRESSES or length not in allowed:
                continue  # someone else's frame, or a form this message does not have
            out += self._dispatch(message)
        return bytes(out)

    def _dispatch(self, m) -> bytes:
        axis = self.axis
        if m.msg_id == Msg.HW_REQ_INFO:
            return self._long(Msg.HW_GET_INFO, pack_hw_info(self.serial_number, self.model, 16, self.firmware,
                                                            "APT Stepper Motor Controller"))
        if m.msg_id == Msg.HW_START_UPDATEMSGS:
            self.updates, self._last_update_t, self._last_update_state = True, None, None
        elif m.msg_id == Msg.HW_STOP_UPDATEMSGS:
            self.updates = False
        elif m.msg_id == Msg.HW_DISCONNECT:
            self.host_disconnected = True
        elif m.msg_id == Msg.MOD_IDENTIFY:
            self.blinks += 1
        elif m.msg_id == Msg.MOD_SET_CHANENABLESTATE:
            self.enabled = m.param2 == 1
            if not self.enabled:
                axis.stop()  # a free motor does not hold or move
                self._pending = None
        elif m.msg_id == Msg.MOD_REQ_CHANENABLESTATE:
            return self._short(Msg.MOD_GET_CHANENABLESTATE, self.channel, 1 if self.enabled else 2)
        elif m.msg_id == Msg.MOT_REQ_POSCOUNTER:
            return self._long(Msg.MOT_GET_POSCOUNTER, pack_position(self.channel, self.position_counts()))
        elif m.msg_id == Msg.MOT_REQ_STATUSBITS:
            return self._long(Msg.MOT_GET_STATUSBITS, pack_statusbits(self.channel, self.status_bits()))
        elif m.msg_id == Msg.MOT_REQ_STATUSUPDATE:
            return self._status_update()
        elif m.msg_id == Msg.MOT_REQ_DCSTATUSUPDATE:
            # velocity is a signed 16-bit field, too small for K10CR1 counts: report 0
            return self._long(Msg.MOT_GET_DCSTATUSUPDATE,
                              pack_dcstatus(self.channel, self.position_counts(), 0, self.status_bits()))
        elif m.msg_id == Msg.MOT_REQ_VELPARAMS:
            return self._long(Msg.MOT_GET_VELPARAMS,
                              pack_velparams(self.channel, 0, self._accel_counts(), self._velocity_counts()))
        elif m.msg_id == Msg.MOT_SET_VELPARAMS:
            _, _, accel, max_velocity = struct.unpack("<Hlll", m.data)
            if accel > 0 and max_velocity > 0:
                axis.spec = dataclasses.replace(axis.spec, max_rate_deg_s=max_velocity / self.velocity_scale,
                                                accel_deg_s2=accel / self.accel_scale)
        elif m.msg_id == Msg.MOT_REQ_JOGPARAMS:
            return self._long(Msg.MOT_GET_JOGPARAMS, pack_jogparams(self.channel, *self.jog_params))
        elif m.msg_id == Msg.MOT_SET_JOGPARAMS:
            self.jog_params = unpack_jogparams(m.data)[1:]
        elif m.msg_id == Msg.MOT_REQ_GENMOVEPARAMS:
            return self._long(Msg.MOT_GET_GENMOVEPARAMS, pack_position(self.channel, self.backlash_counts))
        elif m.msg_id == Msg.MOT_SET_GENMOVEPARAMS:
            self.backlash_counts = struct.unpack("<Hl", m.data)[1]
        elif m.msg_id == Msg.MOT_REQ_HOMEPARAMS:
            velocity = int(round(axis.spec.home_rate_deg_s * self.velocity_scale))
            return self._long(Msg.MOT_GET_HOMEPARAMS, pack_homeparams(self.channel, self.home_dir,
                                                                      self.home_limit_switch, velocity,
                                                                      self.home_offset_counts))
        elif m.msg_id == Msg.MOT_SET_HOMEPARAMS:
            _, self.home_dir, self.home_limit_switch, velocity, self.home_offset_counts = unpack_homeparams(m.data)
            if velocity > 0:
                axis.spec = dataclasses.replace(axis.spec, home_rate_deg_s=velocity / self.velocity_scale)
        elif m.msg_id == Msg.MOT_SET_MOVEABSPARAMS:
            self.abs_params_counts = struct.unpack("<Hl", m.data)[1]
        elif m.msg_id == Msg.MOT_SET_MOVERELPARAMS:
            self.rel_params_counts = struct.unpack("<Hl", m.data)[1]
        elif m.msg_id == Msg.MOT_MOVE_HOME:
            if self.enabled:
                axis.home()
                self._pending = "home"
        elif m.msg_id == Msg.MOT_MOVE_ABSOLUTE:
            target = struct.unpack("<Hl", m.data)[1] if m.data else self.abs_params_counts
            return self._move(Msg.MOT_MOVE_ABSOLUTE, target / self.counts_per_deg)
        elif m.msg_id == Msg.MOT_MOVE_RELATIVE:
            distance = struct.unpack("<Hl", m.data)[1] if m.data else self.rel_params_counts
            return self._move(Msg.MOT_MOVE_RELATIVE, axis.position_deg() + distance / self.counts_per_deg)
        elif m.msg_id == Msg.MOT_MOVE_STOP:
            axis.stop()
            if self._pending:
                self._pending = None
                return self._completion(Msg.MOT_MOVE_STOPPED)
        # HW_NO_FLASH_PROGRAMMING, MOT_ACK_DCSTATUSUPDATE: nothing to do, nothing to say
        return b""

    def _move(self, msg_id: int, target_deg: float) -> bytes:
        if not self.enabled:
            return b""
        try:
            self.axis.move_to(target_deg)
        except AxisLimitError as exc:
            return self._long(Msg.HW_RICHRESPONSE, pack_richresponse(msg_id, 1, str(exc)))
        self._pending = "move"
        return b""

    # -- volunteered output ---------------------------------------------------------------------------------
    def unsolicited(self) -> bytes:
        out = bytearray()
        if self._pending and not self.axis.busy():  # in instant mode, asking busy() completes the move
            if self._pending == "home":
                out += self._short(Msg.MOT_MOVE_HOMED, self.channel)
            elif self.axis.limit_hit:
                out += self._completion(Msg.MOT_MOVE_STOPPED)
            else:
                out += self._completion(Msg.MOT_MOVE_COMPLETED)
            self._pending = None
        if self.updates:
            now = self.world.clock.now()
            state = (self.position_counts(), self.status_bits())
            if self.world.clock.instant:
                due = state != self._last_update_state
            else:
                due = self._last_update_t is None or now - self._last_update_t >= self.update_period_s
            if due:
                out += self._status_update()
                self._last_update_t, self._last_update_state = now, state
        return bytes(out)
