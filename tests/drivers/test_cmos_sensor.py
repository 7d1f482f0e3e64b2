"""The CMOS module driver, byte for byte against scripted exchanges (wire format: drivers.cmos_protocol)."""

import struct
import zlib

import numpy as np
import pytest
from framedtools import garbled

from drivers import cmos_protocol as wire
from drivers.cmos_sensor import CmosSunSensor, SensorError
from drivers.errors import ChecksumError, DeviceTimeout, LimitError, ProtocolError
from drivers.testing import scripted_port


def frame(code, seq, payload=b""):
    """A frame built by hand from the documented layout (independent of encode_frame)."""
    body = bytes([code, seq]) + struct.pack("<I", len(payload)) + payload
    return b"\xa5\x5a" + body + struct.pack("<I", zlib.crc32(body))


def test_encode_frame_matches_the_documented_layout():
    assert wire.encode_frame(0x01, 7) == frame(0x01, 7)
    raw = wire.encode_frame(0x02, 1, b"\xa0\x0f\x00\x00")
    assert raw[:8] == bytes.fromhex("a55a020104000000") and len(raw) == 16
    assert wire.decode_frame(raw + b"junk") == (wire.Frame(0x02, 1, b"\xa0\x0f\x00\x00"), 16)
    assert wire.decode_frame(raw[:10]) == (None, 0)


def test_identify():
    payload = b"SB-CMOS-PINHOLE\0" + b"NORBI-07".ljust(16, b"\0") + b"1.0.0\0\0\0" + struct.pack("<HHB", 640, 480, 10)
    with scripted_port([(frame(0x01, 1), frame(0x81, 1, payload))]) as port:
        identity = CmosSunSensor(port).identify()
    assert (identity.model, identity.serial, identity.firmware) == ("SB-CMOS-PINHOLE", "NORBI-07", "1.0.0")


def test_set_and_get_exposure():
    with scripted_port([(frame(0x02, 1, struct.pack("<I", 3920)), frame(0x82, 1, struct.pack("<I", 3920))),
                        (frame(0x03, 2), frame(0x83, 2, struct.pack("<I", 3920)))]) as port:
        sensor = CmosSunSensor(port)
        assert sensor.set_exposure_ms(3.92) == pytest.approx(3.92)
        assert sensor.exposure_ms() == pytest.approx(3.92)


def test_exposure_out_of_range_is_refused_before_sending():
    with scripted_port([]) as port:
        with pytest.raises(LimitError):
            CmosSunSensor(port, exposure_range_ms=(0.01, 100)).set_exposure_ms(500.0)


@pytest.mark.parametrize("packing", [wire.RAW16, wire.PACKED10])
def test_capture_both_packings(packing):
    rng = np.random.default_rng(0)
    image = rng.integers(0, 1024, (6, 8)).astype(np.uint16)
    pixels = image.astype("<u2").tobytes() if packing == wire.RAW16 else wire.pack10(image)
    header = struct.pack("<HHBBII", 8, 6, 10, packing, 4000, 17)
    with scripted_port([(frame(0x04, 1, bytes([packing])), frame(0x84, 1, header + pixels))]) as port:
        got, meta = CmosSunSensor(port, packing=packing).capture_with_metadata()
    np.testing.assert_array_equal(got, image)
    assert meta == {"exposure_ms": 4.0, "frame_counter": 17, "bit_depth": 10}


def test_pack10_layout_and_round_trip():
    assert wire.pack10(np.array([1023, 0, 1, 2], dtype=np.uint16)) == bytes([0xFF, 0x00, 0x00, 0x00, 0b10_01_00_11])
    values = np.random.default_rng(1).integers(0, 1024, 4000).astype(np.uint16)
    np.testing.assert_array_equal(wire.unpack10(wire.pack10(values), values.size), values)


def test_onboard_centroid_and_temperature():
    reply = struct.pack("<ffHHBI", 321.25, 240.5, 812, 66, 0, 4000)
    with scripted_port([(frame(0x05, 1), frame(0x85, 1, reply)),
                        (frame(0x06, 2), frame(0x86, 2, struct.pack("<h", -1234)))]) as port:
        sensor = CmosSunSensor(port)
        spot = sensor.onboard_centroid()
        assert (spot.x_px, spot.y_px, spot.peak_dn, spot.n_pixels, spot.status) == (321.25, 240.5, 812, 66, "ok")
        assert sensor.temperature_c() == pytest.approx(-12.34)


def test_module_error_frame_is_a_typed_error():
    with scripted_port([(frame(0x02, 1, struct.pack("<I", 4000)), frame(0xFF, 1, b"\x04exposure too long"))]) as port:
        with pytest.raises(SensorError, match="value out of range") as info:
            CmosSunSensor(port).set_exposure_ms(4.0)
    assert info.value.code == 4


@pytest.mark.parametrize("reply, message", [
    (frame(0x83, 1, struct.pack("<I", 1))[:-1] + b"\x00", "CRC"),  # corrupted CRC
    (frame(0x83, 9, struct.pack("<I", 1)), "sequence"),  # answer to another request
    (frame(0x81, 1, struct.pack("<I", 1)), "reply code"),  # wrong reply type
    (frame(0x83, 1, b"\x01\x02"), "payload bytes"),  # wrong payload length
    (b"\x00\x00" + frame(0x83, 1, struct.pack("<I", 1))[2:], "sync"),
])
def test_bad_replies_are_protocol_errors_with_the_bytes(reply, message):
    with scripted_port([(frame(0x03, 1), reply)]) as port:
        with pytest.raises(ProtocolError, match=message) as info:
            CmosSunSensor(port, retries=0).exposure_ms()
    assert info.value.received


def test_silence_and_a_cut_reply_are_timeouts():
    with scripted_port([(frame(0x03, 1), b"")]) as port:
        with pytest.raises(DeviceTimeout):
            CmosSunSensor(port, retries=0).exposure_ms()
    with scripted_port([(frame(0x03, 1), frame(0x83, 1, struct.pack("<I", 5))[:10])]) as port:
        with pytest.raises(DeviceTimeout, match="cut short") as info:
            CmosSunSensor(port, retries=0).exposure_ms()
    assert info.value.received.startswith(b"\xa5\x5a")


# -- retries (issue 10 item 10) ---------------------------------------------------------------------------------------
def exposure_reply(seq, us=5):
    return frame(0x83, seq, struct.pack("<I", us))


def test_one_garbled_reply_then_a_good_one_is_a_counted_retry():
    # asked again with the next sequence number
    with scripted_port([(frame(0x03, 1), garbled(exposure_reply(1))), (frame(0x03, 2), exposure_reply(2))]) as port:
        sensor = CmosSunSensor(port)
        assert sensor.exposure_ms() == pytest.approx(0.005)
    assert sensor.retry_count == 1


def test_retries_are_bounded_and_the_last_problem_is_raised_typed():
    script = [(frame(0x03, n), b"") for n in (1, 2, 3)] + [(frame(0x03, 4), garbled(exposure_reply(4)))]
    with scripted_port(script) as port:
        sensor = CmosSunSensor(port)
        assert sensor.retries == 3
        with pytest.raises(ChecksumError, match="scripted: CRC mismatch") as info:
            sensor.exposure_ms()
    assert info.value.attempts == 4 and "gave up after 4 attempts" in str(info.value)
    assert sensor.retry_count == 3
    script = [(frame(0x03, n), garbled(exposure_reply(n))) for n in (1, 2, 3)] + [(frame(0x03, 4), b"")]
    with scripted_port(script) as port:
        with pytest.raises(DeviceTimeout, match="scripted") as info:
            CmosSunSensor(port).exposure_ms()
    assert info.value.attempts == 4


def test_a_late_capture_reply_is_skipped_and_the_capture_asked_again():
    # the first frame comes after the driver gave up on it, just ahead of the reply to the repeated request:
    # the sequence number tells them apart (a capture is safe to re-request: the late frame is not used)
    old, new = np.zeros((2, 4), np.uint16), np.full((2, 4), 7, np.uint16)

    def reply(seq, image, counter):
        header = struct.pack("<HHBBII", 4, 2, 10, wire.RAW16, 4000, counter)
        return frame(0x84, seq, header + image.astype("<u2").tobytes())

    raw16 = bytes([wire.RAW16])
    script = [(frame(0x04, 1, raw16), b""), (frame(0x04, 2, raw16), reply(1, old, 1) + reply(2, new, 2))]
    with scripted_port(script) as port:
        sensor = CmosSunSensor(port, packing=wire.RAW16, frame_timeout_s=0.05)
        image, meta = sensor.capture_with_metadata()
    np.testing.assert_array_equal(image, new)
    assert meta["frame_counter"] == 2 and sensor.retry_count == 1


def test_garbage_before_the_sync_is_skipped():
    with scripted_port([(frame(0x03, 1), b"\x00\xff\xa5\x13" + exposure_reply(1))]) as port:
        assert CmosSunSensor(port, retries=0).exposure_ms() == pytest.approx(0.005)


def test_the_module_receiving_a_bad_crc_is_a_checksum_error_and_retried():
    # error 3: our command reached the module garbled; sending it again is the cure
    bad_crc = frame(0xFF, 1, b"\x03CRC mismatch")
    with scripted_port([(frame(0x06, 1), bad_crc), (frame(0x06, 2), frame(0x86, 2, struct.pack("<h", 2512)))]) as port:
        sensor = CmosSunSensor(port)
        assert sensor.temperature_c() == pytest.approx(25.12)
    assert sensor.retry_count == 1
    with scripted_port([(frame(0x06, 1), bad_crc)]) as port:
        with pytest.raises(ChecksumError, match="module error 3"):
            CmosSunSensor(port, retries=0).temperature_c()
