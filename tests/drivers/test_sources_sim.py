"""The sun-simulator drivers against their wire-level simulators, through real ``sim://`` URLs.

Each test serves fresh simulators of one simulated world under unique names and unregisters them after.
The drivers get the world's clock, so warm-up is timed in simulated time: at a small time scale it takes
(simulated) time, at time scale 0 observing the lamp completes it at once (anchors-protocols §6).
"""

from __future__ import annotations

import math
import time
import uuid
from dataclasses import dataclass

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.oriel69907 import Oriel69907, Oriel69907Error
from drivers.scpi_supply import ScpiError, ScpiSupply
from drivers.shutter import ThorlabsSC10
from drivers.sim import registry
from drivers.sim.clock import SimClock
from drivers.sim.lamp import LED, XENON, LampSpec
from drivers.sim.oriel69907 import Oriel69907Simulator, amps_for_watts
from drivers.sim.scpi_supply import ScpiSupplySimulator
from drivers.sim.shutter import ShutterSimulator, ThorlabsSC10Simulator
from drivers.sim.world import SimWorld
from drivers.sources import ArcLampSource, LedSource
from drivers.transport import open_port

TIMEOUT_S = 0.02  # port read timeout; the simulators answer within the write


def warm_time_s(spec: LampSpec) -> float:
    """Time from switch-on until the lamp model counts as warm [s] (drivers.sim.lamp.LampModel.warm_at)."""
    return spec.ignition_s + spec.warmup_tau_s * math.log(0.3 / spec.warm_tolerance)


@pytest.fixture
def serve():
    """Register simulators under unique names; unregister them after the test."""
    names = []

    def _serve(device) -> str:
        name = f"test-{device.name}-{uuid.uuid4().hex[:10]}"
        names.append(name)
        return registry.register(name, device)

    yield _serve
    for name in names:
        registry.unregister(name)


@dataclass
class Arc:
    world: SimWorld
    lamp_sim: Oriel69907Simulator
    shutter_sim: ThorlabsSC10Simulator
    supply: Oriel69907
    shutter: ThorlabsSC10
    source: ArcLampSource
    sent: list  # every byte the supply driver wrote, as RecordingSerial events


@dataclass
class Led:
    world: SimWorld
    sim: ScpiSupplySimulator
    supply: ScpiSupply
    source: LedSource
    sent: list


@pytest.fixture
def make_arc(serve):
    def _make(time_scale: float = 0.0, **source_kwargs) -> Arc:
        world = SimWorld(clock=SimClock(time_scale), lamp_spec=XENON)
        lamp_sim, shutter_sim = Oriel69907Simulator(world), ShutterSimulator(world)
        events: list = []
        supply = Oriel69907(open_port(serve(lamp_sim), timeout_s=TIMEOUT_S, record=events), clock=world.clock.now)
        shutter = ThorlabsSC10(open_port(serve(shutter_sim), timeout_s=TIMEOUT_S))
        shutter.configure()
        source_kwargs.setdefault("warmup_s", warm_time_s(XENON))
        source = ArcLampSource(supply, shutter, **source_kwargs)
        return Arc(world, lamp_sim, shutter_sim, supply, shutter, source, events)
    return _make


@pytest.fixture
def make_led(serve):
    def _make(time_scale: float = 0.0, *, current_a: float = 0.7, out_terminator: bytes = b"\n") -> Led:
        world = SimWorld(clock=SimClock(time_scale), lamp_spec=LED)
        sim = ScpiSupplySimulator(world, out_terminator=out_terminator)
        events: list = []
        supply = ScpiSupply(open_port(serve(sim), timeout_s=TIMEOUT_S, record=events), max_current_a=1.0,
                            max_voltage_v=12.0, clock=world.clock.now)
        source = LedSource(supply, current_a, voltage_v=6.0, warmup_s=warm_time_s(LED))
        return Led(world, sim, supply, source, events)
    return _make


def tx(events) -> list[bytes]:
    return [bytes.fromhex(e["hex"]) for e in events if e["dir"] == "tx"]


# == arc lamp: Oriel 69907 + Thorlabs SC10 ================================================================
def test_arc_warm_up_takes_simulated_time_at_a_small_time_scale(make_arc):
    scale = 2000.0
    arc = make_arc(scale)
    arc.source.lamp_on()
    t0_wall, t0_sim = time.monotonic(), arc.world.clock.now()
    assert not arc.source.status().warm
    arc.source.wait_until_warm(timeout_s=3.0, poll_s=0.002)
    wall = time.monotonic() - t0_wall
    assert arc.world.clock.now() - t0_sim >= warm_time_s(XENON) * 0.99
    assert wall >= warm_time_s(XENON) / scale * 0.9, "warm-up must not be instant at a non-zero time scale"
    assert arc.world.lamp.is_warm()


def test_arc_warm_up_is_instant_at_time_scale_zero(make_arc):
    arc = make_arc(0.0)
    t0 = time.monotonic()
    arc.source.lamp_on()
    arc.source.wait_until_warm(timeout_s=1.0, poll_s=0.5)
    assert time.monotonic() - t0 < 0.25, "the first status must already be warm"
    assert arc.world.clock.now() == pytest.approx(warm_time_s(XENON))
    status = arc.source.status()
    assert status.lamp_on and status.warm and not status.fault
    assert status.output == pytest.approx(XENON.nominal_current_a) and status.output_unit == "A"


def test_arc_shutter_open_and_close_change_the_irradiance(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.source.wait_until_warm(timeout_s=1.0)
    assert arc.world.irradiance() == 0.0
    arc.source.open_shutter()
    assert arc.world.irradiance() == pytest.approx(1.0, abs=0.02)
    assert arc.source.status().shutter_open
    arc.source.close_shutter()
    assert arc.world.irradiance() == 0.0
    assert not arc.source.status().shutter_open


def test_arc_standby_closes_the_shutter_and_leaves_the_lamp_burning(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.source.wait_until_warm(timeout_s=1.0)
    arc.source.open_shutter()
    arc.source.standby()
    assert not arc.world.lamp.shutter_open and arc.world.irradiance() == 0.0
    assert arc.world.lamp.on, "a xenon lamp is not re-struck between runs"
    status = arc.source.status()
    assert status.lamp_on and status.warm and not status.shutter_open
    assert b"STOP\r" not in tx(arc.sent)


def test_arc_lamp_on_with_a_burning_lamp_does_not_strike_again(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.source.lamp_on()
    assert tx(arc.sent).count(b"START\r") == 1


def test_arc_lamp_on_sets_the_current_preset(make_arc):
    arc = make_arc(current_a=4.5)
    arc.source.lamp_on()
    assert arc.world.lamp.current_a == 4.5
    assert arc.supply.current_preset_a() == 4.5 and arc.supply.amps() == 4.5
    assert not arc.supply.status_byte().limit


def test_arc_power_limit_holds_the_lamp_at_its_limit(make_arc):
    """P-LIM is enforced: 6 A would take 6 × 19.8 = 119 W from the 100 W factory limit, so the supply runs the
    lamp at 100 W and lights its LIMIT bit; a lower limit holds it lower, a preset within it runs as set."""
    arc = make_arc(current_a=6.0)
    arc.source.lamp_on()
    assert arc.supply.current_preset_a() == 6.0 and arc.supply.power_limit_w() == 100.0
    assert arc.supply.watts() == 100.0 and arc.supply.amps() == round(amps_for_watts(100), 1)  # AMPS?: 5.2
    assert arc.supply.status_byte().limit and arc.world.lamp.current_a < 6.0
    arc.supply.set_power_limit_w(80)
    assert arc.supply.watts() == 80.0 and arc.world.lamp.current_a == pytest.approx(amps_for_watts(80))
    with pytest.raises(Oriel69907Error) as info:
        arc.supply.set_power_preset_w(90)  # a preset above the limit is refused
    assert info.value.status.execution_error
    arc.supply.set_current_preset_a(4.0)
    assert arc.supply.amps() == 4.0 and not arc.supply.status_byte().limit and arc.world.lamp.current_a == 4.0


def test_arc_current_limit_below_the_preset_holds_the_lamp(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.supply.set_current_limit_a(4.0)
    assert arc.supply.amps() == 4.0 and arc.supply.status_byte().limit and arc.supply.current_preset_a() == 5.0
    arc.supply.reset()  # RST: the factory limits again; the lamp burns on at the factory preset
    assert (arc.supply.current_limit_a(), arc.supply.power_limit_w()) == (12.0, 100.0)
    assert arc.supply.amps() == 5.0 and not arc.supply.status_byte().limit and arc.world.lamp.on


def test_arc_limits_above_the_supply_rating_are_refused(serve):
    sim = Oriel69907Simulator(SimWorld(), rating_a=20.0, rating_w=200)
    port = open_port(serve(sim), timeout_s=TIMEOUT_S)
    port.query(b"ESR?\r", b"\r")
    assert port.query(b"A-LIM=20.5\r", b"\r") == b"ESR10\r" and sim.a_limit == 12.0
    assert port.query(b"P-LIM=0201\r", b"\r") == b"ESR10\r" and sim.p_limit == 100
    assert port.query(b"P-LIM=0200\r", b"\r") == b"ESR00\r" and port.query(b"P-LIM?\r", b"\r") == b"0200\r"


def test_69920_mode_and_panel_commands_only_as_an_option(serve):
    """MODE= and COMM= are the 69920's (UNCONFIRMED for the 69907): a command error unless asked for."""
    world = SimWorld()
    port = open_port(serve(Oriel69907Simulator(world)), timeout_s=TIMEOUT_S)
    port.query(b"ESR?\r", b"\r")
    assert port.query(b"MODE=0\r", b"\r") == b"ESR20\r" and port.query(b"COMM=1\r", b"\r") == b"ESR20\r"

    world = SimWorld()
    sim = Oriel69907Simulator(world, sibling_commands=True)
    port = open_port(serve(sim), timeout_s=TIMEOUT_S)
    port.query(b"ESR?\r", b"\r")
    assert port.query(b"P-PRESET=0080\r", b"\r") == b"ESR00\r"
    assert port.query(b"MODE=0\r", b"\r") == b"ESR00\r"  # power mode: the lamp runs at P-PRESET
    assert port.query(b"COMM=1\r", b"\r") == b"ESR00\r"
    assert port.query(b"STB?\r", b"\r") == b"STB25\r"  # power mode, panel locked, interlock closed
    assert port.query(b"START\r", b"\r") == b"ESR00\r"
    assert port.query(b"WATTS?\r", b"\r") == b"80\r"
    assert world.lamp.current_a == pytest.approx(amps_for_watts(80))
    assert port.query(b"MODE=1\r", b"\r") == b"ESR10\r"  # not while the lamp burns
    sim.front_panel_mode(False)  # the operator turns the knob instead
    assert port.query(b"AMPS?\r", b"\r") == b"5.0\r" and port.query(b"STB?\r", b"\r") == b"STB85\r"


def test_arc_lamp_off_stops_the_lamp(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.source.open_shutter()
    arc.source.lamp_off()
    assert not arc.world.lamp.on and not arc.world.lamp.shutter_open
    status = arc.source.status()
    assert not status.lamp_on and not status.warm and status.output == 0.0


def test_arc_lamp_fault_is_reported_and_stops_the_warm_up_wait(make_arc):
    arc = make_arc(1000.0)
    arc.source.lamp_on()
    arc.world.lamp.inject_fault()
    status = arc.source.status()
    assert status.fault and not status.warm and not status.lamp_on
    with pytest.raises(DeviceFault):
        arc.source.wait_until_warm(timeout_s=1.0, poll_s=0.002)
    with pytest.raises(DeviceFault, match="lamp fault"):
        arc.source.lamp_on()


def test_arc_start_refused_by_a_faulty_supply_raises_its_esr(make_arc):
    arc = make_arc()
    arc.world.lamp.inject_fault()
    with pytest.raises(Oriel69907Error) as info:
        arc.supply.start()  # the driver alone, without the source's check
    assert info.value.status.execution_error and not arc.world.lamp.on


def test_arc_open_interlock_is_a_fault_and_nothing_is_struck(make_arc):
    arc = make_arc()
    arc.world.lamp.interlock_open = True
    assert arc.source.status().fault
    with pytest.raises(DeviceFault, match="interlock"):
        arc.source.lamp_on()
    assert not arc.world.lamp.on
    assert b"START\r" not in tx(arc.sent)


def test_arc_lamp_interlock_opening_while_lit_is_a_fault(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.world.lamp.interlock_open = True
    assert arc.source.status().fault
    with pytest.raises(DeviceFault):
        arc.source.wait_until_warm(timeout_s=1.0)


def test_shutter_interlock_keeps_the_shutter_closed(make_arc):
    arc = make_arc()
    arc.source.lamp_on()
    arc.shutter_sim.trip_interlock()
    with pytest.raises(DeviceFault, match="interlock"):
        arc.source.open_shutter()
    assert arc.world.irradiance() == 0.0 and not arc.source.status().shutter_open
    arc.shutter_sim.reset_interlock()
    arc.source.open_shutter()
    assert arc.world.irradiance() > 0.9


def test_arc_preset_above_the_supply_limit_raises_its_esr(make_arc):
    arc = make_arc()
    arc.lamp_sim.a_limit = 4.0
    with pytest.raises(Oriel69907Error) as info:
        arc.supply.set_current_preset_a(5.0)
    assert info.value.esr == 0x90  # execution error, plus the power-on bit of a fresh supply
    assert info.value.status.execution_error and arc.world.lamp.current_a == XENON.nominal_current_a


def test_arc_readings_follow_the_lamp(make_arc):
    arc = make_arc()
    assert arc.supply.event_status().power_on  # the power-on bit of a fresh supply, cleared by the read
    assert not arc.supply.event_status().power_on
    assert (arc.supply.amps(), arc.supply.volts(), arc.supply.watts()) == (0.0, 0.0, 0.0)
    arc.source.lamp_on()
    assert arc.supply.amps() == 5.0 and arc.supply.volts() == 19.0 and arc.supply.watts() == 95.0
    arc.supply.set_power_preset_w(80)
    assert arc.supply.power_preset_w() == 80.0
    assert arc.supply.lamp_hours() == 0.0
    assert arc.source.identify() == "supply: 69907; shutter: THORLABS SC10 (simulated) VERSION 1.0"


def test_unknown_command_sets_the_command_error_bit(serve):
    world = SimWorld()
    port = open_port(serve(Oriel69907Simulator(world)), timeout_s=TIMEOUT_S)
    assert port.query(b"ESR?\r", b"\r") == b"ESR80\r"
    assert port.query(b"LAMP ON\r", b"\r") == b"ESR20\r"
    assert port.query(b"A-PRESET=five\r", b"\r") == b"ESR20\r"


# -- link faults ----------------------------------------------------------------------------------------
def test_arc_no_reply_raises_device_timeout(make_arc):
    arc = make_arc()
    arc.lamp_sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout):
        arc.source.status()
    arc.lamp_sim.faults.no_reply = False
    arc.shutter_sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout):
        arc.source.open_shutter()


@pytest.mark.parametrize("fault", ["garble", "truncate"])
def test_arc_one_bad_reply_is_asked_again(make_arc, fault):
    arc = make_arc()
    arc.source.lamp_on()
    clean = (arc.supply.status_byte(), arc.supply.amps(), arc.shutter.is_closed())
    setattr(arc.lamp_sim.faults, fault, 1)
    setattr(arc.shutter_sim.faults, fault, 1)
    assert arc.supply.status_byte() == clean[0]
    assert arc.supply.amps() == clean[1]
    assert arc.shutter.is_closed() == clean[2]


@pytest.mark.parametrize("query", ["status_byte", "event_status", "amps", "volts", "watts", "lamp_hours",
                                   "current_preset_a", "power_preset_w"])
def test_arc_persistently_garbled_replies_never_give_a_reading(make_arc, query):
    arc = make_arc()
    arc.source.lamp_on()
    arc.lamp_sim.faults.garble = 5
    with pytest.raises((ProtocolError, DeviceTimeout)):
        getattr(arc.supply, query)()


def test_arc_persistently_cut_replies_time_out_with_the_partial_reply(make_arc):
    arc = make_arc()
    arc.lamp_sim.faults.truncate = 5
    with pytest.raises(DeviceTimeout) as info:
        arc.supply.amps()
    assert info.value.received == b"0."


@pytest.mark.parametrize("query", ["enabled", "is_closed", "interlock_tripped", "mode", "identify"])
def test_shutter_persistently_garbled_replies_never_give_a_reading(make_arc, query):
    arc = make_arc()
    arc.shutter_sim.faults.garble = 5
    with pytest.raises((ProtocolError, DeviceTimeout)):
        getattr(arc.shutter, query)()


def test_arc_garbled_reply_to_a_command_raises_and_is_not_resent(make_arc):
    arc = make_arc()
    arc.lamp_sim.faults.garble = 1
    with pytest.raises(ProtocolError):
        arc.supply.start()
    assert tx(arc.sent).count(b"START\r") == 1


def test_arc_disconnect_raises_device_disconnected(make_arc):
    arc = make_arc()
    arc.lamp_sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        arc.source.status()
    arc.lamp_sim.faults.disconnected = False
    arc.shutter_sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        arc.source.close_shutter()


def test_opening_a_disconnected_simulator_raises_device_disconnected(serve):
    sim = Oriel69907Simulator(SimWorld())
    sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        open_port(serve(sim))


# -- limits ---------------------------------------------------------------------------------------------
def test_arc_out_of_range_current_is_refused_with_nothing_sent(make_arc):
    arc = make_arc()
    with pytest.raises(LimitError):
        arc.supply.set_current_preset_a(50.0)
    with pytest.raises(LimitError):
        ArcLampSource(arc.supply, arc.shutter, current_a=50.0)
    assert arc.sent == [] and arc.lamp_sim.commands == 0
    assert arc.world.lamp.current_a == XENON.nominal_current_a


# == LED: SCPI bench supply ===============================================================================
def test_led_warm_up_takes_simulated_time_at_a_small_time_scale(make_led):
    scale = 10.0
    led = make_led(scale)
    led.source.lamp_on()
    t0 = time.monotonic()
    assert not led.source.status().warm
    led.source.wait_until_warm(timeout_s=3.0, poll_s=0.002)
    assert time.monotonic() - t0 >= warm_time_s(LED) / scale * 0.8
    assert led.world.lamp.is_warm()


def test_led_warm_up_is_instant_at_time_scale_zero(make_led):
    led = make_led(0.0)
    t0 = time.monotonic()
    led.source.lamp_on()
    led.source.wait_until_warm(timeout_s=1.0, poll_s=0.5)
    assert time.monotonic() - t0 < 0.25
    status = led.source.status()
    assert status.lamp_on and status.warm and status.shutter_open and not status.fault
    assert status.output == pytest.approx(0.7) and status.output_unit == "A"


def test_led_output_is_the_shutter(make_led):
    led = make_led()
    assert led.world.irradiance() == 0.0
    led.source.open_shutter()
    led.source.wait_until_warm(timeout_s=1.0)
    assert led.world.irradiance() == pytest.approx(1.0, abs=0.02)
    led.source.close_shutter()
    assert led.world.irradiance() == 0.0 and not led.world.lamp.on
    assert not led.source.status().shutter_open


def test_led_standby_turns_the_output_off(make_led):
    led = make_led()
    led.source.lamp_on()
    led.source.standby()
    status = led.source.status()
    assert not status.lamp_on and not status.shutter_open and status.output == 0.0
    assert led.world.irradiance() == 0.0 and not led.sim.output


def test_led_current_sets_the_output(make_led):
    led = make_led(current_a=0.35)
    led.source.lamp_on()
    led.source.wait_until_warm(timeout_s=1.0)
    assert led.supply.current_setpoint_a() == pytest.approx(0.35)
    assert led.supply.measure_voltage_v() == pytest.approx(2.9 + 0.35)
    assert led.world.irradiance() == pytest.approx(0.5, abs=0.01)


def test_led_failure_is_a_fault_and_stops_the_warm_up_wait(make_led):
    led = make_led(1.0)
    led.source.lamp_on()
    led.world.lamp.inject_fault()  # the LED string opens: no current, voltage at compliance
    status = led.source.status()
    assert status.fault and not status.warm and status.output == 0.0
    assert led.supply.measure_voltage_v() == pytest.approx(6.0)
    with pytest.raises(DeviceFault):
        led.source.wait_until_warm(timeout_s=1.0, poll_s=0.002)


def test_led_interlock_refuses_the_output(make_led):
    led = make_led()
    led.world.lamp.interlock_open = True
    with pytest.raises(ScpiError) as info:
        led.source.lamp_on()
    assert info.value.errors == [(-221, "Settings conflict")]
    assert led.world.irradiance() == 0.0 and not led.source.status().lamp_on


def test_led_bad_command_goes_to_the_error_queue(make_led):
    led = make_led()
    led.supply.port.write(b"OUTP:BLINK ON\n")
    led.supply.port.write(b"CURR 9\n")
    with pytest.raises(ScpiError) as info:
        led.supply.check_errors()
    assert info.value.errors == [(-113, "Undefined header"), (-222, "Data out of range")]
    led.supply.check_errors()  # read empty


def test_led_supply_answering_cr_lf(make_led):
    led = make_led(out_terminator=b"\r\n")
    led.source.lamp_on()
    assert led.source.status().lamp_on
    assert led.supply.identify() == "SUNBENCH,SCPI-SUPPLY-SIM,0,1.0"
    led.supply.remote()


@pytest.mark.parametrize("fault", ["garble", "truncate"])
def test_led_one_bad_reply_is_asked_again(make_led, fault):
    led = make_led()
    led.source.lamp_on()
    clean = (led.supply.output_enabled(), led.supply.measure_current_a())
    setattr(led.sim.faults, fault, 1)
    assert led.supply.output_enabled() == clean[0]
    setattr(led.sim.faults, fault, 1)
    assert led.supply.measure_current_a() == clean[1]


@pytest.mark.parametrize("query", ["output_enabled", "measure_current_a", "measure_voltage_v", "current_setpoint_a",
                                   "next_error", "identify"])
def test_led_persistently_garbled_replies_never_give_a_reading(make_led, query):
    led = make_led()
    led.source.lamp_on()
    led.sim.faults.garble = 5
    with pytest.raises((ProtocolError, DeviceTimeout)):
        getattr(led.supply, query)()


def test_led_no_reply_and_disconnect(make_led):
    led = make_led()
    led.sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout):
        led.source.status()
    led.sim.faults.clear()
    led.sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        led.source.lamp_on()


def test_led_out_of_range_current_is_refused_with_nothing_sent(make_led):
    led = make_led()
    with pytest.raises(LimitError):
        LedSource(led.supply, 5.0)
    with pytest.raises(LimitError):
        LedSource(led.supply, 0.5, voltage_v=50.0)
    with pytest.raises(LimitError):
        led.supply.set_current_a(5.0)
    assert led.sent == [] and led.sim.commands == 0


# == the SCPI supply's parser and status model (SCPI-99, IEEE 488.2) =======================================
@pytest.fixture
def scpi(serve):
    """A fresh simulated supply on a sim:// port; ``ask(text)`` sends one program message, returns its answer."""
    world = SimWorld(clock=SimClock(0.0), lamp_spec=LED)
    sim = ScpiSupplySimulator(world)
    port = open_port(serve(sim), timeout_s=TIMEOUT_S)

    def ask(text: str) -> str:
        if "?" not in text:
            port.write(text.encode() + b"\n")
            return ""
        return port.query(text.encode() + b"\n", b"\n")[:-1].decode()

    ask.sim, ask.world = sim, world
    return ask


def test_scpi_compounds_follow_the_root_and_path_rules(scpi):
    scpi("INST:NSEL 1;:VOLT 5;:CURR 0.5")
    assert scpi("VOLT?;CURR?;:INST:NSEL?") == "+5.00000000E+00;+5.00000000E-01;1"
    scpi("SOUR:VOLT 4;CURR 0.25")  # CURR is SOUR:CURR
    assert scpi("SOUR:VOLT?;CURR?") == "+4.00000000E+00;+2.50000000E-01"
    scpi("INST:NSEL 1;VOLT 3")  # VOLT is INST:VOLT: undefined, never a silent loss
    assert scpi("VOLT?") == "+4.00000000E+00"
    assert scpi("SYST:ERR?") == '-113,"Undefined header"'
    assert scpi("MEAS:VOLT?;CURR?") == "+0.00000000E+00;+0.00000000E+00"  # MEAS:CURR?, output off


def test_scpi_optional_nodes_long_and_short_forms(scpi):
    scpi("source:voltage:level:immediate:amplitude 4.5")
    scpi(":SOURce:CURRent:LEVel 300mA")
    scpi("OUTPut:STATe ON")
    assert scpi("VOLTage:LEVel?;:CURR:IMM:AMPL?;:OUTP:STAT?") == "+4.50000000E+00;+3.00000000E-01;1"
    assert scpi("MEASure:SCALar:CURRent:DC?;:MEAS:VOLT?") == "+3.00000000E-01;+3.20000000E+00"
    assert scpi("SYSTem:ERRor:NEXT?") == '0,"No error"'


def test_scpi_common_commands(scpi):
    assert scpi("*IDN?") == "SUNBENCH,SCPI-SUPPLY-SIM,0,1.0"
    assert scpi("*ESR?;*ESR?") == "128;0"  # power-on bit, cleared by the read
    assert scpi("*OPC?;*OPT?;*TST?;:SYST:VERS?") == "1;0;0;1999.0"
    scpi("*OPC")
    assert scpi("*ESR?") == "1"
    scpi("VOLT 1;*RST")
    assert scpi("VOLT?;CURR?;OUTP?;:INST?") == "+0.00000000E+00;+5.15000000E+00;0;P6V"
    scpi("*ESE 48;*SRE 32")
    assert scpi("*ESE?;*SRE?;*STB?") == "48;32;16"  # MAV: two answers are pending
    scpi("BOGUS")
    assert scpi("*STB?") == str(0x04 | 0x20 | 0x40)  # error queue, ESB (CME enabled), MSS (ESB enabled)
    assert scpi("*IDN?;*STB?").endswith(";" + str(0x04 | 0x10 | 0x20 | 0x40))  # and MAV: an answer is pending
    scpi("*CLS")
    assert scpi("*STB?;*ESR?;:SYST:ERR?") == '0;0;0,"No error"'
    assert scpi("*ESE?") == "48"  # *CLS keeps the enables


@pytest.mark.parametrize("command, code, bit", [
    ("VOLT 99", -222, 0x10), ("FOO:BAR", -113, 0x20), ("VOLT abc", -104, 0x20), ("VOLT: 5", -102, 0x20),
    ("VOLT", -109, 0x20), ("VOLT 1,2", -108, 0x20), ("CURR 1 V", -131, 0x20), ("OUTP MAYBE", -224, 0x10),
    ("INST P99V", -224, 0x10), ("INST:NSEL 4", -222, 0x10), ("SYST:VERS", -113, 0x20), ("MEAS:VOLT 1", -113, 0x20),
    ("*FOO", -113, 0x20), ("VOLT (1", -102, 0x20), ("*IDN? 1", -108, 0x20),
])
def test_scpi_every_error_is_queued_and_sets_its_event_bit(scpi, command, code, bit):
    scpi("*CLS")
    before = (scpi.sim.voltages[:], scpi.sim.currents[:], scpi.sim.states[:], scpi.sim.selected)
    if "?" in command:
        scpi.sim.receive(command.encode() + b"\n")
    else:
        scpi(command)
    error, esr = scpi("SYST:ERR?;*ESR?").split(";")
    assert int(error.split(",")[0]) == code and int(esr) == bit
    assert (scpi.sim.voltages, scpi.sim.currents, scpi.sim.states, scpi.sim.selected) == before


def test_scpi_error_queue_order_and_overflow(scpi):
    scpi("VOLT 99;FOO")
    assert scpi("SYST:ERR:COUN?") == "2"
    assert scpi("SYST:ERR?;ERR?;ERR?") == '-222,"Data out of range";-113,"Undefined header";0,"No error"'
    for _ in range(25):
        scpi("FOO")
    errors = [scpi("SYST:ERR?") for _ in range(21)]
    assert errors[:19] == ['-113,"Undefined header"'] * 19
    assert errors[19:] == ['-350,"Queue overflow"', '0,"No error"']


def test_scpi_outputs_are_selected_and_switched_alone_with_a_channel_list(scpi):
    scpi("INST P25V;:VOLT 12;CURR 0.1;:APPL N25V,-5,0.2")
    assert scpi("INST?;:INST:NSEL?;:VOLT?;:APPL? N25V") == 'P25V;2;+1.20000000E+01;"-5.000000,0.200000"'
    assert scpi("VOLT? MAX;VOLT? MIN;:INST:NSEL 3;:VOLT? MIN") == "+2.57500000E+01;+0.00000000E+00;-2.57500000E+01"
    scpi("OUTP ON,(@2)")
    assert scpi("OUTP? (@1:3);:MEAS:VOLT? P25V;:MEAS:VOLT? (@1)") == "0,1,0;+1.20000000E+01;+0.00000000E+00"
    assert not scpi.world.lamp.on  # output 1, the LED, stays off
    scpi("OUTP:TRAC ON;:INST:NSEL 2;:VOLT 7")
    assert scpi("OUTP:TRAC?;:INST N25V;:VOLT?") == "1;-7.00000000E+00"
    scpi("OUTP ON")  # no list: every output
    assert scpi("OUTP? (@1,2,3)") == "1,1,1" and scpi.world.lamp.on


def test_scpi_led_below_its_forward_voltage_draws_what_the_voltage_allows(scpi):
    scpi("APPL P6V,3.2,0.7;:OUTP ON")  # 3.2 V allows 0.3 A through 2.9 V + 1 V/A
    assert scpi("MEAS:CURR?;VOLT?") == "+3.00000000E-01;+3.20000000E+00"
    assert scpi.world.lamp.current_a == pytest.approx(0.3)
    scpi("VOLT 6")
    assert scpi("MEAS:CURR?;VOLT?") == "+7.00000000E-01;+3.60000000E+00" and scpi.world.lamp.current_a == 0.7


# == the SC10's full keyword set and its timed modes =======================================================
@pytest.fixture
def sc10(serve):
    """A fresh simulated SC10 on a sim:// port at time scale 0 (time moves only when the test moves it);
    ``ask(command)`` returns the value line, or None for a command answered with the echo and prompt only."""
    world = SimWorld(clock=SimClock(0.0))
    sim = ThorlabsSC10Simulator(world)
    port = open_port(serve(sim), timeout_s=TIMEOUT_S)

    def ask(command: str) -> str | None:
        reply = port.query(command.encode() + b"\r", b"> ").decode()
        lines = reply[:-2].split("\r")
        assert lines[0] == command and lines[-1] == ""
        return lines[1] if len(lines) == 3 else None

    ask.sim, ask.world = sim, world
    return ask


def test_sc10_answers_the_manuals_keyword_table(sc10):
    assert sc10("?").split() == ["?", "id?", "ens", "ens?", "rep=n", "rep?", "mode=n", "mode?", "trig=n", "trig?",
                                 "xto=n", "xto?", "open=n", "open?", "shut=n", "shut?", "closed?", "interlock?",
                                 "baud=n", "baud?", "save", "savp", "resp"]
    defaults = {"mode": "1", "rep": "1", "trig": "0", "xto": "0", "open": "100", "shut": "100", "baud": "0"}
    assert {name: sc10(name + "?") for name in defaults} == defaults
    for name, value in (("mode", "4"), ("rep", "99"), ("trig", "1"), ("xto", "1"), ("open", "999999"),
                        ("shut", "0"), ("baud", "1")):
        assert sc10(f"{name}={value}") is None and sc10(name + "?") == value
    for bad in ("mode=0", "mode=6", "rep=0", "rep=100", "trig=2", "xto=x", "open=1000000", "shut=-1", "baud=2",
                "mode="):
        assert sc10(bad) == "Command error CMD_ARG_INVALID"
    for unknown in ("ens=1", "ens=0", "open", "foo?", "MODE?", "default?"):
        assert sc10(unknown) == "Command error CMD_NOT_DEFINED"
    assert sc10("mode?") == "4" and sc10("ens?") == "0"  # the bad ones changed nothing


def test_sc10_stores_loads_and_restores_its_settings(sc10):
    sc10("open=250")
    sc10("xto=1")
    assert sc10("savp") is None and sc10("save") is None
    sc10("open=400")
    sc10("xto=0")
    assert sc10("resp") is None
    assert sc10("open?") == "250" and sc10("xto?") == "0"  # resp loads the configuration, not the mode info
    assert sc10.sim.stored["xto"] == 1
    assert sc10("default") is None
    assert sc10("open?") == "100" and sc10("xto?") == "0" and sc10.sim.stored["open"] == 250


def test_sc10_instrumentkit_readings_are_options(sc10):
    sc10.sim.accept_ens_value, sc10.sim.action_reply = True, "1"
    assert sc10("ens=1") is None and sc10("closed?") == "0" and sc10.world.lamp.shutter_open
    assert sc10("ens=1") is None and sc10("ens?") == "1"  # a set, not a toggle
    assert sc10("ens=0") is None and sc10("closed?") == "1"
    assert sc10("ens=2") == "Command error CMD_ARG_INVALID"
    assert [sc10(c) for c in ("savp", "save", "resp", "default")] == ["1", "1", "1", "1"]


def test_sc10_auto_mode_cycles_while_enabled(sc10):
    clock, lamp = sc10.world.clock, sc10.world.lamp
    for command in ("mode=2", "open=50", "shut=150", "ens"):
        sc10(command)
    seen = []
    for t in (0.01, 0.049, 0.051, 0.199, 0.201, 0.26, 0.41):
        clock.advance_to(t)
        seen.append(sc10("closed?"))
        assert lamp.shutter_open == (seen[-1] == "0")
    assert seen == ["0", "0", "1", "1", "0", "1", "0"]
    sc10("ens")
    assert sc10("closed?") == "1" and sc10("ens?") == "0"


def test_sc10_single_and_repeat_modes_end_by_themselves(sc10):
    clock = sc10.world.clock
    for command in ("mode=3", "open=100", "shut=100", "ens"):
        sc10(command)
    assert sc10("closed?") == "0"
    clock.advance(0.15)
    assert sc10("closed?") == "1" and sc10("ens?") == "1"
    clock.advance(0.1)
    assert sc10("ens?") == "0"  # one shot: the controller disables itself
    for command in ("mode=4", "rep=3", "ens"):
        sc10(command)
    opened = 0
    for _ in range(12):
        was_open = sc10("closed?") == "0"
        clock.advance(0.05)
        if was_open and sc10("closed?") == "1":
            opened += 1
    assert opened == 3 and sc10("ens?") == "0"


def test_sc10_polling_keeps_the_world_in_step(sc10):
    """Between commands the world's shutter follows the timing when the port is polled (a TCP or pty link
    polls every few milliseconds)."""
    clock, lamp = sc10.world.clock, sc10.world.lamp
    for command in ("mode=2", "open=100", "shut=100", "ens"):
        sc10(command)
    clock.advance(0.15)
    assert lamp.shutter_open
    sc10.sim.poll()
    assert not lamp.shutter_open


def test_sc10_external_trigger_and_gate(sc10):
    clock, sim = sc10.world.clock, sc10.sim
    for command in ("mode=3", "trig=1", "open=100", "ens"):
        sc10(command)
    assert sc10("closed?") == "1" and sc10("ens?") == "1"  # armed
    sim.external_trigger()
    assert sc10("closed?") == "0"
    clock.advance(0.5)
    assert sc10("closed?") == "1" and sc10("ens?") == "1"  # still armed for the next pulse
    sc10("mode=5")  # a new mode disables the controller
    assert sc10("ens?") == "0"
    sc10("ens")
    sim.set_gate(True)
    assert sc10("closed?") == "0"
    sim.set_gate(False)
    assert sc10("closed?") == "1"
