"""Wire-level simulator of a Thorlabs K10CR1 rotation stage (APT protocol, anchors-protocols §2, §6 item 3).

Split the lewis way: the physics is an :class:`~drivers.sim.motion.AxisModel` on the world's clock; this
module is the protocol front (bytes in, bytes out); the back door is :attr:`AptStageSimulator.faults`
(wire faults) and :attr:`AptStageSimulator.axis` (``stall()``, ``trip_limit()``), never the wire.

Device analysis (what the front does):

* Framing: 6-byte header, long form when bit 7 of the destination byte is set (§2.2). Frames addressed to
  0x50 (USB unit), 0x11 (rack) or 0x21 (bay 0) are served, other addresses are ignored; an unknown message
  id loses one byte and the parser tries again at the next byte (yaq's ``Unpacker`` resync). The id met at
  a frame boundary that started such a resync is kept in :attr:`AptStageSimulator.unknown_ids` (back door:
  a peer test asserts that a client sent nothing the simulator ignores).
* Replies come from the host's point of view: destination 0x01, source 0x50.
* HW_REQ_INFO → HW_GET_INFO (84 bytes, model ``K10CR1``); MOD_SET/REQ_CHANENABLESTATE; MOT_MOVE_HOME →
  MOVE_HOMED when the axis reaches the home switch; MOT_MOVE_ABSOLUTE / RELATIVE (long form, or short
  form with the stored parameters) → MOVE_COMPLETED when the move ends, MOVE_STOPPED when it ends on a
  limit switch; MOT_MOVE_STOP → MOVE_STOPPED; MOT_REQ_POSCOUNTER, MOT_REQ_STATUSBITS,
  MOT_REQ_(DC)STATUSUPDATE, MOT_REQ/SET_VELPARAMS, JOGPARAMS, GENMOVEPARAMS, HOMEPARAMS, LIMSWITCHPARAMS;
  MOT_SET_POSCOUNTER; MOT_MOVE_JOG and MOT_MOVE_VELOCITY (below).
* Completion messages (MOVE_COMPLETED, MOVE_STOPPED, MOVE_HOMED) are always volunteered, never part of the
  reply to a command, so that they follow any reply owed to a request received with the command. QMI
  relies on this: after MOVE_STOP it asks MOT_REQ_STATUSBITS at once, and when both requests arrive in one
  read, a MOVE_STOPPED before the status reply made its ``ask`` give up (measured over the pty).
* MOT_MOVE_VELOCITY (0x0457; short, p1 = channel, p2 = 1 forward / 2 reverse): "the motor will move
  continuously in the specified direction, using the velocity parameters [MOT_SET_VELPARAMS] until either a
  stop command … is called, or a limit switch is reached" (APT manual, as quoted by thorpy and the
  thorlabs_apt_protocol package). MOT_MOVE_STOP then stops it and MOVE_STOPPED is volunteered; it also
  ends on a hard limit switch (MOVE_STOPPED, limit bit set). Where no switch stops it, the simulator ends it
  at the soft limit, else at the end of the signed 32-bit position counter (about ±15 729° on a K10CR1; QMI
  notes the real counter overflows there) with MOVE_STOPPED — the real device's behaviour there is
  UNCONFIRMED. In instant mode (simulated time stands still) observing the axis completes any motion, so a
  move at velocity runs at once to that end.
* MOT_MOVE_JOG (0x046A; short, p1 = channel, p2 = 1 forward / 2 reverse) uses the jog parameters
  (MOT_SET_JOGPARAMS 0x0416, ``<H H l l l l H>``: mode 1 continuous / 2 single step, step size, min velocity,
  acceleration, max velocity, stop mode 1 immediate / 2 profiled): a single step moves by the step size at
  the jog's max velocity and ends with MOVE_COMPLETED; a continuous jog runs like a move at velocity (at the
  jog's max velocity) until MOT_MOVE_STOP. Over the wire there is no "button released", so that reading of
  continuous mode is UNCONFIRMED, as is MOVE_COMPLETED after a jog step. The jog's own acceleration is
  stored and reported, but the axis accelerates at the velocity parameters' acceleration (the axis model has
  one acceleration). The default jog is a 1° single step at the velocity parameters' speed (K10CR1 factory
  jog settings UNCONFIRMED).
* Direction: 1 = forward, 2 = reverse (manual: "0x01 forward, 0x02 reverse"); by default forward counts
  up, as homing suggests (stages home in reverse onto the reverse switch, read 0 there and count up away
  from it). Which way forward turns a K10CR1 is UNCONFIRMED, and it differs between devices:
  thorlabs-apt-device 0.3.8 offers ``invert_direction_logic`` because "on some devices, 'forward' velocity
  moves towards negative encoder counts", and pylablib 1.4.5 assumes it for every Kinesis motor
  (``KinesisMotor._forward_positive = False``: ``jog("+")`` sends 2, and it names status bit 0x10
  "moving_bk") — CONFLICT. ``forward_counts_up=False`` gives pylablib's reading. The jogging bits follow
  the direction byte either way; the limit bits stay with the ends of the count (the high end is the
  forward switch), as in thorlabs-apt-device, where direction and limit switches are separate settings.
* MOT_MOVE_STOP (p2 = 1 immediate, 2 profiled; manual: "stop … immediately" / "in a controlled (profiled)
  manner") → MOVE_STOPPED once the axis is at rest. An immediate stop (and any stop of a stalled axis) stops
  at once. A profiled stop comes to rest where decelerating at the velocity parameters' acceleration would
  (v²/2a further: 2.5° from 10 °/s at 20 °/s²), reporting "moving" until then; the axis model starts moves
  from rest, so the simulator brakes with a fresh triangular move over that distance, which takes √2·v/a
  instead of v/a and dips to v/√2 at once (an approximation). QMI needs the delay: it asks the status right
  after MOVE_STOP, and a MOVE_STOPPED arriving while its ``ask`` sleeps made the ask give up (measured).
* Limit switches (MOT_SET/REQ/GET_LIMSWITCHPARAMS 0x0423/0x0424/0x0425, ``<H H H l l H>``: CW hard-switch
  kind, CCW hard-switch kind, CW soft limit, CCW soft limit [counts], soft-limit mode). Kinds (manual, via
  thorpy): 1 ignore / absent, 2 makes on contact, 3 breaks on contact, 4 / 5 the same used for homing only,
  6 index mark; 0x80 OR'd in swaps CW and CCW. Soft-limit mode: 1 ignore, 2 stop immediately, 3 profiled
  stop. The defaults describe the axis: switches that make on contact when its spec has hard limits, else a
  K10CR1-like CW "absent" and CCW "homing only" (its home switch; the K10CR1's factory values are
  UNCONFIRMED); soft limits from the spec with mode 2, else mode 1 with the counter's extremes. CW is taken
  as forward (UNCONFIRMED). Setting them stores what was sent and sets the axis's soft limits (mode 2 or 3
  with CCW < CW) or clears them (mode 1); the hard-switch kinds are reported back but do not change the
  mechanics.
* MOT_SET_POSCOUNTER (0x0410, ``<H l>``; pylablib's ``set_position_reference``) redefines the position
  counter of an axis at rest (the load does not move); while the axis moves it is ignored (UNCONFIRMED).
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
  "homing" during homing and the jogging bit of the direction during a jog (UNCONFIRMED: QMI saw only
  "jogging reverse" on a K10CR1); "homed"; "settled" at rest; "channel enabled".
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
    pack_limswitchparams,
    pack_long,
    pack_position,
    pack_richresponse,
    pack_short,
    pack_statusbits,
    pack_statusupdate,
    pack_velparams,
    unpack_homeparams,
    unpack_jogparams,
    unpack_limswitchparams,
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
    Msg.MOT_SET_POSCOUNTER: frozenset({6}),
    Msg.MOT_REQ_POSCOUNTER: frozenset({0}),
    Msg.MOT_SET_VELPARAMS: frozenset({14}),
    Msg.MOT_REQ_VELPARAMS: frozenset({0}),
    Msg.MOT_SET_JOGPARAMS: frozenset({22}),
    Msg.MOT_REQ_JOGPARAMS: frozenset({0}),
    Msg.MOT_SET_LIMSWITCHPARAMS: frozenset({16}),
    Msg.MOT_REQ_LIMSWITCHPARAMS: frozenset({0}),
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
    Msg.MOT_MOVE_VELOCITY: frozenset({0}),
    Msg.MOT_MOVE_JOG: frozenset({0}),
    Msg.MOT_MOVE_STOP: frozenset({0}),
    Msg.MOT_REQ_STATUSUPDATE: frozenset({0}),
    Msg.MOT_REQ_DCSTATUSUPDATE: frozenset({0}),
    Msg.MOT_ACK_DCSTATUSUPDATE: frozenset({0}),
}

_MAX_DATA = 255  # "no data packet exceeds 255 bytes" (APT manual, via thorlabs-apt-device's unpacker)

_DIRECTIONS = {1: 1.0, 2: -1.0}  # MOVE_JOG / MOVE_VELOCITY p2: forward (counts up), reverse
_COUNTER_MAX, _COUNTER_MIN = 2**31 - 1, -2**31  # the signed 32-bit position counter
# limit-switch kinds and soft-limit modes (MOT_SET_LIMSWITCHPARAMS, APT manual via thorpy)
SWITCH_ABSENT, SWITCH_MAKES, SWITCH_MAKES_HOME = 1, 2, 4
SOFT_IGNORE, SOFT_STOP_IMMEDIATE, SOFT_STOP_PROFILED = 1, 2, 3


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
    forward_counts_up : bool
        Jogs and moves at velocity "forward" (p2 = 1) count up (default) or down (see the module docstring).
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
    jog_params : tuple of int
        (mode, step, min velocity, acceleration, max velocity, stop mode) in APT units (MOT_SET_JOGPARAMS).
    limit_switch_params : tuple of int
        (CW kind, CCW kind, CW soft limit, CCW soft limit, soft-limit mode) (MOT_SET_LIMSWITCHPARAMS).
    unknown_ids : list of int
        Message ids the front did not know, each met where a frame should start (the back door's record of
        what a client sent that went unanswered); the bytes dropped while resyncing are not listed.
    """

    name = "thorlabs-k10cr1"

    def __init__(self, world, spec: AxisSpec, serial_number: int, *, model: str = "K10CR1",
                 firmware: tuple[int, int, int] = (3, 0, 10), counts_per_deg: float = K10CR1_COUNTS_PER_DEG,
                 velocity_scale: float = K10CR1_VELOCITY_SCALE, accel_scale: float = K10CR1_ACCEL_SCALE,
                 completion_form: str = "long", update_period_s: float = 0.1, forward_counts_up: bool = True,
                 channel: int = 1):
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
        self.forward_sign = 1.0 if forward_counts_up else -1.0
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
        self.limit_switch_params = self._default_limit_switch_params(spec)
        self.unknown_ids: list[int] = []
        self._resyncing = False
        self._pending: str | None = None  # "move" / "run" / "stop" / "home": a completion message is owed
        self._owed: list[int] = []  # completion messages to volunteer at the next poll (MOVE_STOPPED)
        self._jogging = 0.0  # direction of the jog in progress (status bits), 0 when not jogging
        self._motion: tuple[float, float, float] | None = None  # (t0, duration, rate) of the last start
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

    def _default_limit_switch_params(self, spec: AxisSpec) -> tuple[int, int, int, int, int]:
        if spec.hard_limits_deg is not None:
            cw, ccw = SWITCH_MAKES, SWITCH_MAKES
        else:  # a K10CR1 turns freely and has a home switch only (which side: its homing is reverse, §2.3)
            cw, ccw = SWITCH_ABSENT, SWITCH_MAKES_HOME
        if spec.soft_limits_deg is not None:
            low, high = spec.soft_limits_deg
            return cw, ccw, self.counts(high), self.counts(low), SOFT_STOP_IMMEDIATE
        return cw, ccw, _COUNTER_MAX, _COUNTER_MIN, SOFT_IGNORE

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
            if self._jogging:
                bits |= Status.JOGGING_FORWARD if self._jogging > 0 else Status.JOGGING_REVERSE
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
                if not self._resyncing:
                    self.unknown_ids.append(msg_id)
                    self._resyncing = True
                del inbuf[0]  # resync: drop one byte and look again (yaq Unpacker)
                continue
            self._resyncing = False
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
                self._pending, self._jogging = None, 0.0
        elif m.msg_id == Msg.MOD_REQ_CHANENABLESTATE:
            return self._short(Msg.MOD_GET_CHANENABLESTATE, self.channel, 1 if self.enabled else 2)
        elif m.msg_id == Msg.MOT_REQ_POSCOUNTER:
            return self._long(Msg.MOT_GET_POSCOUNTER, pack_position(self.channel, self.position_counts()))
        elif m.msg_id == Msg.MOT_SET_POSCOUNTER:
            if not axis.busy():  # re-reference the counter; the load stays where it is
                new_deg = struct.unpack("<Hl", m.data)[1] / self.counts_per_deg
                axis.true_minus_reported += axis.motor_deg - new_deg
                axis.motor_deg = new_deg
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
        elif m.msg_id == Msg.MOT_REQ_LIMSWITCHPARAMS:
            return self._long(Msg.MOT_GET_LIMSWITCHPARAMS,
                              pack_limswitchparams(self.channel, *self.limit_switch_params))
        elif m.msg_id == Msg.MOT_SET_LIMSWITCHPARAMS:
            self._set_limit_switch_params(unpack_limswitchparams(m.data)[1:])
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
                self._motion = (self.world.clock.now(), axis.home(), axis.spec.home_rate_deg_s)
                self._pending, self._jogging = "home", 0.0
        elif m.msg_id == Msg.MOT_MOVE_ABSOLUTE:
            target = struct.unpack("<Hl", m.data)[1] if m.data else self.abs_params_counts
            return self._move(Msg.MOT_MOVE_ABSOLUTE, target / self.counts_per_deg)
        elif m.msg_id == Msg.MOT_MOVE_RELATIVE:
            distance = struct.unpack("<Hl", m.data)[1] if m.data else self.rel_params_counts
            return self._move(Msg.MOT_MOVE_RELATIVE, axis.position_deg() + distance / self.counts_per_deg)
        elif m.msg_id == Msg.MOT_MOVE_VELOCITY:
            direction = _DIRECTIONS.get(m.param2)
            if direction is not None:
                return self._move(Msg.MOT_MOVE_VELOCITY, self._run_end_deg(direction * self.forward_sign),
                                  kind="run")
        elif m.msg_id == Msg.MOT_MOVE_JOG:
            return self._jog(m.param2)
        elif m.msg_id == Msg.MOT_MOVE_STOP:
            speed = self._speed_deg_s()
            axis.stop()
            self._jogging = 0.0
            if m.param2 == 2 and speed > 0 and not axis.stalled and self._brake(speed):
                self._pending = "stop"  # MOVE_STOPPED when at rest
            elif self._pending:
                self._pending = None
                self._owed.append(Msg.MOT_MOVE_STOPPED)  # volunteered after any reply (module docstring)
        # HW_NO_FLASH_PROGRAMMING, MOT_ACK_DCSTATUSUPDATE: nothing to do, nothing to say
        return b""

    def _set_limit_switch_params(self, params: tuple[int, ...]) -> None:
        cw, ccw, cw_soft, ccw_soft, mode = params
        self.limit_switch_params = (cw, ccw, cw_soft, ccw_soft, mode)
        mode &= 0x7F
        spec = self.axis.spec
        if mode in (SOFT_STOP_IMMEDIATE, SOFT_STOP_PROFILED) and ccw_soft < cw_soft:
            limits = (ccw_soft / self.counts_per_deg, cw_soft / self.counts_per_deg)
            self.axis.spec = dataclasses.replace(spec, soft_limits_deg=limits)
        elif mode == SOFT_IGNORE:
            self.axis.spec = dataclasses.replace(spec, soft_limits_deg=None)

    def _run_end_deg(self, sign: float) -> float:
        """Where a move at velocity counting up (`sign` > 0) or down ends unless stopped: the soft limit, else
        the end of the counter [°]. A hard limit switch on the way stops it first (the axis model's job)."""
        limits = self.axis.spec.soft_limits_deg
        if limits is not None:
            return limits[1] if sign > 0 else limits[0]
        return (_COUNTER_MAX if sign > 0 else _COUNTER_MIN) / self.counts_per_deg

    def _jog(self, p2: int) -> bytes:
        direction = _DIRECTIONS.get(p2)
        if direction is None:
            return b""
        mode, step, _, _, max_velocity, _ = self.jog_params
        rate, sign = max_velocity / self.velocity_scale, direction * self.forward_sign
        if mode == 1:  # continuous: until MOT_MOVE_STOP
            return self._move(Msg.MOT_MOVE_JOG, self._run_end_deg(sign), rate_deg_s=rate, kind="run",
                              jogging=direction)
        target = self.axis.position_deg() + sign * abs(step) / self.counts_per_deg
        return self._move(Msg.MOT_MOVE_JOG, target, rate_deg_s=rate, jogging=direction)

    def _move(self, msg_id: int, target_deg: float, *, rate_deg_s: float | None = None, kind: str = "move",
              jogging: float = 0.0) -> bytes:
        """Start a motion to `target_deg` at `rate_deg_s` (default: the velocity parameters' speed)."""
        if not self.enabled:
            return b""
        try:
            self._start(target_deg, rate_deg_s)
        except AxisLimitError as exc:
            return self._long(Msg.HW_RICHRESPONSE, pack_richresponse(msg_id, 1, str(exc)))
        self._pending, self._jogging = kind, jogging
        return b""

    def _start(self, target_deg: float, rate_deg_s: float | None) -> None:
        axis = self.axis
        spec = axis.spec
        rate = rate_deg_s if rate_deg_s is not None and rate_deg_s > 0 else spec.max_rate_deg_s
        # the axis model takes the speed of a move from its spec when the move starts (and keeps it); the
        # acceleration stays the spec's
        axis.spec = dataclasses.replace(spec, max_rate_deg_s=rate)
        try:
            self._motion = (self.world.clock.now(), axis.move_to(target_deg), rate)
        finally:
            axis.spec = spec

    def _speed_deg_s(self) -> float:
        """Speed of the motion in progress [°/s], from its trapezoid (0 at rest)."""
        if self._motion is None or not self.axis.busy():
            return 0.0
        t0, duration, rate = self._motion
        accel = self.axis.spec.accel_deg_s2
        t = self.world.clock.now() - t0
        if t <= 0 or t >= duration:
            return 0.0
        if duration >= 2.0 * rate / accel:  # trapezoid: accelerate, cruise, decelerate
            return min(accel * t, rate, accel * (duration - t))
        return min(accel * t, accel * (duration - t))  # triangle

    def _brake(self, speed: float) -> bool:
        """After ``axis.stop()``: run on to where a profiled stop from `speed` ends; False if it cannot."""
        distance = speed * speed / (2.0 * self.axis.spec.accel_deg_s2)
        if distance < self.axis.spec.step_deg:
            return False
        try:
            self._start(self.axis.position_deg() + self.axis.direction * distance, speed)
        except AxisLimitError:
            return False  # a soft limit or a switch right there: it stops where it is
        return True

    # -- volunteered output ---------------------------------------------------------------------------------
    def unsolicited(self) -> bytes:
        out = bytearray()
        for msg_id in self._owed:
            out += self._completion(msg_id)
        self._owed.clear()
        if self._pending and not self.axis.busy():  # in instant mode, asking busy() completes the move
            if self._pending == "home":
                out += self._short(Msg.MOT_MOVE_HOMED, self.channel)
            elif self.axis.limit_hit or self._pending in ("run", "stop"):
                out += self._completion(Msg.MOT_MOVE_STOPPED)
            else:
                out += self._completion(Msg.MOT_MOVE_COMPLETED)
            self._pending, self._jogging = None, 0.0
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
