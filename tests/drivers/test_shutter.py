"""Byte-exact tests of the Thorlabs SC10 shutter-controller driver.

Reply shapes follow the public sources named in drivers.shutter: the controller echoes the command and a
CR, then (queries) the value and a CR, then the prompt ``"> "`` — InstrumentKit's SC10 tests script
``"ens?" → "ens?\\r0\\r> "`` and ``"mode=2" → "mode=2\\r> "``; Micro-Manager strips the echo the same way.
"""

from __future__ import annotations

import pytest

from drivers.errors import DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.shutter import SC10CommandError, ThorlabsSC10
from drivers.testing import scripted_port

T = 0.02  # read timeout of the scripted port [s]


def q(command: bytes, value: bytes) -> tuple[bytes, bytes]:
    """A query exchange: echo, value, prompt."""
    return command + b"\r", command + b"\r" + value + b"\r> "


def s(command: bytes) -> tuple[bytes, bytes]:
    """A set exchange: echo and prompt."""
    return command + b"\r", command + b"\r> "


# -- queries --------------------------------------------------------------------------------------------
def test_identify():
    with scripted_port([q(b"id?", b"THORLABS SC10 VERSION 1.07")], timeout_s=T) as port:
        assert ThorlabsSC10(port).identify() == "THORLABS SC10 VERSION 1.07"


def test_mode():
    with scripted_port([q(b"mode?", b"1")], timeout_s=T) as port:
        assert ThorlabsSC10(port).mode() == 1


@pytest.mark.parametrize("value, expected", [(b"0", False), (b"1", True)])
def test_enabled(value, expected):
    with scripted_port([q(b"ens?", value)], timeout_s=T) as port:
        assert ThorlabsSC10(port).enabled() is expected


def test_closed_and_open():
    with scripted_port([q(b"closed?", b"1"), q(b"closed?", b"0")], timeout_s=T) as port:
        sc10 = ThorlabsSC10(port)
        assert sc10.is_closed() is True
        assert sc10.is_open() is True


def test_interlock_tripped():
    with scripted_port([q(b"interlock?", b"1")], timeout_s=T) as port:
        assert ThorlabsSC10(port).interlock_tripped() is True


# -- sets -----------------------------------------------------------------------------------------------
def test_set_mode():
    with scripted_port([s(b"mode=1")], timeout_s=T) as port:
        ThorlabsSC10(port).set_mode(1)


@pytest.mark.parametrize("mode", [0, 6, True, "1"])
def test_a_mode_outside_1_to_5_is_refused_with_nothing_sent(mode):
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        ThorlabsSC10(port).set_mode(mode)


def test_toggle_enable():
    with scripted_port([s(b"ens")], timeout_s=T) as port:
        ThorlabsSC10(port).toggle_enable()


def test_configure_switches_to_manual_mode_only_when_needed():
    with scripted_port([q(b"mode?", b"2"), s(b"mode=1"), q(b"mode?", b"1")], timeout_s=T) as port:
        sc10 = ThorlabsSC10(port)
        sc10.configure()
        sc10.configure()


def test_an_error_string_raises_sc10_command_error():
    reply = b"mode=1\rCommand error CMD_ARG_INVALID\r> "
    with scripted_port([(b"mode=1\r", reply)], timeout_s=T) as port, pytest.raises(SC10CommandError) as info:
        ThorlabsSC10(port).set_mode(1)
    assert "CMD_ARG_INVALID" in str(info.value) and info.value.received == reply


# -- open / close -----------------------------------------------------------------------------------------
def test_open_reads_the_state_toggles_and_checks():
    with scripted_port([q(b"ens?", b"0"), s(b"ens"), q(b"closed?", b"0")], timeout_s=T) as port:
        ThorlabsSC10(port).open()


def test_open_when_open_does_not_toggle():
    with scripted_port([q(b"ens?", b"1"), q(b"closed?", b"0")], timeout_s=T) as port:
        ThorlabsSC10(port).open()


def test_close_reads_the_state_toggles_and_checks():
    with scripted_port([q(b"ens?", b"1"), s(b"ens"), q(b"closed?", b"1")], timeout_s=T) as port:
        ThorlabsSC10(port).close()


def test_open_with_the_interlock_tripped_raises_device_fault():
    script = [q(b"ens?", b"0"), s(b"ens"), q(b"closed?", b"1"), q(b"interlock?", b"1")]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(DeviceFault, match="interlock"):
        ThorlabsSC10(port).open()


def test_a_shutter_that_does_not_move_raises_device_fault():
    script = [q(b"ens?", b"1"), s(b"ens"), q(b"closed?", b"0"), q(b"interlock?", b"0")]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(DeviceFault, match="did not move"):
        ThorlabsSC10(port).close()


def test_a_garbled_reply_to_ens_is_checked_by_reading_the_state_not_by_toggling_again():
    script = [q(b"ens?", b"0"), (b"ens\r", b"?4s\r> "), q(b"ens?", b"1"), q(b"closed?", b"0")]
    with scripted_port(script, timeout_s=T) as port:
        ThorlabsSC10(port).open()


def test_a_garbled_reply_to_ens_with_the_state_unchanged_raises():
    script = [q(b"ens?", b"0"), (b"ens\r", b"?4s\r> "), q(b"ens?", b"0")]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(ProtocolError):
        ThorlabsSC10(port).open()


# -- bad replies ------------------------------------------------------------------------------------------
def test_a_wrong_echo_is_asked_again():
    with scripted_port([(b"ens?\r", b"?4s?\r0\r> "), q(b"ens?", b"1")], timeout_s=T) as port:
        assert ThorlabsSC10(port).enabled() is True


def test_a_bad_flag_twice_raises_protocol_error():
    with scripted_port([q(b"closed?", b"2"), q(b"closed?", b"k")], timeout_s=T) as port, pytest.raises(ProtocolError):
        ThorlabsSC10(port).is_closed()


def test_a_set_answered_with_a_value_is_a_protocol_error():
    with scripted_port([(b"ens\r", b"ens\r1\r> ")], timeout_s=T) as port, pytest.raises(ProtocolError):
        ThorlabsSC10(port).toggle_enable()


def test_a_missing_prompt_times_out_after_the_retry():
    script = [(b"mode?\r", b"mode?\r1\r"), (b"mode?\r", b"mode?\r1\r")]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(DeviceTimeout) as info:
        ThorlabsSC10(port).mode()
    assert info.value.received == b"mode?\r1\r"
