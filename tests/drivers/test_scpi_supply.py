"""Byte-exact tests of the SCPI bench-supply driver (anchors-protocols §4.2: the RTS2 E3631A subset).

Commands end with LF; replies are read up to LF and a CR before it is dropped, so both LF and CR LF
supplies are covered. Every set is followed by ``SYST:ERR?`` until the queue reads ``+0``.
"""

from __future__ import annotations

import math

import pytest

from drivers.errors import DeviceTimeout, LimitError, ProtocolError
from drivers.scpi_supply import E363XA_SERIAL, ScpiError, ScpiSupply
from drivers.testing import scripted_port

T = 0.02  # read timeout of the scripted port [s]
NO_ERROR = (b"SYST:ERR?\n", b'+0,"No error"\n')


class FakeClock:
    def __init__(self, t: float = 100.0):
        self.t = t

    def __call__(self) -> float:
        return self.t


def psu(port, **kwargs) -> ScpiSupply:
    kwargs.setdefault("max_current_a", 1.0)
    kwargs.setdefault("max_voltage_v", 12.0)
    return ScpiSupply(port, **kwargs)


def test_e363xa_line_settings_are_8n2_with_dsr_dtr():
    assert E363XA_SERIAL == {"baudrate": 9600, "bytesize": 8, "parity": "N", "stopbits": 2, "dsrdtr": True}


# -- identity and errors --------------------------------------------------------------------------------
def test_identify_accepts_cr_lf():
    reply = b"Agilent Technologies,E3631A,0,1.4-5.0-1.0\r\n"
    with scripted_port([(b"*IDN?\n", reply)], timeout_s=T) as port:
        assert psu(port).identify() == "Agilent Technologies,E3631A,0,1.4-5.0-1.0"


def test_identify_rejects_a_reply_without_four_fields():
    with scripted_port([(b"*IDN?\n", b"E3631A\n"), (b"*IDN?\n", b"E3631A\n")], timeout_s=T) as port:
        with pytest.raises(ProtocolError):
            psu(port).identify()


def test_next_error():
    with scripted_port([(b"SYST:ERR?\n", b'-113,"Undefined header"\n')], timeout_s=T) as port:
        assert psu(port).next_error() == (-113, "Undefined header")


def test_no_error_in_the_scpi_99_form_without_a_sign():
    with scripted_port([(b"CURR 0.700\n", b""), (b"SYST:ERR?\n", b'0,"No error"\n')], timeout_s=T) as port:
        psu(port).set_current_a(0.7)


def test_check_errors_reads_the_queue_empty_and_raises_with_every_entry():
    script = [(b"SYST:ERR?\n", b'-222,"Data out of range"\n'), (b"SYST:ERR?\n", b'-113,"Undefined header"\n'),
              NO_ERROR]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(ScpiError) as info:
        psu(port).check_errors("CURR 0.700")
    assert info.value.errors == [(-222, "Data out of range"), (-113, "Undefined header")]
    assert info.value.command == "CURR 0.700"


def test_a_garbled_error_reply_is_not_asked_again():
    """SYST:ERR? pops the entry it reads: asking again could report "no error" for a lost one."""
    with scripted_port([(b"SYST:ERR?\n", b'q222v"Data out of range"\n')], timeout_s=T) as port:
        with pytest.raises(ProtocolError):
            psu(port).check_errors()


def test_remote_sends_syst_rem_and_checks_errors():
    with scripted_port([(b"SYST:REM\n", b""), NO_ERROR], timeout_s=T) as port:
        psu(port).remote()


# -- setpoints ------------------------------------------------------------------------------------------
def test_set_current_sends_curr_and_checks_errors():
    with scripted_port([(b"CURR 0.700\n", b""), NO_ERROR], timeout_s=T) as port:
        psu(port).set_current_a(0.7)


def test_set_current_refused_by_the_supply_raises_scpi_error():
    script = [(b"CURR 0.700\n", b""), (b"SYST:ERR?\n", b'-222,"Data out of range"\n'), NO_ERROR]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(ScpiError) as info:
        psu(port).set_current_a(0.7)
    assert info.value.errors == [(-222, "Data out of range")]


@pytest.mark.parametrize("current_a", [1.01, -0.1, math.nan, math.inf])
def test_a_current_outside_the_limit_is_refused_with_nothing_sent(current_a):
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        psu(port).set_current_a(current_a)


def test_current_setpoint():
    with scripted_port([(b"CURR?\n", b"+7.00000000E-01\n")], timeout_s=T) as port:
        assert psu(port).current_setpoint_a() == pytest.approx(0.7)


def test_apply_single_output():
    with scripted_port([(b"APPL 5.000,0.700\n", b""), NO_ERROR], timeout_s=T) as port:
        psu(port).apply(5.0, 0.7)


def test_apply_names_the_output_of_a_multi_output_supply():
    with scripted_port([(b"APPL P6V,5.000,0.700\n", b""), NO_ERROR], timeout_s=T) as port:
        psu(port, output="P6V").apply(5.0, 0.7)


@pytest.mark.parametrize("voltage_v, current_a", [(12.5, 0.7), (5.0, 1.5), (-1.0, 0.5)])
def test_apply_outside_the_limits_is_refused_with_nothing_sent(voltage_v, current_a):
    with scripted_port([], timeout_s=T) as port, pytest.raises(LimitError):
        psu(port).apply(voltage_v, current_a)


# -- output ---------------------------------------------------------------------------------------------
def test_output_on_and_off_keep_the_warm_up_timer():
    clock = FakeClock(5.0)
    script = [(b"OUTP ON\n", b""), NO_ERROR, (b"OUTP ON\n", b""), NO_ERROR, (b"OUTP OFF\n", b""), NO_ERROR]
    with scripted_port(script, timeout_s=T) as port:
        supply = psu(port, clock=clock)
        supply.set_output(True)
        assert supply.output_on_at_s == 5.0
        clock.t = 7.0
        supply.set_output(True)  # already on: the LED is not restarted
        assert supply.output_on_at_s == 5.0
        supply.set_output(False)
        assert supply.output_on_at_s is None


def test_output_on_refused_raises_and_starts_no_timer():
    script = [(b"OUTP ON\n", b""), (b"SYST:ERR?\n", b'-221,"Settings conflict"\n'), NO_ERROR]
    with scripted_port(script, timeout_s=T) as port:
        supply = psu(port, clock=FakeClock())
        with pytest.raises(ScpiError):
            supply.set_output(True)
    assert supply.output_on_at_s is None


@pytest.mark.parametrize("reply, expected", [(b"1\n", True), (b"0\r\n", False)])
def test_output_enabled(reply, expected):
    with scripted_port([(b"OUTP?\n", reply)], timeout_s=T) as port:
        assert psu(port).output_enabled() is expected


def test_output_enabled_keeps_the_warm_up_timer_true_to_the_supply():
    clock = FakeClock(3.0)
    with scripted_port([(b"OUTP?\n", b"1\n"), (b"OUTP?\n", b"0\n")], timeout_s=T) as port:
        supply = psu(port, clock=clock)
        supply.output_enabled()  # found on: counted from now
        assert supply.output_on_at_s == 3.0
        supply.output_enabled()
        assert supply.output_on_at_s is None


# -- measurements ---------------------------------------------------------------------------------------
def test_measure_current_and_voltage():
    script = [(b"MEAS:CURR?\n", b"+6.99800000E-01\n"), (b"MEAS:VOLT?\n", b"+3.60100000E+00\n")]
    with scripted_port(script, timeout_s=T) as port:
        supply = psu(port)
        assert supply.measure_current_a() == pytest.approx(0.6998)
        assert supply.measure_voltage_v() == pytest.approx(3.601)


def test_measure_names_the_output_of_a_multi_output_supply():
    script = [(b"MEAS:CURR? P6V\n", b"+7.0E-01\n"), (b"MEAS:VOLT? P6V\n", b"+3.6E+00\n")]
    with scripted_port(script, timeout_s=T) as port:
        supply = psu(port, output="P6V")
        assert supply.measure_current_a() == pytest.approx(0.7)
        assert supply.measure_voltage_v() == pytest.approx(3.6)


def test_a_garbled_measurement_is_asked_again():
    with scripted_port([(b"MEAS:CURR?\n", b"q6t99E-01\n"), (b"MEAS:CURR?\n", b"+7.0E-01\n")], timeout_s=T) as port:
        assert psu(port).measure_current_a() == pytest.approx(0.7)


def test_a_measurement_garbled_twice_raises_and_never_returns_a_value():
    script = [(b"MEAS:CURR?\n", b"q6t99E-01\n"), (b"MEAS:CURR?\n", b"+7.0E-0?\n")]
    with scripted_port(script, timeout_s=T) as port, pytest.raises(ProtocolError):
        psu(port).measure_current_a()


def test_no_reply_raises_device_timeout():
    with scripted_port([(b"OUTP?\n", b""), (b"OUTP?\n", b"1")], timeout_s=T) as port, pytest.raises(DeviceTimeout):
        psu(port).output_enabled()
