"""Other people's SCPI clients against the simulated bench supply of the LED sun simulator
(research/peer-clients.md): PyVISA with its pure-Python backend pyvisa-py, and pymeasure's ``KeysightE3631A``
on the same resource, ``TCPIP0::127.0.0.1::PORT::SOCKET`` (the simulator served in this process by
``SimBench.serve``), in a venv of their own (scripts/setup-peers.sh).

Each session connects, reads, switches the LED on and reads its setpoints and measurements back; the test
checks that the simulated LED itself lit at the current the client set. PyVISA also sends what the research
note found missing — ``;`` compounds with the root rule, ``*RST *OPC? *ESR? *STB? *OPT? SYST:VERS?`` — and
reads the error queue after commands that must fail. pymeasure sends ``INST:NSEL n;:VOLT 5`` compounds for
every channel property and ``OUTPut 1, (@n)`` for a channel's output.

No client may wait on a timeout: in this process every program message holding a query was answered within
the same write (:class:`QueryWatch`), and in the client every call is timed against a small fraction of its
timeout.
"""

from __future__ import annotations

import re

import pytest
from peers.peer import host_port, run_peer, served, slow_calls

from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.lamp import LED

VISA_TIMEOUT_MS = 2000
CALL_LIMIT_S = 0.25  # the longest one call may take: an eighth of the client's timeout


class QueryWatch:
    """Wraps a line simulator's ``receive`` and notes every program message with a query (a ``?`` outside
    quotes) whose answer was not in the reply to the write that completed it."""

    def __init__(self, sim):
        self.queries = 0
        self.unanswered: list[str] = []
        self._buf = b""
        self._receive = sim.receive
        sim.receive = self.receive

    def receive(self, data: bytes) -> bytes:
        reply = self._receive(data)
        self._buf += data
        *lines, self._buf = self._buf.split(b"\n")
        asked = [line for line in lines if b"?" in re.sub(rb'"[^"]*"', b"", line)]
        self.queries += len(asked)
        if asked and reply.count(b"\n") < len(asked):
            self.unanswered += [line.decode("ascii", "replace") for line in asked]
        return reply


@pytest.fixture
def bench():
    """The simulated bench with the LED source, in instant mode (the LED is warm when looked at)."""
    return SimBench(SimBenchConfig(source="led", time_scale=0.0))


def _session(bench, script: str):
    """Run a client `script` against the bench's LED supply over TCP: (simulator, its QueryWatch, the script's
    output)."""
    sim = bench.devices["led"]
    watch = QueryWatch(sim)
    with served(bench) as server:
        host, port = host_port(server.urls["led"])
        out = run_peer("pyvisa", script, resource=f"TCPIP0::{host}::{port}::SOCKET", timeout_ms=VISA_TIMEOUT_MS)
    return sim, watch, out


PYVISA_SESSION = """
import time
import pyvisa


out = {}
rm = pyvisa.ResourceManager("@py")
inst = timed("open", rm.open_resource, ARGS["resource"], read_termination="\\n", write_termination="\\n",
             timeout=ARGS["timeout_ms"])
ask = lambda text: timed("query", inst.query, text)
tell = lambda text: timed("write", inst.write, text)

out["idn"] = ask("*IDN?")
out["esr_power_on"] = ask("*ESR?")
out["version"] = ask("SYST:VERS?")
out["opt"] = ask("*OPT?")
out["rst"] = ask("*RST;*CLS;*OPC?")
out["after_rst"] = ask("OUTP?;:VOLT?;:CURR?")
# setpoints in compounds, the root rule, long forms and optional nodes
tell("INST:NSEL 1;:VOLT 5;:CURR 0.5")
out["setpoints"] = ask("VOLT?;CURR?")
tell("SOURce:VOLTage:LEVel:IMMediate:AMPLitude 4.4;:sour:curr:lev 300mA")
out["long_forms"] = ask("VOLTage?;:CURRent:LEVel:IMMediate:AMPLitude?")
tell("SOUR:VOLT 4.5;CURR 350mA")  # CURR is relative to SOUR:
out["relative"] = ask(":SOUR:VOLT?;CURR?")
out["stb_clean"] = ask("*STB?")
# the error queue: a relative header outside its path, an undefined one, a value out of range
tell("INST:NSEL 1;VOLT 5")
tell("FOO:BAR 1")
tell("CURR 9")
out["stb_errors"] = ask("*STB?")
out["errors"] = [ask("SYST:ERR?") for _ in range(4)]
out["esr_errors"] = ask("*ESR?")
# switch the LED on and read it back
tell("OUTP ON")
out["output"] = ask("OUTP?")
out["measured"] = ask("MEAS:CURR?;VOLT?")
out["opc"] = ask("*OPC?")
inst.close()
out["calls"] = calls
print(json.dumps(out))
"""


def test_pyvisa_py_over_a_socket(bench):
    sim, watch, out = _session(bench, PYVISA_SESSION)

    assert out["idn"] == "SUNBENCH,SCPI-SUPPLY-SIM,0,1.0"
    assert out["esr_power_on"] == "128" and out["version"] == "1999.0" and out["opt"] == "0"
    assert out["rst"] == "1" and out["after_rst"] == "0;+0.00000000E+00;+5.15000000E+00"
    assert out["setpoints"] == "+5.00000000E+00;+5.00000000E-01"
    assert out["long_forms"] == "+4.40000000E+00;+3.00000000E-01"
    assert out["relative"] == "+4.50000000E+00;+3.50000000E-01"
    assert out["stb_clean"] == "0"
    assert out["stb_errors"] == "4"  # bit 2: the error queue is not empty
    assert out["errors"] == ['-113,"Undefined header"', '-113,"Undefined header"', '-222,"Data out of range"',
                             '0,"No error"']
    assert int(out["esr_errors"]) == 0x20 | 0x10  # command error (-113), execution error (-222)
    # the LED is on at the current the client set, and the simulated light is there
    assert out["output"] == "1"
    assert out["measured"] == "+3.50000000E-01;+3.25000000E+00"  # 2.9 V + 1 V/A
    assert bench.world.lamp.on and bench.world.lamp.current_a == pytest.approx(0.35)
    assert bench.world.irradiance() == pytest.approx(0.35 / LED.nominal_current_a, rel=0.01)

    # nothing waited on a timeout
    assert watch.queries >= 15 and not watch.unanswered, watch.unanswered
    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"


PYMEASURE_SESSION = """
import time
from pymeasure.instruments.keysight import KeysightE3631A


out = {}
psu = timed("connect", KeysightE3631A, ARGS["resource"], read_termination="\\n", write_termination="\\n",
            timeout=ARGS["timeout_ms"], visa_library="@py")
out["id"] = timed("id", lambda: psu.id)
ch1, ch2, ch3 = psu.ch_1, psu.ch_2, psu.ch_3
timed("set", setattr, ch1, "voltage_setpoint", 4.5)
timed("set", setattr, ch1, "current_limit", 0.35)
timed("set", setattr, ch2, "voltage_setpoint", 12.0)
timed("set", setattr, ch2, "current_limit", 0.1)
timed("set", setattr, ch3, "voltage_setpoint", -5.0)
timed("set", setattr, ch1, "output_enabled", True)
out["ch1"] = [timed("get", getattr, ch1, name) for name in
              ("voltage_setpoint", "current_limit", "output_enabled", "voltage", "current")]
out["ch2"] = [timed("get", getattr, ch2, name) for name in ("voltage_setpoint", "current_limit", "output_enabled")]
out["ch3"] = timed("get", getattr, ch3, "voltage_setpoint")
timed("set", setattr, psu, "tracking_enabled", True)
out["tracking"] = timed("get", getattr, psu, "tracking_enabled")
out["errors"] = [list(e) for e in timed("check_errors", psu.check_errors)]
psu.adapter.close()
out["calls"] = calls
print(json.dumps(out))
"""


def test_pymeasure_keysight_e3631a(bench):
    sim, watch, out = _session(bench, PYMEASURE_SESSION)

    assert out["id"] == "SUNBENCH,SCPI-SUPPLY-SIM,0,1.0"
    assert out["ch1"] == [4.5, 0.35, True, pytest.approx(3.25), pytest.approx(0.35)]
    assert out["ch2"] == [12.0, 0.1, False]  # "OUTPut 1, (@1)" switched output 1 only
    assert out["ch3"] == -5.0 and out["tracking"] is True
    assert out["errors"] == []
    # the client's setpoints reached the supply, and the LED on output 1 shines at 0.35 A
    assert sim.voltages == [4.5, 12.0, -12.0] and sim.currents[:2] == [0.35, 0.1]  # N25V tracks P25V
    assert sim.states == [True, False, False]
    assert bench.world.lamp.on and bench.world.lamp.current_a == pytest.approx(0.35)
    assert bench.world.irradiance() == pytest.approx(0.35 / LED.nominal_current_a, rel=0.01)

    assert watch.queries >= 10 and not watch.unanswered, watch.unanswered
    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"
