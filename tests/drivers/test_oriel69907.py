"""Byte-exact tests of the Oriel 69907 arc-lamp supply driver (anchors-protocols §4.1).

Command forms and reply shapes follow the lantz and RTS2 drivers cited in the research note: CR on both
sides, ``STBxx`` / ``ESRxx`` hex registers, ``ESRxx`` after every set and action, ``A-PRESET`` with one
decimal, ``P-PRESET`` zero-padded to four digits.
"""

from __future__ import annotations

import math

import pytest

from drivers.errors import DeviceTimeout, LimitError, ProtocolError
from drivers.oriel69907 import EventStatus, Oriel69907, Oriel69907Error, StatusByte
from drivers.testing import scripted_port

T = 0.02  # read timeout of the scripted port [s]


class FakeClock:
    def __init__(self, t: float = 100.0):
        self.t = t

    def __call__(self) -> float:
        return self.t


def supply(port, **kwargs) -> Oriel69907:
    return Oriel69907(port, **kwargs)


# -- identity and registers ---------------------------------------------------------------------------
def test_identify_sends_idn_and_returns_the_text():
    with scripted_port([(b"IDN?\r", b"69907\r")], timeout_s=T) as port:
        assert supply(port).identify() == "69907"


def test_identify_answered_with_an_error_register_raises_the_esr():
    with scripted_port([(b"IDN?\r", b"ESR20\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error) as info:
        supply(port).identify()
    assert info.value.esr == 0x20 and info.value.status.command_error


def test_status_byte_lamp_on_with_interlock_closed():
    with scripted_port([(b"STB?\r", b"STB81\r")], timeout_s=T) as port:
        stb = supply(port).status_byte()
    assert stb == StatusByte(value=0x81, lamp_on=True, external=False, power_mode=False, cal_mode=False,
                             fault=False, comm=False, limit=False, interlock_open=False)


@pytest.mark.parametrize("value, field", [(0x80, "lamp_on"), (0x40, "external"), (0x20, "power_mode"),
                                          (0x10, "cal_mode"), (0x08, "fault"), (0x04, "comm"), (0x02, "limit")])
def test_status_bits_are_decoded_with_masks_at_exact_powers_of_two(value, field):
    """lantz decodes with `>` and misses a register equal to one bit; masks do not (research note §4.1)."""
    stb = StatusByte.decode(value | 0x01)
    flags = {name: getattr(stb, name) for name in ("lamp_on", "external", "power_mode", "cal_mode", "fault",
                                                   "comm", "limit")}
    assert flags == {name: name == field for name in flags}


def test_interlock_polarity_is_configurable():
    assert StatusByte.decode(0x00).interlock_open  # default: bit 0 set = interlock closed (69920 reading)
    assert not StatusByte.decode(0x01).interlock_open
    assert StatusByte.decode(0x01, interlock_bit_set_means_closed=False).interlock_open  # lantz LED reading
    with scripted_port([(b"STB?\r", b"STB01\r")], timeout_s=T) as port:
        assert supply(port, interlock_bit_set_means_closed=False).status_byte().interlock_open


def test_status_byte_keeps_the_warm_up_timer_true_to_the_supply():
    clock = FakeClock(10.0)
    with scripted_port([(b"STB?\r", b"STB81\r"), (b"STB?\r", b"STB01\r")], timeout_s=T) as port:
        psu = supply(port, clock=clock)
        psu.status_byte()  # lamp found burning: warm-up counted from now (conservative)
        assert psu.started_at_s == 10.0
        psu.status_byte()  # lamp off: no warm-up running
        assert psu.started_at_s is None


def test_status_byte_answered_with_esr_raises_the_register():
    with scripted_port([(b"STB?\r", b"ESR24\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error) as info:
        supply(port).status_byte()
    assert info.value.esr == 0x24 and info.value.status.query_error


def test_event_status_decodes_every_bit():
    with scripted_port([(b"ESR?\r", b"ESRB5\r")], timeout_s=T) as port:
        esr = supply(port).event_status()
    assert esr == EventStatus(value=0xB5, power_on=True, user_request=False, command_error=True,
                              execution_error=True, device_error=False, query_error=True,
                              request_control=False, operation_complete=True)
    assert esr.error and esr.describe() == "command error, execution error, query error"


def test_a_garbled_event_status_is_not_asked_again():
    """ESR? clears the register: a second read would report 0 and hide the error bits."""
    with scripted_port([(b"ESR?\r", b"\x1fS\x08\x30\x30\r")], timeout_s=T) as port, pytest.raises(ProtocolError):
        supply(port).event_status()


def test_power_on_and_operation_complete_are_not_errors():
    assert not EventStatus.decode(0x80 | 0x40 | 0x02 | 0x01).error


# -- lamp -----------------------------------------------------------------------------------------------
def test_start_checks_the_esr_and_notes_the_time():
    clock = FakeClock(42.0)
    with scripted_port([(b"START\r", b"ESR00\r")], timeout_s=T) as port:
        psu = supply(port, clock=clock)
        psu.start()
    assert psu.started_at_s == 42.0


def test_start_on_a_started_lamp_keeps_the_first_time():
    clock = FakeClock(1.0)
    with scripted_port([(b"START\r", b"ESR80\r"), (b"START\r", b"ESR00\r")], timeout_s=T) as port:
        psu = supply(port, clock=clock)
        psu.start()  # ESR80: power-on bit only, not an error
        clock.t = 5.0
        psu.start()
    assert psu.started_at_s == 1.0


def test_start_refused_raises_with_the_register_value():
    with scripted_port([(b"START\r", b"ESR10\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error) as info:
        supply(port).start()
    assert info.value.esr == 0x10 and info.value.status.execution_error and info.value.command == "START"
    assert info.value.received == b"ESR10"


def test_stop_clears_the_warm_up_timer():
    with scripted_port([(b"START\r", b"ESR00\r"), (b"STOP\r", b"ESR00\r")], timeout_s=T) as port:
        psu = supply(port, clock=FakeClock())
        psu.start()
        psu.stop()
    assert psu.started_at_s is None


def test_a_garbled_reply_to_an_action_is_not_sent_again():
    """START may have struck the lamp: the driver cannot know, so it raises instead of re-sending."""
    with scripted_port([(b"START\r", b"\x1fS\x08\r")], timeout_s=T) as port, pytest.raises(ProtocolError):
        supply(port).start()


# -- readings -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method, command, reply, value", [
    ("amps", b"AMPS?\r", b"5.0\r", 5.0),
    ("volts", b"VOLTS?\r", b"19\r", 19.0),  # RTS2 reads an integer
    ("volts", b"VOLTS?\r", b"18.7\r", 18.7),  # lantz a float
    ("watts", b"WATTS?\r", b"95\r", 95.0),
    ("lamp_hours", b"LAMP HRS?\r", b"1234\r", 1234.0),
    ("current_preset_a", b"A-PRESET?\r", b"5.5\r", 5.5),
    ("power_preset_w", b"P-PRESET?\r", b"0095\r", 95.0),
])
def test_readings(method, command, reply, value):
    with scripted_port([(command, reply)], timeout_s=T) as port:
        assert getattr(supply(port), method)() == value


def test_a_query_answered_with_an_error_register_raises():
    with scripted_port([(b"AMPS?\r", b"ESR20\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error):
        supply(port).amps()


def test_a_garbled_reading_is_asked_again():
    with scripted_port([(b"AMPS?\r", b"o.j\r"), (b"AMPS?\r", b"5.0\r")], timeout_s=T) as port:
        assert supply(port).amps() == 5.0


def test_a_cut_reading_is_asked_again():
    with scripted_port([(b"WATTS?\r", b"9"), (b"WATTS?\r", b"95\r")], timeout_s=T) as port:
        assert supply(port).watts() == 95.0


def test_a_reading_garbled_twice_raises_and_never_returns_a_value():
    with scripted_port([(b"AMPS?\r", b"o.j\r"), (b"AMPS?\r", b"5.\x00\r")], timeout_s=T) as port:
        with pytest.raises(ProtocolError) as info:
            supply(port).amps()
    assert info.value.received == b"5.\x00"


def test_no_reply_raises_device_timeout_after_the_retry():
    with scripted_port([(b"STB?\r", b""), (b"STB?\r", b"")], timeout_s=T) as port, pytest.raises(DeviceTimeout):
        supply(port).status_byte()


def test_a_malformed_register_is_a_protocol_error():
    with scripted_port([(b"STB?\r", b"STBZZ\r"), (b"STB?\r", b"STB1\r")], timeout_s=T) as port:
        with pytest.raises(ProtocolError):
            supply(port).status_byte()


# -- presets --------------------------------------------------------------------------------------------
def test_set_current_preset_sends_one_decimal_and_checks_the_esr():
    with scripted_port([(b"A-PRESET=5.5\r", b"ESR00\r")], timeout_s=T) as port:
        supply(port).set_current_preset_a(5.5)


def test_set_current_preset_refused_by_the_supply_raises_with_the_register():
    with scripted_port([(b"A-PRESET=9.0\r", b"ESR10\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error) as info:
        supply(port).set_current_preset_a(9.0)
    assert info.value.esr == 0x10 and info.value.command == "A-PRESET=9.0"


def test_set_current_preset_with_a_command_error_raises():
    with scripted_port([(b"A-PRESET=5.0\r", b"ESR20\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error) as info:
        supply(port).set_current_preset_a(5.0)
    assert info.value.status.command_error


@pytest.mark.parametrize("current_a", [12.5, -0.1, math.nan, math.inf])
def test_a_current_outside_the_limit_is_refused_with_nothing_sent(current_a):
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        supply(port, max_current_a=12.0).set_current_preset_a(current_a)


def test_the_current_limit_is_the_drivers_setting():
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        supply(port, max_current_a=6.0).set_current_preset_a(6.5)


def test_set_power_preset_sends_four_digits():
    with scripted_port([(b"P-PRESET=0095\r", b"ESR00\r"), (b"P-PRESET=0080\r", b"ESR00\r")], timeout_s=T) as port:
        psu = supply(port)
        psu.set_power_preset_w(95)
        psu.set_power_preset_w(80.0)


@pytest.mark.parametrize("power_w", [101, -1, 95.5, True, "95", math.nan])
def test_a_power_outside_the_limit_is_refused_with_nothing_sent(power_w):
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        supply(port, max_power_w=100).set_power_preset_w(power_w)


def test_a_garbled_esr_after_a_set_raises_protocol_error():
    with scripted_port([(b"P-PRESET=0095\r", b"\x1fS\x08\x300\r")], timeout_s=T) as port, pytest.raises(ProtocolError):
        supply(port).set_power_preset_w(95)


# -- limits and reset -----------------------------------------------------------------------------------
def test_limits_are_read_and_set_in_the_lantz_formats():
    script = [(b"A-LIM?\r", b"12.0\r"), (b"P-LIM?\r", b"0100\r"), (b"A-LIM=10.0\r", b"ESR00\r"),
              (b"P-LIM=0080\r", b"ESR00\r")]
    with scripted_port(script, timeout_s=T) as port:
        psu = supply(port)
        assert psu.current_limit_a() == 12.0 and psu.power_limit_w() == 100.0
        psu.set_current_limit_a(10.0)
        psu.set_power_limit_w(80)


@pytest.mark.parametrize("method, value", [("set_current_limit_a", 12.5), ("set_current_limit_a", math.nan),
                                           ("set_power_limit_w", 101), ("set_power_limit_w", 99.5)])
def test_a_limit_beyond_the_drivers_is_refused_with_nothing_sent(method, value):
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        getattr(supply(port, max_current_a=12.0, max_power_w=100), method)(value)


def test_a_limit_refused_by_the_supply_raises_with_the_register():
    with scripted_port([(b"P-LIM=0090\r", b"ESR10\r")], timeout_s=T) as port, pytest.raises(Oriel69907Error) as info:
        supply(port).set_power_limit_w(90)
    assert info.value.status.execution_error and info.value.command == "P-LIM=0090"


def test_reset_sends_rst_and_checks_the_esr():
    with scripted_port([(b"RST\r", b"ESR00\r"), (b"RST\r", b"ESR20\r")], timeout_s=T) as port:
        psu = supply(port)
        psu.reset()
        with pytest.raises(Oriel69907Error):
            psu.reset()
