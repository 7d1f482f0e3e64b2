"""The IR Earth simulator's driver, byte for byte against scripted exchanges (its SCPI-style line protocol is
documented in drivers/sim/earth_simulator.py): commands end with LF, every set is followed by SYST:ERR?, limits are
refused before anything is sent, motions are polled to their end and a stuck one is a typed error."""

import pytest

from drivers.earth_simulator import EarthSimulatorError, EarthSimulatorSource
from drivers.errors import DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import EarthSimulator, SunSimulator
from drivers.testing import scripted_port

OK = (b"SYST:ERR?\n", b'0,"No error"\n')


def source(port, **options):
    return EarthSimulatorSource(port, pause=lambda s: None, **options)


def test_identify_and_the_interfaces():
    with scripted_port([(b"*IDN?\n", b"SUNBENCH,EARTH-SIM,ES-0007,1.0\r\n")]) as port:
        earth = source(port)
        assert earth.identify() == "SUNBENCH,EARTH-SIM,ES-0007,1.0"
    assert isinstance(earth, EarthSimulator) and isinstance(earth, SunSimulator)


def test_lamp_on_sets_the_disc_setpoint_then_the_heater():
    with scripted_port([(b"STAT?\n", b"8\n"), (b"HEAT:TEMP 295.500\n", b""), OK, (b"HEAT ON\n", b""), OK]) as port:
        source(port, disc_temperature_k=295.5).lamp_on()


def test_lamp_on_with_a_heater_fault_is_refused_before_anything_is_sent():
    with scripted_port([(b"STAT?\n", b"32\n")]) as port:
        with pytest.raises(DeviceFault, match="heater fault"):
            source(port).lamp_on()


def test_status_reads_the_word_and_the_disc_temperature():
    with scripted_port([(b"STAT?\n", b"11\n"), (b"MEAS:TEMP?\n", b"290.012\n")]) as port:
        status = source(port).status()
    # 11 = heater on, settled, cover open
    assert (status.lamp_on, status.warm, status.shutter_open, status.fault) == (True, True, True, False)
    assert (status.output, status.output_unit) == (290.012, "K")


def test_a_refused_set_raises_with_the_queue_read_empty():
    with scripted_port([(b"HEAT:TEMP 300.000\n", b""), (b"SYST:ERR?\n", b'-222,"Data out of range"\n'),
                        (b"SYST:ERR?\n", b'-113,"Undefined header"\n'), OK]) as port:
        with pytest.raises(EarthSimulatorError, match="-222 Data out of range; -113") as info:
            source(port).set_disc_temperature_k(300.0)
    assert info.value.errors == [(-222, "Data out of range"), (-113, "Undefined header")]


def test_setpoints_outside_the_limits_are_refused_before_sending():
    with scripted_port([]) as port:
        earth = source(port, temperature_limits_k=(250.0, 320.0))
        with pytest.raises(LimitError, match="400.0 K is outside"):
            earth.set_disc_temperature_k(400.0)
    with scripted_port([]) as port:
        with pytest.raises(LimitError, match="standby|disc setpoint"):
            source(port, temperature_limits_k=(250.0, 320.0), standby_temperature_k=240.0)


def test_the_iris_moves_and_is_polled_until_it_has_settled_at_its_target():
    with scripted_port([(b"IRIS?\n", b"68.0000\n"), (b"IRIS:SPE?\n", b"0.5000\n"), (b"IRIS 64.3000\n", b""), OK,
                        (b"IRIS:MOV?\n", b"1\n"), (b"IRIS:MOV?\n", b"1\n"), (b"IRIS:MOV?\n", b"0\n"),
                        (b"IRIS?\n", b"64.3000\n")]) as port:
        source(port).set_disc_radius_deg(64.3)


def test_a_moving_flag_raised_late_does_not_end_the_wait():
    """Right after the set the controller still says "not moving" and the iris reads where it stood: not settled; the
    wait goes on until it has moved and reads the target (within the driver's 0.005°)."""
    with scripted_port([(b"IRIS 64.3000\n", b""), OK, (b"IRIS:MOV?\n", b"0\n"), (b"IRIS?\n", b"68.0000\n"),
                        (b"IRIS:MOV?\n", b"1\n"), (b"IRIS:MOV?\n", b"0\n"), (b"IRIS?\n", b"64.2970\n")]) as port:
        source(port).set_disc_radius_deg(64.3, timeout_s=10.0)  # 64.297 is 0.003° off: settled
    with scripted_port([(b"IRIS 64.3000\n", b""), OK, (b"IRIS:MOV?\n", b"0\n"), (b"IRIS?\n", b"68.0000\n"),
                        (b"IRIS:MOV?\n", b"0\n"), (b"IRIS?\n", b"64.3100\n")]) as port:
        earth = source(port)
        earth.set_disc_radius_deg(64.3, wait=False)
        assert not earth.disc_settled() and not earth.disc_settled()  # 0.01° off the target: not settled either


def test_settled_without_a_target_of_its_own_asks_the_controllers():
    with scripted_port([(b"IRIS:MOV?\n", b"0\n"), (b"IRIS:TARG?\n", b"66.0000\n"), (b"IRIS?\n", b"66.0010\n"),
                        (b"IRIS:STOP\n", b""), OK, (b"IRIS:MOV?\n", b"0\n"), (b"IRIS:TARG?\n", b"65.1000\n"),
                        (b"IRIS?\n", b"65.1000\n")]) as port:
        earth = source(port)
        assert earth.disc_settled()
        earth.stop_iris()  # the controller's target is now where it stopped
        assert earth.disc_settled()


def test_an_iris_speed_that_is_not_positive_is_a_protocol_error_naming_it():
    for answer in (b"0.0000\n", b"-0.5000\n"):
        with scripted_port([(b"IRIS?\n", b"68.0000\n"), (b"IRIS:SPE?\n", answer)]) as port:
            with pytest.raises(ProtocolError, match=r"IRIS:SPE\?.*speed must be positive.*answered -?0(\.5)? deg/s"):
                source(port).set_disc_radius_deg(64.3)


def test_the_soft_limits_are_told_and_checked_without_a_word_on_the_wire():
    with scripted_port([]) as port:
        earth = source(port, radius_limits_deg=(55.0, 75.0))
        assert earth.radius_limits_deg == (55.0, 75.0)
        earth.check_disc_radius(75.0)
        with pytest.raises(LimitError, match=r"79.0° is outside the soft limits \[55.0, 75.0\]"):
            earth.check_disc_radius(79.0)


def test_the_iris_soft_limits_are_checked_before_anything_is_sent():
    with scripted_port([]) as port:
        earth = source(port, radius_limits_deg=(55.0, 75.0))
        for bad in (54.9, 75.01, float("nan")):
            with pytest.raises(LimitError, match="soft limits"):
                earth.set_disc_radius_deg(bad)


def test_a_stuck_iris_times_out_naming_where_it_stopped():
    with scripted_port([(b"IRIS 60.0000\n", b""), OK, (b"IRIS:MOV?\n", b"1\n"), (b"IRIS?\n", b"66.1000\n")]) as port:
        with pytest.raises(DeviceTimeout, match=r"iris move to 60.0000 deg not finished after 0.0 s \(at 66.1000"):
            source(port).set_disc_radius_deg(60.0, timeout_s=0.0)


def test_the_cover_opens_and_a_stuck_cover_is_a_fault():
    with scripted_port([(b"COV OPEN\n", b""), OK, (b"COV?\n", b"MOVING\n"), (b"COV?\n", b"OPEN\n")]) as port:
        source(port).open_shutter()
    with scripted_port([(b"COV OPEN\n", b""), OK]) as port:
        source(port).open_shutter(wait=False)  # told to open, not waited for
    with scripted_port([(b"COV CLOS\n", b""), OK, (b"COV?\n", b"OPEN\n"), (b"COV?\n", b"OPEN\n")]) as port:
        with pytest.raises(DeviceFault, match=r"cover closing not finished after 0.0 s \(the cover reads OPEN\)"):
            source(port, cover_timeout_s=0.0).close_shutter()


def test_standby_closes_the_cover_and_lowers_the_setpoint():
    with scripted_port([(b"COV CLOS\n", b""), OK, (b"COV?\n", b"CLOSED\n"), (b"HEAT:TEMP 255.000\n", b""),
                        OK]) as port:
        source(port, standby_temperature_k=255.0).standby()


def test_lamp_off_switches_the_heater_off_even_when_the_cover_sticks():
    with scripted_port([(b"HEAT OFF\n", b""), OK, (b"COV CLOS\n", b""), OK, (b"COV?\n", b"OPEN\n"),
                        (b"COV?\n", b"OPEN\n")]) as port:
        source(port, cover_timeout_s=0.0).lamp_off()  # logged, not raised: the disc cools anyway


def test_a_garbled_query_is_asked_again_but_not_a_malformed_error_entry():
    with scripted_port([(b"IRIS?\n", b"6x.0\n"), (b"IRIS?\n", b"66.5000\n")]) as port:
        assert source(port).disc_radius_deg() == 66.5
    with scripted_port([(b"SYST:ERR?\n", b"garbage\n")]) as port:
        with pytest.raises(ProtocolError, match="expected <code>"):
            source(port).check_errors()
