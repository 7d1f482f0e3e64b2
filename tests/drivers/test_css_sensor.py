"""The CSS head driver, byte for byte against scripted exchanges (wire format: drivers.css_protocol).

Every frame here is built by hand from the layout documented in drivers/css_protocol.py (sync A5 43, code,
sequence, u16 length, payload, CRC-32 of code … payload), not with the module's own encoder; the channel list is
spelled out here too."""

import math
import struct
import zlib

import pytest
from framedtools import garbled

from drivers import css_protocol as wire
from drivers.css_sensor import CssHead, CssHeadError, CssIdentity
from drivers.errors import ChecksumError, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import CoarseSunHead
from drivers.testing import scripted_port

NAMES = ["px_uv", "px_vis", "px_ir", "py_uv", "py_vis", "py_ir", "mx_uv", "mx_vis", "mx_ir",
         "my_uv", "my_vis", "my_ir", "pz_uv", "pz_vis", "pz_ir", "mz_uv", "mz_vis", "mz_ir"]
# per channel type: pedestal [counts], units per count [A or V per count] (sent as f32: compared through f32())
PEDESTAL = {"uv": 64, "vis": 64, "ir": 32768}
UNITS = {"uv": 12e-6 / 65471, "vis": 2e-3 / 65471, "ir": 5e-3 / 32768}


def kind(name):
    return name.split("_")[1]


def frame(code, seq, payload=b""):
    body = bytes([code, seq]) + struct.pack("<H", len(payload)) + payload
    return b"\xa5\x43" + body + struct.pack("<I", zlib.crc32(body))


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def identity_payload(serial=b"CSS-0042", bits=16, count=18, max_average=1024, sample_us=1000, names=NAMES,
                     units=None):
    # model 16s, serial 16s, firmware 8s, bits u8, channel count u8, max average u16, sample time u32 [µs];
    # per channel: name 8s, pedestal u32, units per count f32
    out = (b"SB-CSS-HEAD".ljust(16, b"\0") + serial.ljust(16, b"\0") + b"1.0.0".ljust(8, b"\0")
           + bytes([bits, count]) + struct.pack("<H", max_average) + struct.pack("<I", sample_us))
    for name in names:
        u = UNITS[kind(name)] if units is None else units
        out += name.encode().ljust(8, b"\0") + struct.pack("<I", PEDESTAL[kind(name)]) + struct.pack("<f", u)
    return out


IDENTIFY = (frame(0x01, 1), frame(0x81, 1, identity_payload()))


def read_reply(seq, n, sums, flags=0, saturated=0, under=0, centi=2512, counter=7):
    # samples u16, flags u8, saturated mask u32, under-range mask u32, sums u32 × 18, temperature i16, counter u32
    return frame(0x82, seq, struct.pack("<H", n) + bytes([flags]) + struct.pack("<II", saturated, under)
                 + struct.pack("<18I", *sums) + struct.pack("<h", centi) + struct.pack("<I", counter))


def status(mode, setpoint, temperature, settled):
    return struct.pack("<B", mode) + struct.pack("<h", setpoint) + struct.pack("<h", temperature) + bytes([settled])


# -- framing ------------------------------------------------------------------------------------------------
def test_encode_frame_matches_the_documented_layout():
    assert wire.encode_frame(0x01, 7) == frame(0x01, 7)
    raw = wire.encode_frame(0x02, 1, b"\x10\x00")
    assert raw[:6] == bytes.fromhex("a54302010200") and raw[6:8] == b"\x10\x00" and len(raw) == 12
    assert raw[8:] == struct.pack("<I", zlib.crc32(bytes.fromhex("020102001000")))
    assert wire.decode_frame(raw + b"junk") == (wire.Frame(0x02, 1, b"\x10\x00"), 12)
    assert wire.decode_frame(raw[:7]) == (None, 0)
    # the documented sizes: IDENTIFY 48 + 18 × 16 = 336, READ 2 + 1 + 4 + 4 + 72 + 2 + 4 = 89; both fit the maximum
    assert wire.IDENTITY.size == len(identity_payload()) == 336
    assert wire.READ_REPLY.size == len(read_reply(1, 1, [0] * 18)) - 10 == 89
    assert wire.TEC_STATUS.size == 6 and wire.MAX_PAYLOAD == 512 >= 336
    assert list(wire.CHANNELS) == NAMES


# -- commands -----------------------------------------------------------------------------------------------
def test_identify():
    with scripted_port([IDENTIFY]) as port:
        head = CssHead(port)
        ident = head.identify()
    assert isinstance(ident, CssIdentity) and isinstance(head, CoarseSunHead) and head.reports_serial
    assert (ident.model, ident.serial, ident.firmware) == ("SB-CSS-HEAD", "CSS-0042", "1.0.0")
    assert (ident.adc_bits, ident.max_average, ident.sample_ms, ident.full_scale_counts) == (16, 1024, 1.0, 65535)
    assert list(ident.channels) == NAMES
    assert ident.pedestal_counts == tuple(PEDESTAL[kind(n)] for n in NAMES)
    assert ident.units_per_count == tuple(f32(UNITS[kind(n)]) for n in NAMES)
    assert ident.units[:3] == ("A", "A", "V") and ident.units.count("V") == 6
    low, high = ident.range[2]  # a thermopile: bipolar, ±5 mV
    assert low == pytest.approx(-5e-3, rel=1e-6) and high == pytest.approx(5e-3 * 32767 / 32768, rel=1e-6)
    assert ident.range[1] == (pytest.approx(-64 * f32(UNITS["vis"])), pytest.approx(2e-3, rel=1e-6))


def test_read_identifies_first_then_averages_and_converts_in_channel_order():
    # N = 16 (0x0010): sums of 16 samples; signal = (sum / 16 − pedestal) × units per count
    means = [64 + 1000 * i if kind(n) != "ir" else 32768 - 500 + 100 * i for i, n in enumerate(NAMES)]
    sums = [16 * m for m in means]
    sums[0] += 8  # px_uv: a mean of 64.5 counts
    exchange = (frame(0x02, 2, b"\x10\x00"), read_reply(2, 16, sums, flags=0x03, centi=-1234, counter=160))
    with scripted_port([IDENTIFY, exchange]) as port:
        reading = CssHead(port).read(average=16)
    assert list(reading.channels) == NAMES and reading.counts[0] == 64.5
    expected = [(s / 16 - PEDESTAL[kind(n)]) * f32(UNITS[kind(n)]) for s, n in zip(sums, NAMES)]
    assert reading.signals == pytest.approx(expected, rel=1e-12)
    assert reading.signal("px_uv") == pytest.approx(0.5 * f32(UNITS["uv"]), rel=1e-12)
    assert reading.signal("pz_vis") == pytest.approx(13000 * f32(UNITS["vis"]), rel=1e-12)  # A
    assert reading.signal("px_ir") == pytest.approx(-300 * f32(UNITS["ir"]), rel=1e-12)  # V, below mid-scale
    assert reading.units == tuple("V" if n.endswith("ir") else "A" for n in NAMES)
    assert list(reading.as_dict()) == NAMES
    assert reading.temperature_c == pytest.approx(-12.34)
    assert (reading.n_samples, reading.sample_counter, reading.plate_on, reading.plate_settled) == (16, 160, True, True)
    assert reading.saturated == (False,) * 18 and reading.under_range == (False,) * 18 and not reading.any_saturated
    with pytest.raises(KeyError, match="no channel 'qx_uv'"):
        reading.signal("qx_uv")


def test_the_default_read_is_the_thesis_sixteen_samples_and_one_sample_is_asked_as_n_1():
    sums16, sums1 = [16 * 100] * 18, [100] * 18
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x10\x00"), read_reply(2, 16, sums16)),
                        (frame(0x02, 3, b"\x01\x00"), read_reply(3, 1, sums1))]) as port:
        head = CssHead(port)
        assert head.read().n_samples == 16
        assert head.read(1).counts == (100.0,) * 18


def test_read_flags_saturated_and_under_range_channels():
    # saturated mask: bit 13 (pz_vis) — a sample at full scale; pz_uv's (bit 12) mean is at full scale unflagged;
    # under-range mask: bit 2 (px_ir) and bit 17 (mz_ir) — a sample at 0 counts
    sums = [4 * 1000] * 18
    sums[12], sums[13] = 4 * 65535, 4 * 60000
    reply = read_reply(2, 4, sums, saturated=1 << 13, under=(1 << 2) | (1 << 17))
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x04\x00"), reply)]) as port:
        reading = CssHead(port).read(4)
    assert [n for n, s in zip(NAMES, reading.saturated) if s] == ["pz_uv", "pz_vis"] and reading.any_saturated
    assert [n for n, u in zip(NAMES, reading.under_range) if u] == ["px_ir", "mz_ir"]


def test_read_reply_for_another_count_or_impossible_values_is_a_protocol_error():
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x04\x00"), read_reply(2, 1, [1] * 18))]) as port:
        with pytest.raises(ProtocolError, match="1 samples, 4 were asked"):
            CssHead(port, retries=0).read(4)
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01\x00"), read_reply(2, 1, [1] * 17 + [70000]))]) as port:
        with pytest.raises(ProtocolError, match="exceed"):
            CssHead(port, retries=0).read(1)
    beyond = read_reply(2, 1, [1] * 18, saturated=1 << 18)  # a 19th channel
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01\x00"), beyond)]) as port:
        with pytest.raises(ProtocolError, match="beyond 18"):
            CssHead(port, retries=0).read(1)


def test_averaging_count_out_of_range_is_refused_before_sending():
    with scripted_port([IDENTIFY]) as port:
        head = CssHead(port)
        for n in (0, 1025):
            with pytest.raises(LimitError, match="averaging count"):
                head.read(n)


def test_set_and_get_temperature():
    # SET: mode 1, setpoint 25.00 °C = 2500 = 0x09C4; status: mode, setpoint, head temperature, settled
    with scripted_port([
        (frame(0x03, 1, b"\x01\xc4\x09"), frame(0x83, 1, status(1, 2500, 2203, 0))),
        (frame(0x04, 2), frame(0x84, 2, status(1, 2500, 2498, 1))),
        (frame(0x03, 3, b"\x01\x0c\xfe"), frame(0x83, 3, status(1, -500, 2498, 0))),  # −5.00 °C = 0xFE0C
        (frame(0x03, 4, b"\x00\x00\x00"), frame(0x83, 4, status(0, 0, 2400, 0))),  # plate off
    ]) as port:
        head = CssHead(port)
        s = head.set_temperature_setpoint_c(25.0)
        assert (s.enabled, s.setpoint_c, s.temperature_c, s.settled) == (True, 25.0, 22.03, False)
        assert head.temperature_status().settled
        assert head.set_temperature_setpoint_c(-5.0).setpoint_c == -5.0
        off = head.set_temperature_setpoint_c(None)
        assert (off.enabled, off.setpoint_c, off.temperature_c) == (False, None, 24.0)


def test_temperature_getters_of_the_interface():
    reply = status(1, 4000, 3917, 0)
    with scripted_port([(frame(0x04, 1), frame(0x84, 1, reply)), (frame(0x04, 2), frame(0x84, 2, reply))]) as port:
        head = CssHead(port)
        assert head.temperature_setpoint_c() == 40.0
        assert head.temperature_c() == pytest.approx(39.17)


def test_wait_until_settled_polls():
    pauses = []
    with scripted_port([(frame(0x04, 1), frame(0x84, 1, status(1, 4000, 3950, 0))),
                        (frame(0x04, 2), frame(0x84, 2, status(1, 4000, 3999, 1)))]) as port:
        s = CssHead(port).wait_until_settled(poll_s=0.25, pause=pauses.append)
    assert s.settled and pauses == [0.25]


@pytest.mark.parametrize("setpoint", [65.0, -25.0, math.nan])
def test_setpoint_out_of_range_is_refused_before_any_byte_is_sent(setpoint):
    with scripted_port([]) as port:  # an empty script: any byte written fails the test
        with pytest.raises(LimitError, match="setpoint"):
            CssHead(port, setpoint_range_c=(-20.0, 60.0)).set_temperature_setpoint_c(setpoint)
        with pytest.raises(ValueError, match="low < high"):
            CssHead(port, setpoint_range_c=(30.0, 30.0))


# -- errors -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("code, text", [(1, "unknown command"), (2, "bad length"), (4, "value out of range"),
                                        (5, "not ready")])
def test_module_error_frames_are_typed_errors(code, text):
    with scripted_port([(frame(0x04, 1), frame(0xFF, 1, bytes([code]) + b"details"))]) as port:
        with pytest.raises(CssHeadError, match=text) as info:
            CssHead(port).temperature_status()  # not retried: the module said why
    assert info.value.code == code and "details" in str(info.value)


@pytest.mark.parametrize("reply, message", [
    (frame(0x84, 1, status(1, 0, 0, 0))[:-1] + b"\x00", "CRC"),  # corrupted CRC
    (frame(0x84, 9, status(1, 0, 0, 0)), "sequence"),  # answer to another request
    (frame(0x81, 1, status(1, 0, 0, 0)), "reply code"),  # wrong reply type
    (frame(0x84, 1, b"\x01\x02"), "payload bytes"),  # wrong payload length
    (frame(0x84, 1, status(7, 0, 0, 0)), "plate mode 7"),  # a field out of its range
    (b"\xa5\x51" + frame(0x84, 1, status(1, 0, 0, 0))[2:], "sync"),  # the QD module's sync
])
def test_bad_replies_are_protocol_errors_with_the_bytes(reply, message):
    with scripted_port([(frame(0x04, 1), reply)]) as port:
        with pytest.raises(ProtocolError, match=message) as info:
            CssHead(port, retries=0).temperature_status()
    assert info.value.received


def test_silence_and_a_cut_reply_are_typed_timeouts():
    with scripted_port([(frame(0x04, 1), b"")]) as port:
        with pytest.raises(DeviceTimeout, match="no reply"):
            CssHead(port, retries=0).temperature_status()
    cut = frame(0x84, 1, status(1, 0, 0, 0))[:9]
    with scripted_port([(frame(0x04, 1), cut)]) as port:
        with pytest.raises(DeviceTimeout, match="cut short after 9 of 16 bytes") as info:
            CssHead(port, retries=0).temperature_status()
    assert info.value.received == cut
    sums = [16 * 100] * 18
    cut = read_reply(2, 16, sums)[:50]  # a READ reply stops inside its sums
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x10\x00"), cut)]) as port:
        with pytest.raises(DeviceTimeout, match="cut short after 50 of 99 bytes"):
            CssHead(port, retries=0).read()


def status_reply(seq):
    return frame(0x84, seq, status(1, 2000, 2001, 1))


def test_a_reply_with_a_bad_crc_is_a_counted_retry():
    with scripted_port([(frame(0x04, 1), garbled(status_reply(1))), (frame(0x04, 2), status_reply(2))]) as port:
        head = CssHead(port)
        assert head.temperature_status().temperature_c == pytest.approx(20.01)
    assert head.retry_count == 1
    sums = [16 * 100] * 18
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x10\x00"), garbled(read_reply(2, 16, sums))),
                        (frame(0x02, 3, b"\x10\x00"), read_reply(3, 16, sums))]) as port:
        head = CssHead(port)
        assert head.read().counts == (100.0,) * 18  # asked again: fresh samples, a new sequence number
    assert head.retry_count == 1


def test_retries_are_bounded_and_the_last_problem_is_raised_typed():
    script = [(frame(0x04, n), b"") for n in (1, 2, 3)] + [(frame(0x04, 4), garbled(status_reply(4)))]
    with scripted_port(script) as port:
        head = CssHead(port)
        with pytest.raises(ChecksumError, match="scripted: CRC mismatch") as info:
            head.temperature_status()
    assert info.value.attempts == 4 and head.retry_count == 3
    script = [(frame(0x04, n), garbled(status_reply(n))) for n in (1, 2, 3)] + [(frame(0x04, 4), b"")]
    with scripted_port(script) as port:
        with pytest.raises(DeviceTimeout) as info:
            CssHead(port).temperature_status()
    assert info.value.attempts == 4


def test_a_late_read_reply_is_skipped_and_the_read_asked_again():
    old = read_reply(2, 1, [100] * 18, counter=1)
    new = read_reply(3, 1, [1064] * 18, counter=2)
    script = [IDENTIFY, (frame(0x02, 2, b"\x01\x00"), b""), (frame(0x02, 3, b"\x01\x00"), old + new)]
    with scripted_port(script) as port:
        head = CssHead(port)
        reading = head.read(1)
    assert reading.counts == (1064.0,) * 18 and reading.sample_counter == 2
    assert head.retry_count == 1


def test_garbage_before_the_sync_is_skipped():
    with scripted_port([(frame(0x04, 1), b"\x00\xff\xa5\x13" + status_reply(1))]) as port:
        assert CssHead(port, retries=0).temperature_status().settled


def test_the_module_receiving_a_bad_crc_is_a_checksum_error_and_retried():
    bad_crc = frame(0xFF, 1, b"\x03CRC mismatch")
    with scripted_port([(frame(0x04, 1), bad_crc), (frame(0x04, 2), status_reply(2))]) as port:
        head = CssHead(port)
        assert head.temperature_status().setpoint_c == 20.0
    assert head.retry_count == 1
    with scripted_port([(frame(0x04, 1), bad_crc)]) as port:
        with pytest.raises(ChecksumError, match="module error 3"):
            CssHead(port, retries=0).temperature_status()


@pytest.mark.parametrize("payload, message", [
    (identity_payload(bits=0), "not a CSS head's"),
    (identity_payload(count=17), "not a CSS head's"),
    (identity_payload(units=0.0), "not a CSS head's"),
    (identity_payload(names=NAMES[3:6] + NAMES[:3] + NAMES[6:]), "reports the channels py_uv"),  # faces swapped
])
def test_an_identify_reply_that_is_no_heads_is_a_protocol_error(payload, message):
    with scripted_port([(frame(0x01, 1), frame(0x81, 1, payload))]) as port:
        with pytest.raises(ProtocolError, match=message):
            CssHead(port, retries=0).identify()
