"""The horizon sensor module's driver, byte for byte against scripted exchanges (wire format:
drivers.horizon_protocol).

Every frame here is built by hand from the layout documented in drivers/horizon_protocol.py (sync A5 48, code,
sequence, u16 length, payload, CRC-32 of code … payload), not with the module's own encoder."""

import math
import struct
import zlib

import numpy as np
import pytest
from framedtools import garbled

from drivers import horizon_protocol as wire
from drivers.errors import DeviceTimeout, LimitError, ProtocolError
from drivers.horizon_sensor import HorizonIdentity, HorizonSensorError, HorizonSensorModule, MotorStalled
from drivers.interfaces import HorizonSensor
from drivers.testing import scripted_port


def frame(code, seq, payload=b""):
    body = bytes([code, seq]) + struct.pack("<H", len(payload)) + payload
    return b"\xa5\x48" + body + struct.pack("<I", zlib.crc32(body))


def identity_payload(serial=b"HZ-0042", cones=2, bits=16, samples=3600, period_us=1_000_000, gamma=70.0, ifov=2.0,
                     threshold=0.5, max_scans=4):
    # model 16s, serial 16s, firmware 8s, cones u8, bits u8, samples u16, period u32 [µs], γ f32, IFOV f32, C1 f32,
    # largest count u8
    return (b"SB-HORIZON-DCS".ljust(16, b"\0") + serial.ljust(16, b"\0") + b"1.0.0".ljust(8, b"\0")
            + bytes([cones, bits]) + struct.pack("<HI", samples, period_us)
            + struct.pack("<fff", gamma, ifov, threshold) + bytes([max_scans]))


IDENTIFY = (frame(0x01, 1), frame(0x81, 1, identity_payload()))


def scan(revolution, period_us, cones, centi=2512):
    # counter u32, period u32; per cone: t_out u32, t_in u32, flags u8, space u16, earth u16; temperature i16
    out = struct.pack("<II", revolution, period_us)
    for t_out, t_in, flags, space, earth in cones:
        out += struct.pack("<IIBHH", t_out, t_in, flags, space, earth)
    return out + struct.pack("<h", centi)


GOOD = [(184_510, 815_490, 0x03, 2010, 25_600), (184_900, 815_700, 0x03, 2012, 25_590)]


def test_the_frame_layout_and_sizes_are_the_documented_ones():
    assert wire.encode_frame(0x02, 7, b"\x03") == frame(0x02, 7, b"\x03")
    assert wire.decode_frame(frame(0x82, 1, b"ab") + b"x") == (wire.Frame(0x82, 1, b"ab"), 12)
    assert wire.IDENTITY.size == len(identity_payload()) == 61
    assert wire.SCAN.size == len(scan(0, 1, GOOD)) == 36 and wire.STATUS.size == 15
    assert wire.pulse_decimation(3600) == 4 and wire.pulse_decimation(900) == 1 and wire.pulse_decimation(1001) == 2


def test_identify_reports_the_design():
    with scripted_port([IDENTIFY]) as port:
        module = HorizonSensorModule(port)
        ident = module.identify()
    assert isinstance(module, HorizonSensor) and module.reports_serial
    assert ident == HorizonIdentity("SB-HORIZON-DCS", "HZ-0042", "1.0.0", 2, 16, 3600, 1.0, 70.0, 2.0, 0.5, 4)


def test_identify_refuses_a_module_that_is_no_dual_cone_scanner():
    with scripted_port([(frame(0x01, 1), frame(0x81, 1, identity_payload(cones=1)))]) as port:
        with pytest.raises(ProtocolError, match="1 cones"):
            HorizonSensorModule(port, retries=0).identify()


def test_read_scans_converts_microseconds_and_flags():
    saturated = (184_000, 300_000, 0x07, 2000, 65_535)  # both edges, but a sample at full scale
    missing_in = (184_500, 0, 0x01, 2000, 25_000)  # no rising edge: its time is meaningless
    reply = bytes([2]) + scan(17, 1_000_120, GOOD) + scan(18, 999_880, [saturated, missing_in], centi=-105)
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x02"), frame(0x82, 2, reply))]) as port:
        scans = HorizonSensorModule(port).read_scans(2)
    first, second = scans
    assert first.revolution == 17 and first.period_s == 1.00012 and first.temperature_c == 25.12
    assert first.t_out_s == (0.18451, 0.1849) and first.t_in_s == (0.81549, 0.8157)
    assert first.level_space == (2010.0, 2012.0) and first.level_earth == (25600.0, 25590.0)
    assert first.phase_out_deg[0] == pytest.approx(360 * 0.18451 / 1.00012, abs=1e-12)
    assert first.valid == (True, True) and first.saturated == (False, False)
    assert second.saturated == (True, False) and second.temperature_c == -1.05
    assert second.t_in_s[0] == 0.3 and second.t_out_s[1] == 0.1845 and math.isnan(second.t_in_s[1])
    assert math.isnan(second.phase_in_deg[1]) and second.valid == (False, False)


def test_read_scans_beyond_the_modules_largest_count_asks_several_times():
    # the module returns at most 4 revolutions a request (IDENTIFY); 6 are two requests of 4 and 2
    four = bytes([4]) + b"".join(scan(i, 1_000_000, GOOD) for i in range(4))
    two = bytes([2]) + b"".join(scan(i, 1_000_000, GOOD) for i in (4, 5))
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x04"), frame(0x82, 2, four)),
                        (frame(0x02, 3, b"\x02"), frame(0x82, 3, two))]) as port:
        assert [s.revolution for s in HorizonSensorModule(port).read_scans(6)] == [0, 1, 2, 3, 4, 5]


def test_read_scans_refuses_bad_counts_before_sending():
    with scripted_port([]) as port:
        module = HorizonSensorModule(port)
        for n in (0, -1, 1.5):
            with pytest.raises(LimitError, match="positive integer"):
                module.read_scans(n)


@pytest.mark.parametrize("bad, match", [
    ((900_000, 815_490, 0x03, 2010, 25_600), "t_out 900000 us"),  # a time beyond the period
    ((184_510, 815_490, 0x13, 2010, 25_600), "flags 0x13"),  # an undocumented flag
])
def test_read_scans_refuses_what_no_revolution_can_be(bad, match):
    reply = bytes([1]) + scan(1, 800_000, [bad, GOOD[1]])
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01"), frame(0x82, 2, reply))]) as port:
        with pytest.raises(ProtocolError, match=match):
            HorizonSensorModule(port, retries=0).read_scans(1)


def test_a_garbled_reply_is_asked_again_and_counted():
    reply = frame(0x82, 2, bytes([1]) + scan(3, 1_000_000, GOOD))
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01"), garbled(reply)),
                        (frame(0x02, 3, b"\x01"), frame(0x82, 3, bytes([1]) + scan(4, 1_000_000, GOOD)))]) as port:
        module = HorizonSensorModule(port)
        assert module.read_scans(1)[0].revolution == 4
    assert module.retry_count == 1


def test_silence_is_a_timeout_after_the_retries():
    with scripted_port([(frame(0x01, 1), b""), (frame(0x01, 2), b"")], timeout_s=0.01) as port:
        with pytest.raises(DeviceTimeout, match="no reply") as info:
            HorizonSensorModule(port, retries=1).identify()
    assert info.value.attempts == 2


def test_a_stalled_motor_is_its_own_error():
    error = frame(0xFF, 2, bytes([6]) + b"no index mark: the motor does not turn")
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01"), error)]) as port:
        with pytest.raises(MotorStalled, match=r"module error 6 \(no index mark\)") as info:
            HorizonSensorModule(port).read_scans(1)
    assert isinstance(info.value, HorizonSensorError) and info.value.code == 6


def test_a_busy_module_is_a_module_error_not_retried():
    with scripted_port([IDENTIFY, (frame(0x02, 2, b"\x01"), frame(0xFF, 2, bytes([5]) + b"busy"))]) as port:
        with pytest.raises(HorizonSensorError, match=r"module error 5 \(not ready\)") as info:
            HorizonSensorModule(port).read_scans(1)
    assert type(info.value) is HorizonSensorError and info.value.code == 5


def test_pulse_returns_both_cones_samples_and_thresholds():
    n = 5
    samples = np.arange(2 * n, dtype="<u2") * 1000
    payload = struct.pack("<IHHHH", 999_990, 4, n, 13_800, 13_790) + samples.tobytes()
    with scripted_port([(frame(0x03, 1), frame(0x83, 1, payload))]) as port:
        pulse = HorizonSensorModule(port).pulse()
    assert pulse.period_s == 0.99999 and pulse.samples.shape == (2, 5)
    assert pulse.samples[1].tolist() == [5000, 6000, 7000, 8000, 9000] and pulse.threshold.tolist() == [13800, 13790]
    assert pulse.phase_deg.tolist() == [0, 72, 144, 216, 288]


def test_pulse_refuses_a_sample_count_its_payload_does_not_hold():
    payload = struct.pack("<IHHHH", 1_000_000, 4, 6, 1, 1) + bytes(20)
    with scripted_port([(frame(0x03, 1), frame(0x83, 1, payload))]) as port:
        with pytest.raises(ProtocolError, match="6 samples per cone"):
            HorizonSensorModule(port, retries=0).pulse()


def test_set_threshold_sends_the_fraction_and_checks_the_echo():
    sent = struct.pack("<f", 0.6)
    with scripted_port([(frame(0x04, 1, sent), frame(0x84, 1, sent))]) as port:
        module = HorizonSensorModule(port)
        assert module.set_threshold(0.6) == pytest.approx(0.6, abs=1e-7)
        for bad in (0.05, 0.95, math.nan):
            with pytest.raises(LimitError, match="outside"):
                module.set_threshold(bad)  # nothing sent: the script has no exchange for it


def test_status_and_temperature():
    payload = struct.pack("<fhBII", 0.5, 2498, 1, 1234, 1_000_050)
    with scripted_port([(frame(0x05, 1), frame(0x85, 1, payload)), (frame(0x05, 2), frame(0x85, 2, payload))]) as port:
        module = HorizonSensorModule(port)
        status = module.status()
        assert module.temperature_c() == 24.98
    assert (status.threshold, status.motor_turning, status.revolution, status.period_s) == (0.5, True, 1234, 1.00005)
