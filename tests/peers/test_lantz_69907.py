"""Other people's Oriel 69907 client against the simulated arc-lamp supply (research/peer-clients.md):
lantz-drivers' ``Newport69907`` (0.5.2, on lantz-core 0.5.3) over a pty (drivers/sim/pty_bridge.py), through
PyVISA's pure-Python backend pyvisa-py, in a venv of its own (scripts/setup-peers.sh).

The published package does not import as it is: lantz-drivers still imports ``visa``, ``lantz.messagebased``
and ``from lantz import Feat, Action``, which lantz-core 0.5.3 has renamed to ``pyvisa``,
``lantz.core.messagebased`` and ``lantz.core``. The session puts the new modules under the old names and loads
``lantz/drivers/newport/newport69907.py`` by its path (the ``lantz.drivers.newport`` package imports every
Newport driver, some of which need more than lantz-core).

The session reads every feature, sets the presets and limits, strikes the lamp, lets ``P-LIM`` hold it back,
resets the supply (``RST``) and puts the lamp out; the test checks the simulated lamp itself. lantz decodes
the registers with ``>`` comparisons, so a register equal to one bit reads wrong (``ESR80`` lists "User
request", not "Power on"); the test compares the raw registers the session reads with ``query``.

No call may wait on a timeout (lantz's is 10 s): every call is timed against a small fraction of it.
"""

from __future__ import annotations

import pytest
from peers.peer import run_peer, slow_calls

from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.oriel69907 import amps_for_watts
from drivers.sim.pty_bridge import PtyBridge

CALL_LIMIT_S = 0.25

LANTZ_SESSION = """
import importlib.util, os, sys, time
import pyvisa
sys.modules["visa"] = pyvisa
import lantz, lantz.core, lantz.core.messagebased
sys.modules["lantz.messagebased"] = lantz.core.messagebased
lantz.Feat, lantz.Action = lantz.core.Feat, lantz.core.Action
import lantz.drivers
path = os.path.join(os.path.dirname(lantz.drivers.__file__), "newport", "newport69907.py")
spec = importlib.util.spec_from_file_location("newport69907", path)
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)

get = lambda inst, name: timed(name, getattr, inst, name)
put = lambda inst, name, value: timed(name + "=", setattr, inst, name, value)

out = {}
inst = module.Newport69907("ASRL" + ARGS["path"] + "::INSTR")
timed("initialize", inst.initialize)
try:
    out["esr_power_on"] = timed("raw", inst.query, "ESR?")
    out["read"] = {name: get(inst, name) for name in ("idn", "status", "error_status", "amps", "volts", "watts",
                                                       "lamp_hrs", "amp_preset", "power_preset", "amp_lim",
                                                       "power_lim")}
    put(inst, "amp_lim", 10.0)
    put(inst, "amp_preset", 4.5)
    put(inst, "power_lim", 98)
    put(inst, "power_preset", 95)
    out["set"] = [get(inst, name) for name in ("amp_lim", "amp_preset", "power_lim", "power_preset")]
    out["set_esr"] = timed("raw", inst.query, "ESR?")
    out["start"] = timed("start_lamp", inst.start_lamp)
    out["lit"] = [get(inst, "status"), get(inst, "amps"), get(inst, "volts"), get(inst, "watts")]
    out["stb_lit"] = timed("raw", inst.query, "STB?")
    put(inst, "power_lim", 80)  # below the lamp's 4.5 A x 18.6 V = 84 W: the supply holds it at 80 W
    out["limited"] = [get(inst, "status"), get(inst, "amps"), get(inst, "watts")]
    out["stb_limited"] = timed("raw", inst.query, "STB?")
    out["preset_over_limit"] = timed("raw", inst.query, "P-PRESET=0090")
    out["reset"] = timed("reset", inst.reset)
    out["after_reset"] = [get(inst, name) for name in ("amp_lim", "amp_preset", "power_lim", "power_preset",
                                                       "amps")]
    out["stop"] = timed("stop_lamp", inst.stop_lamp)
    out["stopped"] = [get(inst, "status"), get(inst, "amps")]
    out["unknown"] = timed("raw", inst.query, "LAMP ON")
finally:
    inst.finalize()
out["calls"] = calls
print(json.dumps(out))
"""


def test_lantz_newport69907_over_a_pty():
    bench = SimBench(SimBenchConfig(source="xenon", time_scale=0.0))
    sim, lamp = bench.devices["lamp"], bench.world.lamp
    seen = {}
    start = sim.handle_line

    def watch(line: bytes) -> bytes:  # the lamp as each command leaves it
        reply = start(line)
        seen[line.decode()] = (lamp.on, lamp.current_a)
        return reply

    sim.handle_line = watch
    with PtyBridge(sim) as bridge:
        out = run_peer("lantz", LANTZ_SESSION, path=bridge.path)

    read = out["read"]
    assert out["esr_power_on"] == "ESR80"  # the power-on bit, cleared by the read
    assert read["idn"] == "69907" and read["status"] == ["Current Mode", "Interlock"]  # STB01: interlock closed
    assert read["error_status"] == [] and [read["amps"], read["volts"], read["watts"]] == [0.0, 0.0, 0]
    assert read["lamp_hrs"] == "0"
    assert [read["amp_preset"], read["power_preset"], read["amp_lim"], read["power_lim"]] == [5.0, 75, 12.0, 100]

    assert out["set"] == [10.0, 4.5, 98, 95] and out["set_esr"] == "ESR00"
    assert seen["A-PRESET=4.5"] == (False, 4.5)  # the preset reached the lamp model before it was struck

    # the lamp strikes at the preset
    assert out["start"] == [] and seen["START"] == (True, 4.5)
    assert out["lit"] == [["Lamp on", "Current Mode", "Interlock"], 4.5, 19.0, 84]  # 15 V + 0.8 V/A
    assert out["stb_lit"] == "STB81"
    # P-LIM is enforced: the lamp is held at 80 W and the LIMIT bit is lit
    assert out["stb_limited"] == "STB83" and "Limit" in out["limited"][0]
    assert out["limited"][1:] == [pytest.approx(amps_for_watts(80), abs=0.05), 80]
    assert seen["P-LIM=0080"][1] == pytest.approx(amps_for_watts(80))
    assert out["preset_over_limit"] == "ESR10"  # a preset above the power limit: execution error
    # RST: factory presets and limits, no error; the lamp burns on at the factory preset
    assert out["reset"] == [] and seen["RST"] == (True, 5.0)
    assert out["after_reset"] == [12.0, 5.0, 100, 75, 5.0]
    assert out["stop"] == [] and out["stopped"] == [["Current Mode", "Interlock"], 0.0]
    assert not lamp.on and seen["STOP"][0] is False
    assert out["unknown"] == "ESR20"  # command error

    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"
