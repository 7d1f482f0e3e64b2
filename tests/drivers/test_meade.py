"""Meade LX200 / Autostar table driver: byte-exact scripted exchanges (PyMeasure style) and the pure
sexagesimal helpers. Reply formats are those of anchors-protocols §1.1–§1.3; ``# from the research note``
marks bytes copied from there."""

import random

import pytest

from drivers.errors import DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import Limits
from drivers.meade import (
    INDI_OK_CHARS,
    OK_CHARS,
    LX200Table,
    MountBusy,
    format_sexagesimal,
    has_seconds,
    parse_sexagesimal,
    refusal_char,
    wrap_azimuth_deg,
)
from drivers.testing import scripted_port

AZ_LIMITS, ZEN_LIMITS = Limits(0.0, 359.0), Limits(-5.0, 85.0)


def table(port, **options):
    """A driver with short waits; precision as given (None = not yet detected)."""
    precision = options.pop("precision", None)
    options = {"nak_wait_s": 0.001, "nak_window_s": 0.005, "poll_s": 0.0, **options}
    t = LX200Table(port, AZ_LIMITS, ZEN_LIMITS, **options)
    t.high_precision = precision
    return t


# -- ACK probe, alignment mode ---------------------------------------------------------------------------
@pytest.mark.parametrize("reply", [b"A", b"L", b"P", b"D"])
def test_ack_probe_returns_the_alignment_char(reply):
    with scripted_port([(b"\x06", reply)]) as port:  # from the research note §1.1
        assert table(port).probe() == reply.decode()


def test_connect_in_alt_az_mode_detects_low_precision_and_switches_to_high():
    script = [
        (b"\x06", b"A"),
        (b":GA#", b"+45\xdf30#"),  # low precision: sDD*MM with 0xDF (research note §1.1, §1.2)
        (b":U#", b""),  # toggle, no reply
        (b":GA#", b"+45\xdf30:00#"),
    ]
    with scripted_port(script) as port:
        t = table(port, high_precision=True)
        assert t.connect() == "A"
        assert t.high_precision is True


def test_connect_sets_alt_az_mode_when_the_mount_is_in_land_or_polar_mode():
    script = [(b"\x06", b"L"), (b":AA#", b""), (b"\x06", b"A"), (b":GA#", b"+10\xdf00'00#")]
    with scripted_port(script) as port:
        t = table(port, high_precision=True)
        assert t.connect() == "A"
        assert t.high_precision is True  # already high: no :U#


def test_connect_keeps_the_precision_when_asked_to():
    with scripted_port([(b"\x06", b"A"), (b":GA#", b"+10\xdf00#")]) as port:
        t = table(port, high_precision=None)
        t.connect()
        assert t.high_precision is False


def test_connect_fails_when_the_mount_stays_in_polar_mode():
    with scripted_port([(b"\x06", b"P"), (b":AA#", b""), (b"\x06", b"P")]) as port:
        with pytest.raises(DeviceFault, match="polar"):
            table(port).connect()


def test_connect_refuses_a_mount_in_its_firmware_downloader():
    with scripted_port([(b"\x06", b"D")]) as port:
        with pytest.raises(DeviceFault, match="downloader"):
            table(port).connect()


def test_set_alt_az_mode():
    with scripted_port([(b":AA#", b"")]) as port:
        table(port).set_alt_az_mode()


def test_unknown_ack_reply_is_a_protocol_error_with_the_bytes():
    with scripted_port([(b"\x06", b"X")]) as port:
        with pytest.raises(ProtocolError) as err:
            table(port, retries=0).probe()
    assert err.value.received == b"X"


# -- precision --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("reply, high", [(b"+45\xdf30#", False), (b"+45\xdf30:15#", True), (b"-05*00'00#", True)])
def test_precision_is_detected_from_the_reply_format(reply, high):
    with scripted_port([(b":GA#", reply)]) as port:
        assert table(port).detect_precision() is high


def test_toggle_precision_sends_u_and_flips_the_known_mode():
    with scripted_port([(b":U#", b"")]) as port:
        t = table(port, precision=True)
        t.toggle_precision()
        assert t.high_precision is False


def test_set_precision_toggles_and_checks():
    script = [(b":GA#", b"+01\xdf02:03#"), (b":U#", b""), (b":GA#", b"+01\xdf02#")]
    with scripted_port(script) as port:
        t = table(port)
        t.set_precision(False)
        assert t.high_precision is False


def test_set_precision_is_a_no_op_when_already_there():
    with scripted_port([]) as port:
        table(port, precision=True).set_precision(True)


def test_set_precision_that_does_not_take_is_a_protocol_error():
    with scripted_port([(b":U#", b""), (b":GA#", b"+01\xdf02#")]) as port:
        with pytest.raises(ProtocolError, match="precision"):
            table(port, precision=False).set_precision(True)


# -- readings -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("reply, expected", [
    (b"+45\xdf30#", 45.5),  # low precision, 0xDF degree sign (research note §1.1)
    (b"-12\xdf06#", -12.1),
    (b"-00\xdf30#", -0.5),  # negative zero
    (b"+51\xdf14:20#", 51 + 14 / 60 + 20 / 3600),  # high precision as a real LX200GPS answers (STEL-818)
    (b"+51\xdf14'20#", 51 + 14 / 60 + 20 / 3600),  # high precision as Rev L writes it
    (b"+51*14'20#", 51 + 14 / 60 + 20 / 3600),  # '*' instead of 0xDF
    (b"-00\xdf00:01#", -1 / 3600),
])
def test_get_altitude(reply, expected):
    with scripted_port([(b":GA#", reply)]) as port:
        assert table(port).altitude_deg() == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("reply, expected", [
    (b"123\xdf45#", 123.75),
    (b"359\xdf59:59#", 359 + 59 / 60 + 59 / 3600),
    (b"007\xdf30'30#", 7.5 + 30 / 3600),
    (b"000*01#", 1 / 60),
])
def test_get_azimuth(reply, expected):
    with scripted_port([(b":GZ#", reply)]) as port:
        assert table(port).mount_azimuth_deg() == pytest.approx(expected, abs=1e-12)


def test_position_reads_azimuth_then_altitude():
    with scripted_port([(b":GZ#", b"090\xdf00:00#"), (b":GA#", b"+30\xdf15:00#")]) as port:
        assert table(port).position() == pytest.approx((90.0, 30.25))


def test_position_maps_the_azimuth_into_a_signed_soft_limit_window():
    with scripted_port([(b":GZ#", b"350\xdf00#"), (b":GA#", b"+00\xdf00#")]) as port:
        t = LX200Table(port, Limits(-180, 180), ZEN_LIMITS)
        assert t.position() == pytest.approx((-10.0, 0.0))


@pytest.mark.parametrize("reply", [
    b"+4X\xdf30#",  # not a digit
    b"+45\xdf75#",  # minutes >= 60
    b"45\xdf30#",  # altitude without its sign
    b"+95\xdf00#",  # beyond the zenith
    b"+45#",  # no minutes
])
def test_malformed_altitude_is_a_protocol_error_with_the_bytes(reply):
    with scripted_port([(b":GA#", reply), (b":GA#", reply)]) as port:  # one clean retry, then the error
        with pytest.raises(ProtocolError) as err:
            table(port).altitude_deg()
    assert err.value.received == reply


def test_malformed_azimuth_is_a_protocol_error_with_the_bytes():
    with scripted_port([(b":GZ#", b"+12\xdf00#")]) as port:
        with pytest.raises(ProtocolError) as err:
            table(port, retries=0).mount_azimuth_deg()
    assert err.value.received == b"+12\xdf00#"


def test_a_garbled_reply_is_retried_once_cleanly():
    garbled = bytes(b ^ 0x5A if i % 2 == 0 else b for i, b in enumerate(b"+45\xdf30#"))
    with scripted_port([(b":GA#", garbled), (b":GA#", b"+45\xdf30#")]) as port:
        assert table(port).altitude_deg() == 45.5


def test_no_reply_is_a_device_timeout_without_retry():
    with scripted_port([(b":GA#", b"")]) as port:
        with pytest.raises(DeviceTimeout) as err:
            table(port).altitude_deg()
    assert err.value.received == b""


def test_a_truncated_reply_is_retried_then_times_out_with_the_partial_bytes():
    with scripted_port([(b":GA#", b"+45\xdf"), (b":GA#", b"+45\xdf")]) as port:
        with pytest.raises(DeviceTimeout) as err:
            table(port).altitude_deg()
    assert err.value.received == b"+45\xdf"


# -- NAK (busy) ---------------------------------------------------------------------------------------------
def test_nak_is_retried_then_the_reply_is_used():
    script = [(b":GA#", b"\x15"), (b":GA#", b"\x15"), (b":GA#", b"+45\xdf30#")]  # research note §1.1
    with scripted_port(script) as port:
        assert table(port, nak_retries=2).altitude_deg() == 45.5


def test_nak_forever_raises_mount_busy_a_device_timeout():
    with scripted_port([(b":GA#", b"\x15")] * 3) as port:
        with pytest.raises(MountBusy) as err:
            table(port, nak_retries=2).altitude_deg()
    assert isinstance(err.value, DeviceTimeout) and err.value.received == b"\x15"


def test_nak_to_a_command_without_reply_is_retried():
    with scripted_port([(b":Q#", b"\x15"), (b":Q#", b"")]) as port:
        table(port).stop()


def test_nak_to_a_set_command_is_retried():
    script = [(b":Sz010*00#", b"\x15"), (b":Sz010*00#", b"1"), (b":Sa+20*00#", b"1")]
    with scripted_port(script) as port:
        table(port, precision=False).set_target(10.0, 20.0)


def test_an_unexpected_reply_to_a_command_without_reply_is_a_protocol_error_and_not_resent():
    with scripted_port([(b":U#", b"?")]) as port:
        t = table(port, precision=True)
        with pytest.raises(ProtocolError) as err:
            t.toggle_precision()
    assert err.value.received == b"?" and t.high_precision is None


# -- targets and slews ---------------------------------------------------------------------------------------
def test_move_low_precision_sends_sz_sa_ma_with_ok_chars():
    script = [(b":Sz123*45#", b"1"), (b":Sa+45*30#", b"1"), (b":MA#", b"0")]  # defaults of OK_CHARS
    with scripted_port(script) as port:
        table(port, precision=False).move_to(123.75, 45.5, wait=False)


def test_move_high_precision_sends_seconds():
    script = [(b":Sz007*30'30#", b"1"), (b":Sa-00*30'01#", b"1"), (b":MA#", b"0")]
    with scripted_port(script) as port:
        table(port, precision=True).move_to(7.5 + 30 / 3600, -(0.5 + 1 / 3600), wait=False)


def test_move_with_0xdf_and_colon_separators_when_configured():
    script = [(b":Sz001\xdf00:00#", b"1"), (b":Sa+02\xdf00:00#", b"1"), (b":MA#", b"0")]
    with scripted_port(script) as port:
        table(port, precision=True, degree_sign="\xdf", seconds_sign=":").move_to(1.0, 2.0, wait=False)


def test_move_detects_the_precision_first_when_unknown():
    script = [(b":GA#", b"+00\xdf00#"), (b":Sz010*00#", b"1"), (b":Sa+20*00#", b"1"), (b":MA#", b"0")]
    with scripted_port(script) as port:
        table(port).move_to(10.0, 20.0, wait=False)


def test_a_negative_bench_azimuth_is_sent_modulo_a_turn():
    script = [(b":Sz350*00#", b"1"), (b":Sa+00*00#", b"1"), (b":MA#", b"0")]
    with scripted_port(script) as port:
        t = LX200Table(port, Limits(-180, 180), ZEN_LIMITS, nak_window_s=0)
        t.high_precision = False
        t.move_to(-10.0, 0.0, wait=False)


def test_refused_altitude_target_is_a_device_fault_and_nothing_more_is_sent():
    with scripted_port([(b":Sz010*00#", b"1"), (b":Sa+20*00#", refusal_char("Sa"))]) as port:
        with pytest.raises(DeviceFault, match="OK_CHARS") as err:
            table(port, precision=False).move_to(10.0, 20.0, wait=False)
    assert err.value.received == b"0"


def test_refused_azimuth_target_is_a_device_fault():
    with scripted_port([(b":Sz010*00#", b"0")]) as port:
        with pytest.raises(DeviceFault):
            table(port, precision=False).move_to(10.0, 20.0, wait=False)


def test_slew_fault_char_is_a_device_fault():
    with scripted_port([(b":MA#", b"1")]) as port:
        with pytest.raises(DeviceFault) as err:
            table(port).slew()
    assert err.value.received == b"1"


def test_an_unknown_set_reply_is_a_protocol_error_with_the_bytes():
    with scripted_port([(b":MA#", b"7"), (b":MA#", b"7")]) as port:
        with pytest.raises(ProtocolError) as err:
            table(port).slew()
    assert err.value.received == b"7"


def test_the_ok_char_table_holds_the_research_note_defaults():
    assert OK_CHARS == {"Sa": b"1", "Sz": b"1", "MA": b"0"}  # research note §1.3 recommendation
    assert (refusal_char("Sa"), refusal_char("Sz"), refusal_char("MA")) == (b"0", b"0", b"1")


def test_the_indi_table_differs_from_the_manual_on_ma_only():
    assert INDI_OK_CHARS == {**OK_CHARS, "MA": b"1"}  # INDI: "0" is failure (lx200driver.cpp)
    assert refusal_char("MA", INDI_OK_CHARS) == b"0"


def test_slew_reply_indi_reads_one_as_slewing_and_zero_as_a_fault():
    with scripted_port([(b":MA#", b"1")]) as port:
        table(port, slew_reply="indi").slew()
    with scripted_port([(b":MA#", b"0")]) as port:
        with pytest.raises(DeviceFault, match="INDI_OK_CHARS") as err:
            table(port, slew_reply="indi").slew()
    assert err.value.received == b"0"


@pytest.mark.parametrize("reply", [b"0", b"1"])
def test_slew_reply_auto_takes_either_char_when_the_bars_show(reply):
    with scripted_port([(b":MA#", reply), (b":D#", b"|#")]) as port:
        table(port, slew_reply="auto").slew()


@pytest.mark.parametrize("reply", [b"0", b"1"])
def test_slew_reply_auto_takes_a_slew_already_ended_at_the_target(reply):
    script = [(b":Sz010*00#", b"1"), (b":Sa+20*00#", b"1"), (b":MA#", reply), (b":D#", b"#"),
              (b":GZ#", b"010\xdf00#"), (b":GA#", b"+20\xdf00#")]
    with scripted_port(script) as port:
        table(port, precision=False, slew_reply="auto").move_to(10.0, 20.0, wait=False)


@pytest.mark.parametrize("reply", [b"0", b"1"])
def test_slew_reply_auto_refuses_a_mount_that_neither_moves_nor_is_there(reply):
    script = [(b":Sz010*00#", b"1"), (b":Sa+20*00#", b"1"), (b":MA#", reply), (b":D#", b"#"),
              (b":GZ#", b"000\xdf00#"), (b":GA#", b"+00\xdf00#")]
    with scripted_port(script) as port:
        with pytest.raises(DeviceFault, match="refused") as err:
            table(port, precision=False, slew_reply="auto").move_to(10.0, 20.0, wait=False)
    assert err.value.received == reply


def test_an_unknown_slew_reply_mode_is_refused():
    with pytest.raises(ValueError, match="slew_reply"):
        LX200Table(object(), AZ_LIMITS, ZEN_LIMITS, slew_reply="ascom")


@pytest.mark.parametrize("azimuth, zenith", [(400.0, 10.0), (-1.0, 10.0), (10.0, 86.0), (10.0, -90.0),
                                             (float("nan"), 0.0), (0.0, float("inf"))])
def test_out_of_limit_move_is_refused_with_nothing_sent(azimuth, zenith):
    with scripted_port([]) as port:  # an empty script fails on any byte written
        with pytest.raises(LimitError):
            table(port, precision=False).move_to(azimuth, zenith)


def test_zenith_limits_beyond_the_mount_altitude_range_are_refused():
    with scripted_port([]) as port:
        with pytest.raises(ValueError, match="zenith_limits"):
            LX200Table(port, AZ_LIMITS, Limits(-10, 95))


# -- motion state, waiting, stop, home ----------------------------------------------------------------------
@pytest.mark.parametrize("reply, moving", [(b"|#", True), (b"\x7f#", True), (b"#", False), (b"    #", False)])
def test_is_moving_from_the_distance_bars(reply, moving):
    with scripted_port([(b":D#", reply)]) as port:  # research note §1.3: a bar while slewing, '#' when done
        assert table(port).is_moving() is moving


def test_move_and_wait_polls_the_bars_then_checks_arrival():
    script = [
        (b":Sz090*00#", b"1"), (b":Sa+30*00#", b"1"), (b":MA#", b"0"),
        (b":D#", b"|#"), (b":D#", b"|#"), (b":D#", b"#"),
        (b":GZ#", b"090\xdf01#"), (b":GA#", b"+29\xdf59#"),  # within the 2' arrival tolerance
    ]
    with scripted_port(script) as port:
        table(port, precision=False).move_to(90.0, 30.0)


def test_a_mount_that_stops_short_of_the_target_is_a_device_fault():
    script = [(b":Sz090*00#", b"1"), (b":Sa+30*00#", b"1"), (b":MA#", b"0"), (b":D#", b"#"),
              (b":GZ#", b"090\xdf00#"), (b":GA#", b"+25\xdf00#")]
    with scripted_port(script) as port:
        with pytest.raises(DeviceFault, match="stopped at"):
            table(port, precision=False).move_to(90.0, 30.0)


def test_a_move_still_in_progress_after_the_timeout_is_stopped_and_raises_device_timeout():
    script = [(b":D#", b"|#")] * 2 + [(b":GZ#", b"010\xdf00#"), (b":GA#", b"+05\xdf00#"), (b":Q#", b"")]
    with scripted_port(script) as port:
        t = table(port, poll_s=0.02)
        with pytest.raises(DeviceTimeout, match="stalled"):
            t.wait_until_stopped(timeout_s=0.01)


def test_stop_sends_q():
    with scripted_port([(b":Q#", b"")]) as port:  # research note §1.3, no reply
        table(port).stop()


def test_home_moves_to_the_home_pose():
    script = [(b":Sz000*00#", b"1"), (b":Sa+00*00#", b"1"), (b":MA#", b"0"), (b":D#", b"#"),
              (b":GZ#", b"000\xdf00#"), (b":GA#", b"+00\xdf00#")]
    with scripted_port(script) as port:
        table(port, precision=False).home()


def test_identify():
    with scripted_port([(b":GVP#", b"Autostar#"), (b":GVN#", b"43Eg#")]) as port:
        assert table(port).identify() == "Autostar 43Eg"


# -- sexagesimal helpers ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("angle, high, text", [
    (45.5, False, "+45*30"),
    (-0.5, False, "-00*30"),  # negative zero (research note §6.6e)
    (-0.5 - 1 / 3600, True, "-00*30'01"),
    (-1e-9, True, "+00*00'00"),  # rounds to zero: no sign of a negative zero left
    (9.99999, False, "+10*00"),  # rounding carries into the degrees
    (89.999999, True, "+90*00'00"),
])
def test_format_signed(angle, high, text):
    assert format_sexagesimal(angle, high_precision=high) == text


def test_format_unsigned_and_separators():
    assert format_sexagesimal(7.5, signed=False, degree_digits=3) == "007*30"
    assert format_sexagesimal(7.5, high_precision=True, signed=False, degree_digits=3, degree_sign="\xdf",
                              seconds_sign=":") == "007\xdf30:00"
    for bad in (lambda: format_sexagesimal(-1.0, signed=False), lambda: format_sexagesimal(float("nan")),
                lambda: format_sexagesimal(100.0, degree_digits=2)):
        with pytest.raises(ValueError):
            bad()


def test_parse_accepts_every_separator_and_strict_options():
    for sep1 in "*\xdf:'":
        for sep2 in "*\xdf:'":
            assert parse_sexagesimal(f"-00{sep1}30{sep2}36#") == pytest.approx(-0.51)
    assert parse_sexagesimal(b"+05\xdf30") == 5.5
    assert has_seconds("+05*30:00") and not has_seconds(b"+05\xdf30#")
    for bad in ("45", "+45*", "45*30", "+45*60", "+45*30'60", "++45*30", "+45*30#x", ""):
        with pytest.raises(ValueError):
            parse_sexagesimal(bad, signed=True, degree_digits=2)
    with pytest.raises(ValueError):
        parse_sexagesimal("+123*00", signed=False)


def test_sexagesimal_round_trip_over_many_seeded_values():
    """Property-style (no hypothesis here): parse(format(x)) is x within half the resolution, and
    format(parse(text)) gives the text back, for both precisions, signed and unsigned."""
    rng = random.Random(20250214)
    values = [rng.uniform(-90, 90) for _ in range(3000)] + [rng.uniform(-1, 1) for _ in range(1000)]
    values += [k / 60 for k in range(-120, 121)] + [-0.0, 0.0, -1e-12, 1e-12]
    for high, resolution in ((False, 1 / 60), (True, 1 / 3600)):
        for x in values:
            text = format_sexagesimal(x, high_precision=high)
            back = parse_sexagesimal(text, signed=True, degree_digits=2)
            assert abs(back - x) <= resolution / 2 + 1e-9, (x, text)
            assert has_seconds(text) is high
            assert format_sexagesimal(back, high_precision=high) == text
            assert (back < 0) == text.startswith("-"), text
        for x in (rng.uniform(0, 360) for _ in range(2000)):
            az = wrap_azimuth_deg(x)
            if round(az / resolution) * resolution >= 360:
                continue
            text = format_sexagesimal(az, high_precision=high, signed=False, degree_digits=3, degree_sign="\xdf",
                                      seconds_sign=":")
            assert abs(parse_sexagesimal(text.encode("latin-1") + b"#", signed=False, degree_digits=3) - az) \
                <= resolution / 2 + 1e-9
