"""The QD module driver, byte for byte against scripted exchanges (wire format: drivers.qd_protocol).

Every frame here is built by hand from the layout documented in drivers/qd_protocol.py (sync A5 51, code,
sequence, u16 length, payload, CRC-32 of code … payload), not with the module's own encoder."""

import struct
import zlib

import pytest
from framedtools import garbled

from drivers import qd_protocol as wire
from drivers.errors import ChecksumError, DeviceTimeout, LimitError, ProtocolError
from drivers.qd_sensor import QdIdentity, QdSensorError, QdSunSensor
from drivers.testing import scripted_port

A_PER_COUNT = (30.5e-12, 30.4e-12, 30.6e-12, 30.55e-12)  # sent as f32: compared through f32() below


def frame(code, seq, payload=b""):
    body = bytes([code, seq]) + struct.pack("<H", len(payload)) + payload
    return b"\xa5\x51" + body + struct.pack("<I", zlib.crc32(body))


def identity_payload(serial=b"QD-0042", bits=16, pedestal=64, a=A_PER_COUNT, max_average=1000):
    # model 16s, serial 16s, firmware 8s, bits u8, pedestal u16, A/count f32 ×4, side f32, gap f32, t_int u32, max u16
    return (b"SB-QD-SUN".ljust(16, b"\0") + serial.ljust(16, b"\0") + b"1.0.0".ljust(8, b"\0")
            + bytes([bits]) + struct.pack("<H", pedestal) + struct.pack("<4f", *a) + struct.pack("<ff", 1000.0, 5.0)
            + struct.pack("<I", 1000) + struct.pack("<H", max_average))


IDENTIFY = (frame(0x01, 1), frame(0x81, 1, identity_payload()))


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def read_reply(seq, n, sums, flags=0, centi=2512, counter=7):
    return frame(0x82, seq, struct.pack("<HB4IhI", n, flags, *sums, centi, counter))


# -- framing ------------------------------------------------------------------------------------------------
def test_encode_frame_matches_the_documented_layout():
    assert wire.encode_frame(0x01, 7) == frame(0x01, 7)
    raw = wire.encode_frame(0x02, 1, b"\x10\x00")
    assert raw[:6] == bytes.fromhex("a55102010200") and raw[6:8] == b"\x10\x00" and len(raw) == 12
    assert raw[8:] == struct.pack("<I", zlib.crc32(bytes.fromhex("020102001000")))
    assert wire.decode_frame(raw + b"junk") == (wire.Frame(0x02, 1, b"\x10\x00"), 12)
    assert wire.decode_frame(raw[:7]) == (None, 0)
    assert wire.IDENTITY.size == 73 and wire.READ_REPLY.size == 25 and wire.TEC_STATUS.size == 6


# -- commands -----------------------------------------------------------------------------------------------
def test_identify():
    with scripted_port([IDENTIFY]) as port:
        ident = QdSunSensor(port).identify()
    assert isinstance(ident, QdIdentity)
    assert (ident.model, ident.serial, ident.firmware) == ("SB-QD-SUN", "QD-0042", "1.0.0")
    assert (ident.adc_bits, ident.pedestal_counts, ident.max_average) == (16, 64, 1000)
    assert ident.amperes_per_count == tuple(f32(a) for a in A_PER_COUNT)
    assert (ident.detector_side_um, ident.gap_um, ident.integration_ms) == (1000.0, 5.0, 1.0)
    assert ident.full_scale_counts == 65535
    assert ident.full_scale_a[0] == pytest.approx((65535 - 64) * 30.5e-12, rel=1e-6)


def test_read_identifies_first_then_averages_and_converts():
    # N = 16 (0x0010): sums of 16 samples; I = (sum / 16 − 64) × A/count
    sums = (16 * 20064, 16 * 10064, 16 * 64 + 8, 16 * 40064)
    exchange = (frame(0x02, 2, b"\x10\x00"), read_reply(2, 16, sums, centi=-1234, counter=160))
    with scripted_port([IDENTIFY, exchange]) as port:
        reading = QdSunSensor(port).read(average=16)
    assert reading.counts == (20064.0, 10064.0, 64.5, 40064.0)
    a = [f32(x) for x in A_PER_COUNT]
    assert reading.currents_a == pytest.approx((20000 * a[0], 10000 * a[1], 0.5 * a[2], 40000 * a[3]), rel=1e-12)
    assert reading.temperature_c == pytest.approx(-12.34)
    assert (reading.n_samples, reading.sample_counter) == (16, 160)
    assert reading.saturated == (False,) * 4 and reading.under_range == (False,) * 4 and not reading.any_saturated
    assert reading.total_a == pytest.approx(sum(reading.currents_a))


def test_read_flags_saturated_and_under_range_channels():
    # flags 0b0100_0010: a sample of Q2 at full scale, a sample of Q3 at 0; Q4's mean is at full scale (65535)
    sums = (4 * 1000, 4 * 60000, 4 * 10, 4 * 65535)
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x04\x00"), read_reply(2, 4, sums, flags=0x42))]) as port:
        reading = QdSunSensor(port).read(4)
    assert reading.saturated == (False, True, False, True) and reading.any_saturated
    assert reading.under_range == (False, False, True, False)


def test_read_reply_for_another_count_or_impossible_sums_is_a_protocol_error():
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x04\x00"), read_reply(2, 1, (1, 2, 3, 4)))]) as port:
        with pytest.raises(ProtocolError, match="1 samples, 4 were asked"):
            QdSunSensor(port, retries=0).read(4)
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01\x00"), read_reply(2, 1, (1, 2, 3, 70000)))]) as port:
        with pytest.raises(ProtocolError, match="exceed"):
            QdSunSensor(port, retries=0).read(1)


def test_averaging_count_out_of_range_is_refused_before_sending():
    with scripted_port([IDENTIFY]) as port:
        sensor = QdSunSensor(port)
        for n in (0, 1001):
            with pytest.raises(LimitError, match="averaging count"):
                sensor.read(n)


def test_set_and_get_temperature():
    # SET: mode 1, setpoint 25.00 °C = 2500 = 0x09C4; status: mode, setpoint, die temperature, settled
    with scripted_port([
        (frame(0x03, 1, b"\x01\xc4\x09"), frame(0x83, 1, struct.pack("<BhhB", 1, 2500, 2203, 0))),
        (frame(0x04, 2), frame(0x84, 2, struct.pack("<BhhB", 1, 2500, 2498, 1))),
        (frame(0x03, 3, b"\x01\x0c\xfe"), frame(0x83, 3, struct.pack("<BhhB", 1, -500, 2498, 0))),  # −5.00 °C
        (frame(0x03, 4, b"\x00\x00\x00"), frame(0x83, 4, struct.pack("<BhhB", 0, 0, 2400, 0))),  # TEC off
    ]) as port:
        sensor = QdSunSensor(port)
        status = sensor.set_temperature_setpoint_c(25.0)
        assert (status.enabled, status.setpoint_c, status.temperature_c, status.settled) == (True, 25.0, 22.03, False)
        assert sensor.temperature_status().settled
        assert sensor.set_temperature_setpoint_c(-5.0).setpoint_c == -5.0
        off = sensor.set_temperature_setpoint_c(None)
        assert (off.enabled, off.setpoint_c, off.temperature_c) == (False, None, 24.0)


def test_temperature_getters_of_the_interface():
    status = frame(0x84, 1, struct.pack("<BhhB", 1, 4000, 3917, 0))
    with scripted_port([(frame(0x04, 1), status), (frame(0x04, 2), frame(0x84, 2, status[6:-4]))]) as port:
        sensor = QdSunSensor(port)
        assert sensor.temperature_setpoint_c() == 40.0
        assert sensor.temperature_c() == pytest.approx(39.17)


def test_wait_until_settled_polls():
    not_yet, done = struct.pack("<BhhB", 1, 4000, 3950, 0), struct.pack("<BhhB", 1, 4000, 3999, 1)
    pauses = []
    with scripted_port([(frame(0x04, 1), frame(0x84, 1, not_yet)), (frame(0x04, 2), frame(0x84, 2, done))]) as port:
        status = QdSunSensor(port).wait_until_settled(poll_s=0.25, pause=pauses.append)
    assert status.settled and pauses == [0.25]


def test_setpoint_out_of_range_is_refused_before_sending():
    with scripted_port([]) as port:
        with pytest.raises(LimitError, match="setpoint"):
            QdSunSensor(port, setpoint_range_c=(-20.0, 60.0)).set_temperature_setpoint_c(65.0)


# -- errors -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("code, text", [(1, "unknown command"), (2, "bad length"), (4, "value out of range"),
                                        (5, "not ready")])
def test_module_error_frames_are_typed_errors(code, text):
    with scripted_port([(frame(0x04, 1), frame(0xFF, 1, bytes([code]) + b"details"))]) as port:
        with pytest.raises(QdSensorError, match=text) as info:
            QdSunSensor(port).temperature_status()  # not retried: the module said why
    assert info.value.code == code and "details" in str(info.value)


@pytest.mark.parametrize("reply, message", [
    (frame(0x84, 1, struct.pack("<BhhB", 1, 0, 0, 0))[:-1] + b"\x00", "CRC"),  # corrupted CRC
    (frame(0x84, 9, struct.pack("<BhhB", 1, 0, 0, 0)), "sequence"),  # answer to another request
    (frame(0x81, 1, struct.pack("<BhhB", 1, 0, 0, 0)), "reply code"),  # wrong reply type
    (frame(0x84, 1, b"\x01\x02"), "payload bytes"),  # wrong payload length
    (frame(0x84, 1, struct.pack("<BhhB", 7, 0, 0, 0)), "TEC mode 7"),  # a field out of its range
    (b"\xa5\x5a" + frame(0x84, 1, struct.pack("<BhhB", 1, 0, 0, 0))[2:], "sync"),  # the CMOS module's sync
])
def test_bad_replies_are_protocol_errors_with_the_bytes(reply, message):
    with scripted_port([(frame(0x04, 1), reply)]) as port:
        with pytest.raises(ProtocolError, match=message) as info:
            QdSunSensor(port, retries=0).temperature_status()
    assert info.value.received


def test_silence_and_a_cut_reply_are_timeouts():
    with scripted_port([(frame(0x04, 1), b"")]) as port:
        with pytest.raises(DeviceTimeout, match="no reply"):
            QdSunSensor(port, retries=0).temperature_status()
    cut = frame(0x84, 1, struct.pack("<BhhB", 1, 0, 0, 0))[:9]
    with scripted_port([(frame(0x04, 1), cut)]) as port:
        with pytest.raises(DeviceTimeout, match="cut short after 9 of 16 bytes") as info:
            QdSunSensor(port, retries=0).temperature_status()
    assert info.value.received == cut


def status_reply(seq):
    return frame(0x84, seq, struct.pack("<BhhB", 1, 2000, 2001, 1))


def test_one_garbled_reply_then_a_good_one_is_a_counted_retry():
    with scripted_port([(frame(0x04, 1), garbled(status_reply(1))), (frame(0x04, 2), status_reply(2))]) as port:
        sensor = QdSunSensor(port)
        assert sensor.temperature_status().temperature_c == pytest.approx(20.01)
    assert sensor.retry_count == 1


def test_retries_are_bounded_and_the_last_problem_is_raised_typed():
    script = [(frame(0x04, n), b"") for n in (1, 2, 3)] + [(frame(0x04, 4), garbled(status_reply(4)))]
    with scripted_port(script) as port:
        sensor = QdSunSensor(port)
        with pytest.raises(ChecksumError, match="scripted: CRC mismatch") as info:
            sensor.temperature_status()
    assert info.value.attempts == 4 and sensor.retry_count == 3
    script = [(frame(0x04, n), garbled(status_reply(n))) for n in (1, 2, 3)] + [(frame(0x04, 4), b"")]
    with scripted_port(script) as port:
        with pytest.raises(DeviceTimeout) as info:
            QdSunSensor(port).temperature_status()
    assert info.value.attempts == 4


def test_a_late_read_reply_is_skipped_and_the_read_asked_again():
    old, new = read_reply(2, 1, (100, 200, 300, 400), counter=1), read_reply(3, 1, (1064, 2064, 3064, 4064), counter=2)
    script = [IDENTIFY, (frame(0x02, 2, b"\x01\x00"), b""), (frame(0x02, 3, b"\x01\x00"), old + new)]
    with scripted_port(script) as port:
        sensor = QdSunSensor(port)
        reading = sensor.read()
    assert reading.counts == (1064.0, 2064.0, 3064.0, 4064.0) and reading.sample_counter == 2
    assert sensor.retry_count == 1


def test_garbage_before_the_sync_is_skipped():
    with scripted_port([(frame(0x04, 1), b"\x00\xff\xa5\x13" + status_reply(1))]) as port:
        assert QdSunSensor(port, retries=0).temperature_status().settled


def test_the_module_receiving_a_bad_crc_is_a_checksum_error_and_retried():
    bad_crc = frame(0xFF, 1, b"\x03CRC mismatch")
    with scripted_port([(frame(0x04, 1), bad_crc), (frame(0x04, 2), status_reply(2))]) as port:
        sensor = QdSunSensor(port)
        assert sensor.temperature_status().setpoint_c == 20.0
    assert sensor.retry_count == 1
    with scripted_port([(frame(0x04, 1), bad_crc)]) as port:
        with pytest.raises(ChecksumError, match="module error 3"):
            QdSunSensor(port, retries=0).temperature_status()


def test_an_identify_reply_that_is_no_modules_is_a_protocol_error():
    with scripted_port([(frame(0x01, 1), frame(0x81, 1, identity_payload(bits=0)))]) as port:
        with pytest.raises(ProtocolError, match="not a module's"):
            QdSunSensor(port, retries=0).identify()
