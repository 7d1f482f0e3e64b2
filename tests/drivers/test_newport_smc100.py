"""Newport SMC100 driver as byte-exact scripted exchanges (anchors-protocols §3.1).

Frames are ``<address><CC><value>\\r\\n`` (``1PA12.5\\r\\n`` is the note's example); replies echo the
address and the command (``1TP12.34567``).
"""

import pytest

from drivers.errors import DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import AxisMotion, Limits
from drivers.newport_smc100 import (
    COMMAND_ERRORS,
    Smc100Axis,
    Smc100CommandError,
    format_number,
    parse_status,
    positioner_errors,
    state_name,
)
from drivers.testing import scripted_port

TE_OK = (b"1TE\r\n", b"1TE@\r\n")


def ts(state: int, errors: int = 0):
    return (b"1TS\r\n", f"1TS{errors:04X}{state:02X}\r\n".encode())


def tp(value: str):
    return (b"1TP\r\n", f"1TP{value}\r\n".encode())


def axis(port, **kwargs) -> Smc100Axis:
    a = Smc100Axis(port, reset_wait_s=0.0, **kwargs)
    a.poll_s = 0.0
    return a


# -- pure helpers ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("code, name", [
    *[(c, "NOT REFERENCED") for c in range(0x0A, 0x12)], (0x14, "CONFIGURATION"), (0x1E, "HOMING"),
    (0x1F, "HOMING"), (0x28, "MOVING"), *[(c, "READY") for c in range(0x32, 0x39)],
    *[(c, "DISABLE") for c in range(0x3C, 0x40)], (0x46, "JOGGING"), (0x47, "JOGGING"),
])
def test_controller_states_are_decoded_by_ranges(code, name):
    assert state_name(code) == name


@pytest.mark.parametrize("code", [0x00, 0x12, 0x20, 0x29, 0x39, 0x40, 0x48])
def test_unknown_state_codes(code):
    assert state_name(code) is None
    with pytest.raises(ProtocolError, match="unknown controller state"):
        parse_status("smc", f"0000{code:02X}")


def test_positioner_error_bits():
    assert positioner_errors(0b1) == ["negative end of run"]
    assert positioner_errors(0x0022) == ["positive end of run", "following error"]
    status = parse_status("smc", "004032")
    assert (status.state, status.errors) == ("READY", ["homing time-out"])
    for bad in ("0000", "00003G", "0000321"):
        with pytest.raises(ProtocolError):
            parse_status("smc", bad)


@pytest.mark.parametrize("value, text", [(12.5, "12.5"), (90.0, "90"), (-1.25, "-1.25"), (0.0, "0"),
                                         (-0.0000001, "0"), (1e-6, "0.000001"), (123.4567891, "123.456789")])
def test_number_format(value, text):
    assert format_number(value) == text


# -- every command, byte for byte -------------------------------------------------------------------------------
def test_identify():
    script = [(b"1VE\r\n", b"1VE SMC_CC - Controller-driver version 2.0.0\r\n"), (b"1ID?\r\n", b"1IDURS100BCC\r\n")]
    with scripted_port(script) as port:
        assert axis(port).identify() == "SMC_CC - Controller-driver version 2.0.0; stage URS100BCC"


def test_position():
    with scripted_port([tp("12.34567")]) as port:
        assert axis(port).position_deg() == 12.34567


def test_address_prefix():
    with scripted_port([(b"3TP\r\n", b"3TP-4.5\r\n")]) as port:
        assert axis(port, address=3).position_deg() == -4.5


def test_status_and_state():
    with scripted_port([ts(0x33), ts(0x0A)]) as port:
        a = axis(port)
        status = a.status()
        assert (status.state, status.state_code, status.error_bits) == ("READY", 0x33, 0)
        assert a.state() == "NOT REFERENCED"


def test_move_absolute_checks_te_then_waits_for_ready():
    script = [(b"1PA12.5\r\n", b""), TE_OK, ts(0x28), ts(0x33), tp("12.5")]
    with scripted_port(script) as port:
        a = axis(port)
        a.move_to(12.5, timeout_s=1.0)


def test_move_without_waiting():
    with scripted_port([(b"1PA-30\r\n", b""), TE_OK]) as port:
        axis(port).move_to(-30.0, wait=False)


@pytest.mark.parametrize("letter, meaning", [("H", "NOT REFERENCED"), ("M", "MOVING"), ("G", "out of limits"),
                                             ("C", "out of specified range")])
def test_refused_move_is_a_typed_error_with_the_letters_meaning(letter, meaning):
    with scripted_port([(b"1PA12.5\r\n", b""), (b"1TE\r\n", f"1TE{letter}\r\n".encode())]) as port:
        with pytest.raises(Smc100CommandError, match=meaning) as info:
            axis(port).move_to(12.5)
    assert info.value.code == letter
    assert info.value.meaning == COMMAND_ERRORS[letter]
    assert isinstance(info.value, DeviceFault)


def test_unknown_command_letter_is_a_protocol_error():
    with scripted_port([(b"1ST\r\n", b""), (b"1TE\r\n", b"1TEA\r\n")]) as port:
        with pytest.raises(ProtocolError, match="unknown message code"):
            axis(port).stop()


def test_stop():
    with scripted_port([(b"1ST\r\n", b""), TE_OK]) as port:
        axis(port).stop()


def test_home_from_not_referenced():
    script = [ts(0x0A), (b"1OR\r\n", b""), TE_OK, ts(0x1E), ts(0x32), tp("0.000000"), ts(0x32)]
    with scripted_port(script) as port:
        axis(port).home(timeout_s=1.0)


def test_home_from_ready_resets_first():
    script = [ts(0x33), (b"1RS\r\n", b""), ts(0x0A), (b"1OR\r\n", b""), TE_OK, ts(0x32), tp("0"), ts(0x32)]
    with scripted_port(script) as port:
        axis(port).home(timeout_s=1.0)


def test_home_without_waiting():
    with scripted_port([ts(0x0A), (b"1OR\r\n", b""), TE_OK]) as port:
        axis(port).home(wait=False)


def test_home_while_moving_is_refused():
    with scripted_port([ts(0x28)]) as port:
        with pytest.raises(DeviceFault, match="cannot home in state MOVING"):
            axis(port).home()


def test_home_that_ends_not_ready_is_a_fault():
    script = [ts(0x0A), (b"1OR\r\n", b""), TE_OK, ts(0x0B), tp("3"), ts(0x0B)]
    with scripted_port(script) as port:
        with pytest.raises(DeviceFault, match="homing ended in state NOT REFERENCED"):
            axis(port).home(timeout_s=1.0)


def test_velocity():
    with scripted_port([(b"1VA?\r\n", b"1VA10.000000\r\n"), (b"1VA5\r\n", b""), TE_OK]) as port:
        a = axis(port)
        assert a.velocity_deg_s() == 10.0
        a.set_velocity_deg_s(5.0)
    with scripted_port([]) as port:
        with pytest.raises(LimitError):
            axis(port).set_velocity_deg_s(-1.0)


def test_acceleration_and_expected_motion():
    script = [(b"1VA?\r\n", b"1VA10.000000\r\n"), (b"1AC?\r\n", b"1AC20.000000\r\n"), (b"1AC8\r\n", b""), TE_OK]
    with scripted_port(script) as port:
        a = axis(port)
        assert a.expected_motion() == AxisMotion(10.0, 20.0)
        a.set_acceleration_deg_s2(8.0)
    with scripted_port([]) as port:
        with pytest.raises(LimitError):
            axis(port).set_acceleration_deg_s2(0.0)


def test_last_error():
    with scripted_port([(b"1TE\r\n", b"1TEK\r\n")]) as port:
        assert axis(port).last_error() == "K"


# -- faults ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bits, text", [(0x1, "negative end of run"), (0x2, "positive end of run"),
                                        (0x20, "following error")])
def test_positioner_errors_are_device_faults(bits, text):
    with scripted_port([ts(0x33, bits)]) as port:
        with pytest.raises(DeviceFault, match=text):
            axis(port).is_moving()


def test_end_of_run_while_homing_is_not_a_fault():
    with scripted_port([ts(0x1E, 0x1)]) as port:
        assert axis(port).is_moving() is True


def test_soft_limits_refuse_before_anything_is_sent():
    with scripted_port([]) as port:
        with pytest.raises(LimitError):
            axis(port, limits=Limits(-45.0, 45.0)).move_to(45.01)


def test_no_reply_is_a_timeout():
    with scripted_port([(b"1TP\r\n", b"")]) as port:
        with pytest.raises(DeviceTimeout):
            axis(port).position_deg()


def test_truncated_reply_is_retried_cleanly():
    with scripted_port([(b"1TP\r\n", b"1TP12."), tp("12.5")]) as port:
        assert axis(port).position_deg() == 12.5
    with scripted_port([(b"1TP\r\n", b"1TP12."), (b"1TP\r\n", b"1TP1")]) as port:
        with pytest.raises(ProtocolError, match="no complete reply") as info:
            axis(port).position_deg()
        assert info.value.received == b"1TP1"


def test_garbled_reply_is_retried_cleanly_never_a_wrong_reading():
    with scripted_port([(b"1TP\r\n", b"kTJ1h.5\r\n"), tp("12.5")]) as port:
        assert axis(port).position_deg() == 12.5
    with scripted_port([(b"1TP\r\n", b"1TPx2.5\r\n"), (b"1TP\r\n", b"1TP12.5.\r\n")]) as port:
        with pytest.raises(ProtocolError, match="cannot parse"):
            axis(port).position_deg()


def test_garbled_te_is_not_asked_again():
    # reading TE may clear the error: a second TE could say "@" and hide a refusal
    with scripted_port([(b"1PA1\r\n", b""), (b"1TE\r\n", b"kTE@\r\n")]) as port:
        with pytest.raises(ProtocolError):
            axis(port).move_to(1.0)
