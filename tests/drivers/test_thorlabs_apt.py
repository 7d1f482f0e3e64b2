"""Thorlabs APT driver as byte-exact scripted exchanges (PyMeasure style).

Golden bytes are the examples of anchors-protocols §2.3 (computed from the header layout of §2.2 and
matching yaq's README: ``mot_move_home`` → ``43 04 01 00 50 01``); the K10CR1 units are those of §2.4.
"""

import errno
import random
import struct

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import Limits
from drivers.testing import ScriptedSerial, scripted_port
from drivers.thorlabs_apt import (
    AptFrameReader,
    AptMessage,
    AptRotationStage,
    Msg,
    counts_to_deg,
    deg_to_counts,
    move_absolute,
    move_relative,
    pack_long,
    pack_short,
    parse_hw_info,
    parse_position,
    parse_status,
    parse_velparams,
    set_velocity_params,
    unpack_message,
)
from drivers.transport import Port


def h(text: str) -> bytes:
    return bytes.fromhex(text)


STEP_DEG = 3.0 / 409600.0  # K10CR1 encoder resolution (anchors-protocols §2.4)

# requests, host 0x01 → stage 0x50 (anchors-protocols §2.3)
NO_FLASH = h("18 00 00 00 50 01")
REQ_INFO = h("05 00 00 00 50 01")
STOP_UPDATES = h("12 00 00 00 50 01")
ENABLE = h("10 02 01 01 50 01")
DISABLE = h("10 02 01 02 50 01")
REQ_ENABLE = h("11 02 01 00 50 01")
BLINK = h("23 02 01 00 50 01")
HOME = h("43 04 01 00 50 01")
MOVE_90 = h("53 04 06 00 D0 01 01 00 00 80 BB 00")
STOP_PROFILED = h("65 04 01 02 50 01")
STOP_IMMEDIATE = h("65 04 01 01 50 01")
REQ_POS = h("11 04 01 00 50 01")
REQ_STATUS = h("29 04 01 00 50 01")
REQ_VEL = h("14 04 01 00 50 01")
SET_VEL_10_20 = h("13 04 0E 00 D0 01 01 00 00 00 00 00 58 75 00 00 52 55 5E 04")

# replies, stage → host
POS_90 = h("12 04 06 00 81 50 01 00 00 80 BB 00")
VEL_10_20 = h("15 04 0E 00 81 50 01 00 00 00 00 00 58 75 00 00 52 55 5E 04")
MOVE_HOMED = h("44 04 01 00 01 50")
MOVE_COMPLETED_SHORT = h("64 04 01 00 01 50")
ENABLED_REPLY = h("12 02 01 01 01 50")
DISABLED_REPLY = h("12 02 01 02 01 50")
HW_RESPONSE = h("80 00 00 00 01 50")

CONNECTED, ENABLED, HOMED, SETTLED = 0x100, 0x80000000, 0x400, 0x2000
MOVING = 0x10 | 0x20 | 0x20000000  # a K10CR1 sets both direction bits while moving (QMI, §2.3)
IDLE = CONNECTED | ENABLED | SETTLED
IDLE_HOMED = IDLE | HOMED


def status_reply(bits: int, source: int = 0x50) -> bytes:
    """MOT_GET_STATUSBITS: header ``2A 04 06 00 81 50`` + ``<H L>`` channel, status word."""
    return bytes([0x2A, 0x04, 0x06, 0x00, 0x81, source]) + struct.pack("<HL", 1, bits)


def pos_reply(counts: int, source: int = 0x50) -> bytes:
    return bytes([0x12, 0x04, 0x06, 0x00, 0x81, source]) + struct.pack("<Hl", 1, counts)


def completed_long(counts: int, bits: int) -> bytes:
    """MOT_MOVE_COMPLETED long form: header ``64 04 0E 00 81 50`` + ``<H l h H L>`` status block."""
    return h("64 04 0E 00 81 50") + struct.pack("<HlhHL", 1, counts, 0, 0, bits)


INFO = h("06 00 54 00 81 50") + struct.pack("<l8sH4B48s12sHHH", 55000123, b"K10CR1", 16, 10, 0, 3, 0,
                                            b"APT Stepper Motor Controller", b"", 1, 0, 1)


def stage(port, **kwargs) -> AptRotationStage:
    s = AptRotationStage(port, **kwargs)
    s.poll_s = 0.0  # scripted exchanges need no pause between polls
    return s


# -- pure helpers ----------------------------------------------------------------------------------------------
def test_message_builders_give_the_golden_bytes_of_the_research_note():
    assert pack_short(Msg.MOT_MOVE_HOME, 1) == HOME
    assert move_absolute(deg_to_counts(90.0)) == MOVE_90
    assert move_absolute(2048) == h("53 04 06 00 D0 01 01 00 00 08 00 00"), "yaq README example"
    assert move_relative(deg_to_counts(-1.0)) == h("48 04 06 00 D0 01 01 00 AB EA FD FF")
    assert set_velocity_params(20 * 1502, 10 * 7329109) == SET_VEL_10_20
    assert pack_short(Msg.MOT_MOVE_STOP, 1, 2) == STOP_PROFILED
    assert pack_short(Msg.HW_REQ_INFO) == REQ_INFO
    assert pack_short(Msg.HW_START_UPDATEMSGS) == h("11 00 00 00 50 01")
    assert pack_short(Msg.MOT_REQ_STATUSUPDATE, 1) == h("80 04 01 00 50 01")
    assert pack_short(Msg.MOT_REQ_DCSTATUSUPDATE, 1) == h("90 04 01 00 50 01")
    assert pack_short(Msg.MOT_ACK_DCSTATUSUPDATE) == h("92 04 00 00 50 01")
    assert pack_short(Msg.MOD_SET_CHANENABLESTATE, 1, 1) == ENABLE


def test_units_of_the_k10cr1():
    assert deg_to_counts(90.0) == 12_288_000  # 409600/3 µsteps per degree
    assert counts_to_deg(12_288_000) == 90.0
    assert deg_to_counts(-1.0) == -136533


def test_unpacking_frames_and_data_packets():
    reply = unpack_message(POS_90)
    assert reply == AptMessage(Msg.MOT_GET_POSCOUNTER, 0x01, 0x50, data=POS_90[6:])
    assert parse_position(reply.data) == (1, 12_288_000)
    assert unpack_message(MOVE_HOMED) == AptMessage(Msg.MOT_MOVE_HOMED, 0x01, 0x50, 1, 0)
    assert parse_velparams(unpack_message(VEL_10_20).data) == (1, 0, 30040, 73291090)
    info = parse_hw_info(unpack_message(INFO).data)
    assert (info.serial, info.model, info.firmware, info.n_channels) == (55000123, "K10CR1", "3.0.10", 1)
    status = parse_status(unpack_message(completed_long(5, IDLE_HOMED)))
    assert (status.position_counts, status.homed, status.moving) == (5, True, False)
    with pytest.raises(ValueError):
        unpack_message(POS_90[:-1])


# -- every command, byte for byte ----------------------------------------------------------------------------------
def test_initialize_purges_stops_updates_identifies_and_enables():
    with scripted_port([(NO_FLASH, b""), (STOP_UPDATES, b""), (REQ_INFO, INFO), (ENABLE, b"")]) as port:
        info = stage(port).initialize(dwell_s=0.0)
    assert (info.model, info.serial) == ("K10CR1", 55000123)


class _PtyLike(ScriptedSerial):
    """A scripted port whose RTS line cannot be set, like a pseudo-terminal (anchors-protocols §2.1)."""

    error = errno.ENOTTY

    @property
    def rts(self):
        return False

    @rts.setter
    def rts(self, value):
        raise OSError(self.error, "Inappropriate ioctl for device")


def test_initialize_tolerates_the_rts_ioctl_failing_on_a_pty():
    raw = _PtyLike([(NO_FLASH, b""), (STOP_UPDATES, b""), (REQ_INFO, INFO), (ENABLE, b"")])
    assert stage(Port(raw, name="pty", timeout_s=0.05)).initialize(dwell_s=0.0).model == "K10CR1"
    raw.check_done()


def test_initialize_reports_a_dead_port_when_rts_fails_otherwise():
    raw = _PtyLike([])
    raw.error = errno.EIO
    with pytest.raises(DeviceDisconnected):
        stage(Port(raw, name="gone", timeout_s=0.05)).initialize(dwell_s=0.0)


def test_identify():
    with scripted_port([(REQ_INFO, INFO)]) as port:
        assert stage(port).identify() == "Thorlabs K10CR1 s/n 55000123 fw 3.0.10"


def test_enable_disable_and_read_back():
    with scripted_port([(ENABLE, b""), (DISABLE, b""), (REQ_ENABLE, DISABLED_REPLY),
                        (REQ_ENABLE, ENABLED_REPLY)]) as port:
        s = stage(port)
        s.enable(True)
        s.enable(False)
        assert s.is_enabled() is False
        assert s.is_enabled() is True


def test_blink():
    with scripted_port([(BLINK, b"")]) as port:
        stage(port).blink()


def test_position_is_read_from_the_counter():
    with scripted_port([(REQ_POS, POS_90)]) as port:
        assert stage(port).position_deg() == 90.0


def test_reply_source_byte_is_not_insisted_on():
    # some controllers put 0 in the source byte (anchors-protocols §2.2)
    with scripted_port([(REQ_POS, pos_reply(12_288_000, source=0x00)),
                        (REQ_STATUS, status_reply(IDLE, source=0x21))]) as port:
        s = stage(port)
        assert s.position_deg() == 90.0
        assert s.is_moving() is False


def test_status_bits_decode():
    with scripted_port([(REQ_STATUS, status_reply(IDLE_HOMED | MOVING | 0x200))]) as port:
        status = stage(port).status()
    assert status.moving and status.homing and status.homed and status.enabled
    assert status.faults() == []


def test_move_absolute_waits_for_the_status_bits_and_consumes_move_completed():
    script = [
        (MOVE_90, b""),
        (REQ_STATUS, status_reply(IDLE | MOVING)),
        (b"", completed_long(12_288_000, IDLE)),  # volunteered after the reply: must not be taken for one
        (REQ_STATUS, status_reply(IDLE)),
        (REQ_POS, POS_90),
    ]
    with scripted_port(script) as port:
        s = stage(port)
        s.move_to(90.0, timeout_s=1.0)
    assert s.events == ["MOT_MOVE_COMPLETED"]
    assert not s.last_status.moving


def test_unsolicited_messages_before_the_reply_are_consumed_not_mistaken_for_it():
    script = [
        (REQ_POS, b""),
        (b"", MOVE_COMPLETED_SHORT),
        (b"", h("81 04 0E 00 81 50") + struct.pack("<HllL", 1, 7, 7, IDLE)),  # a status update
        (b"", MOVE_HOMED),
        (b"", POS_90),
    ]
    with scripted_port(script) as port:
        s = stage(port)
        assert s.position_deg() == 90.0
    assert s.events == ["MOT_MOVE_COMPLETED", "MOT_MOVE_HOMED"]
    assert s.last_status.position_counts == 7


def test_move_without_waiting_sends_only_the_move():
    with scripted_port([(MOVE_90, b"")]) as port:
        stage(port).move_to(90.0, wait=False)


def test_soft_limits_refuse_before_anything_is_sent():
    with scripted_port([]) as port:
        s = stage(port, limits=Limits(-10.0, 100.0))
        with pytest.raises(LimitError):
            s.move_to(100.5)
        with pytest.raises(LimitError):
            s.move_to(float("nan"))


def test_stop_profiled_and_immediate():
    with scripted_port([(STOP_PROFILED, b""), (STOP_IMMEDIATE, b"")]) as port:
        s = stage(port)
        s.stop()
        s.stop(immediate=True)


def test_home_completes_on_status_bits_and_move_homed():
    script = [
        (HOME, b""),
        (REQ_STATUS, status_reply(IDLE | MOVING | 0x200)),
        (b"", MOVE_HOMED),
        (REQ_STATUS, status_reply(IDLE_HOMED)),
        (REQ_POS, pos_reply(0)),
    ]
    with scripted_port(script) as port:
        s = stage(port)
        s.home(timeout_s=1.0)
    assert "MOT_MOVE_HOMED" in s.events


def test_home_that_ends_without_homed_is_a_fault():
    script = [(HOME, b""), (REQ_STATUS, status_reply(IDLE)), (REQ_POS, pos_reply(0)), (REQ_STATUS, status_reply(IDLE))]
    with scripted_port(script) as port:
        with pytest.raises(DeviceFault, match="homed"):
            stage(port).home(timeout_s=1.0)


def test_velocity_parameters_in_degrees():
    with scripted_port([(REQ_VEL, VEL_10_20), (SET_VEL_10_20, b"")]) as port:
        s = stage(port)
        assert s.velocity_params() == pytest.approx((10.0, 20.0))
        s.set_velocity_params(10.0, 20.0)


def test_velocity_parameters_out_of_range_are_refused_before_sending():
    with scripted_port([]) as port:
        s = stage(port)
        with pytest.raises(LimitError):
            s.set_velocity_params(11.0, 5.0)
        with pytest.raises(LimitError):
            s.set_velocity_params(5.0, 0.0)


# -- faults ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bits, text", [(0x1, "forward limit"), (0x2, "reverse limit"), (0x4000, "motion error")])
def test_limit_switch_and_motion_error_bits_are_faults(bits, text):
    with scripted_port([(REQ_STATUS, status_reply(IDLE | bits))]) as port:
        with pytest.raises(DeviceFault, match=text):
            stage(port).is_moving()


def test_limit_bit_while_leaving_the_switch_is_not_a_fault():
    with scripted_port([(REQ_STATUS, status_reply(IDLE | MOVING | 0x1))]) as port:
        assert stage(port).is_moving() is True


def test_move_that_stops_on_a_limit_switch_raises():
    script = [(MOVE_90, b""), (REQ_STATUS, status_reply(IDLE | MOVING)), (REQ_STATUS, status_reply(IDLE | 0x1))]
    with scripted_port(script) as port:
        with pytest.raises(DeviceFault, match="forward limit"):
            stage(port).move_to(90.0, timeout_s=1.0)


def test_hw_richresponse_instead_of_the_reply_is_a_device_fault():
    rich = h("81 00 44 00 81 50") + struct.pack("<HH64s", 0x0429, 7, b"channel not responding")
    with scripted_port([(REQ_STATUS, rich)]) as port:
        with pytest.raises(DeviceFault, match="error 7 on message 0x0429: channel not responding"):
            stage(port).is_moving()


def test_hw_response_before_the_reply_is_raised_after_the_reply_is_read():
    with scripted_port([(REQ_POS, HW_RESPONSE + POS_90)]) as port:
        with pytest.raises(DeviceFault, match="HW_RESPONSE"):
            stage(port).position_deg()


def test_no_reply_is_a_timeout():
    with scripted_port([(REQ_POS, b"")]) as port:
        with pytest.raises(DeviceTimeout) as info:
            stage(port, retries=0).position_deg()
    assert info.value.received == b""


def test_unknown_message_id_is_a_protocol_error_with_the_bytes_then_a_clean_retry():
    junk = h("99 99 00 00 01 50")
    with scripted_port([(REQ_POS, junk), (REQ_POS, POS_90)]) as port:
        assert stage(port).position_deg() == 90.0
    with scripted_port([(REQ_POS, junk), (REQ_POS, junk)]) as port:
        with pytest.raises(ProtocolError, match="unknown message id 0x9999") as info:
            stage(port, retries=1).position_deg()
        assert info.value.received == junk
        port.discard_input()


def test_truncated_reply_is_a_protocol_error_or_a_clean_retry_never_a_wrong_value():
    with scripted_port([(REQ_POS, POS_90[:8]), (REQ_POS, POS_90)]) as port:
        assert stage(port).position_deg() == 90.0
    with scripted_port([(REQ_POS, POS_90[:8])]) as port:
        with pytest.raises(ProtocolError, match="truncated") as info:
            stage(port, retries=0).position_deg()
        assert info.value.received == POS_90[:8]


def test_frames_not_for_the_host_or_of_the_wrong_length_are_rejected():
    not_for_host = bytes([0x12, 0x04, 0x06, 0x00, 0xDB, 0x50]) + POS_90[6:]  # dest 0x5B
    wrong_length = h("12 04 0E 00 81 50") + bytes(14)
    for bad in (not_for_host, wrong_length):
        with scripted_port([(REQ_POS, bad)]) as port:
            with pytest.raises(ProtocolError):
                stage(port, retries=0).position_deg()
            port.discard_input()


def test_stale_bytes_from_a_broken_reply_are_dropped_before_the_next_exchange():
    with scripted_port([(REQ_POS, h("99 99 00 00 01 50 12 04")), (REQ_STATUS, status_reply(IDLE))]) as port:
        s = stage(port, retries=0)
        with pytest.raises(ProtocolError):
            s.position_deg()
        assert s.is_moving() is False


# -- framing: never decode across a message boundary (issue 10 item 5) ----------------------------------------------
def status_update(counts: int, bits: int) -> bytes:
    """MOT_GET_STATUSUPDATE: header ``81 04 0E 00 81 50`` + ``<H l l L>`` channel, position, encoder, status."""
    return h("81 04 0E 00 81 50") + struct.pack("<HllL", 1, counts, counts, bits)


def test_truncated_status_reply_followed_by_move_completed_is_not_a_limit_switch():
    # the reply lost its data packet; the completion volunteered next must not be read as the status word
    # (its header "64 04 0E 00 81 50" decodes as channel 0x0464, status 0x5081000E: a reverse limit switch)
    script = [
        (MOVE_90, b""),
        (REQ_STATUS, status_reply(IDLE | MOVING)[:6] + completed_long(12_288_000, IDLE)),
        (REQ_STATUS, status_reply(IDLE)),  # asked again: the first reply was broken
        (REQ_POS, POS_90),
    ]
    with scripted_port(script) as port:
        s = stage(port)
        s.move_to(90.0, timeout_s=1.0)
    assert s.events == ["MOT_MOVE_COMPLETED"]
    assert s.retry_count == 1
    assert not s.last_status.faults()


def test_truncated_status_update_then_a_good_one_during_a_move():
    cut = status_update(4_000_000, IDLE | MOVING)[:13]  # header and 7 of its 14 data bytes
    script = [
        (MOVE_90, b""),
        (REQ_STATUS, cut + status_update(6_144_000, IDLE | MOVING) + status_reply(IDLE | MOVING)),
        (REQ_STATUS, status_reply(IDLE)),
        (REQ_POS, cut + status_update(12_288_000, IDLE) + POS_90),
    ]
    with scripted_port(script) as port:
        s = stage(port, retries=0)  # resynchronised within the exchange: nothing is asked twice
        s.move_to(90.0, timeout_s=1.0)
        assert s.last_status.position_counts == 12_288_000
        assert not s.last_status.moving and not s.last_status.faults()
    assert s.retry_count == 0


def test_garbage_before_a_valid_header_is_skipped():
    garbage = h("FF 00 13 12 04 06 99 81 50")  # line noise, including the start of a plausible header
    with scripted_port([(REQ_POS, garbage + POS_90), (REQ_STATUS, h("00") + status_reply(IDLE))]) as port:
        s = stage(port, retries=0)
        assert s.position_deg() == 90.0
        assert s.is_moving() is False


def test_reply_for_another_channel_is_not_taken():
    other = bytes([0x12, 0x04, 0x06, 0x00, 0x81, 0x50]) + struct.pack("<Hl", 2, 5)
    with scripted_port([(REQ_POS, other)]) as port:
        with pytest.raises(ProtocolError, match="channel 2"):
            stage(port, retries=0).position_deg()


def test_a_frame_that_really_contains_header_like_bytes_is_kept():
    # position 0x0444 and encoder 1 put "44 04 00 00 01 00" (a MOVE_HOMED header to the host) inside the
    # data packet; what follows the frame is a valid header, so the frame is whole
    update = status_update(0x0444, IDLE)[:12] + struct.pack("<lL", 1, IDLE)
    with scripted_port([(REQ_POS, update + POS_90)]) as port:
        s = stage(port, retries=0)
        assert s.position_deg() == 90.0
    assert s.last_status.position_counts == 0x0444
    assert s.events == []


# -- retries (issue 10 item 10) ---------------------------------------------------------------------------------------
def test_one_garbled_reply_then_a_good_one_is_a_counted_retry():
    garbled = bytes(b ^ 0x5A if i % 2 == 0 else b for i, b in enumerate(POS_90))  # the simulator's garble
    with scripted_port([(REQ_POS, garbled), (REQ_POS, POS_90)]) as port:
        s = stage(port)
        assert s.position_deg() == 90.0
    assert s.retry_count == 1


def test_retries_are_bounded_and_the_last_problem_is_raised_typed():
    junk = h("99 99 00 00 01 50")
    script = [(REQ_POS, junk)] * 3 + [(REQ_POS, POS_90[:8])]
    with scripted_port(script) as port:
        s = stage(port)
        assert s.retries == 3
        with pytest.raises(ProtocolError, match=r"scripted: truncated MOT_GET_POSCOUNTER") as info:
            s.position_deg()
    assert info.value.attempts == 4 and "gave up after 4 attempts" in str(info.value)
    assert s.retry_count == 3
    with scripted_port([(REQ_POS, b"")] * 4) as port:
        with pytest.raises(DeviceTimeout, match="scripted") as info:
            stage(port).position_deg()
    assert info.value.attempts == 4


class _LateSerial(ScriptedSerial):
    """Volunteered bytes reach the driver only when it looks before writing (``in_waiting``), not while it
    waits for a reply: a reply that comes after the driver gave up on it."""

    def read(self, size: int = 1) -> bytes:
        data = bytes(self.output[:size])
        del self.output[:size]
        return data


def test_a_late_reply_then_a_good_one():
    raw = _LateSerial([(REQ_POS, b""), (b"", pos_reply(12_000_000)), (REQ_POS, POS_90)])
    s = stage(Port(raw, name="late", timeout_s=0.05))
    assert s.position_deg() == 90.0  # the late reply is drained before asking again, never taken
    raw.check_done()
    assert s.retry_count == 1


def test_frame_reader_property_whole_streams_exact_cut_or_noisy_streams_never_invent_a_frame():
    # frames full of header-like values (0x0444, 0x0080, 0x0464 …); whole streams fed in random chunks come
    # back exactly; with one frame cut short, or junk between frames, nothing comes out that was not sent
    # (the source byte aside, which the driver never insists on)
    rng = random.Random(10)

    def value():
        return rng.choice([rng.randrange(-2**31, 2**31), rng.randrange(-5000, 5000), 0x0444, 0x0080, 0x0464, 1, 0])

    def frame():
        bits = rng.choice([rng.randrange(2**32), IDLE, IDLE_HOMED | MOVING, CONNECTED | rng.randrange(256)])
        source = rng.choice([0x50, 0x00, 0x21])
        data = {Msg.MOT_GET_STATUSBITS: struct.pack("<HL", 1, bits),
                Msg.MOT_GET_POSCOUNTER: struct.pack("<Hl", 1, value()),
                Msg.MOT_GET_STATUSUPDATE: struct.pack("<HllL", 1, value(), value(), bits),
                Msg.MOT_MOVE_COMPLETED: struct.pack("<HlhHL", 1, value(), 0, 0, bits),
                Msg.MOT_GET_VELPARAMS: struct.pack("<Hlll", 1, 0, value(), value())}
        msg_id = rng.choice([*data, None])
        if msg_id is None:
            return pack_short(Msg.MOT_MOVE_COMPLETED, 1, dest=0x01, source=source)
        return pack_long(msg_id, data[msg_id], dest=0x01, source=source)

    def read(stream, chunked):
        reader, got, i = AptFrameReader(1), [], 0
        while i < len(stream):
            j = min(len(stream), i + (rng.randrange(1, 30) if chunked else len(stream)))
            reader.feed(stream[i:j])
            i = j
            while (m := reader.next()) is not None:
                got.append(m)
        while (m := reader.next(final=True)) is not None:
            got.append(m)
        return [(m.msg_id, m.dest, m.param1, m.param2, m.data) for m in got]

    for _ in range(1500):
        frames = [frame() for _ in range(rng.randrange(1, 5))]
        sent = [(m.msg_id, m.dest, m.param1, m.param2, m.data) for m in map(unpack_message, frames)]
        assert read(b"".join(frames), chunked=True) == sent
        cut = list(frames)
        k = rng.randrange(len(cut))
        cut[k] = cut[k][:rng.randrange(1, len(cut[k]))]
        assert set(read(b"".join(cut), chunked=False)) <= set(sent)
        noisy = list(frames)
        noisy.insert(rng.randrange(len(noisy) + 1), bytes(rng.randrange(256) for _ in range(rng.randrange(1, 12))))
        assert set(read(b"".join(noisy), chunked=True)) <= set(sent)
