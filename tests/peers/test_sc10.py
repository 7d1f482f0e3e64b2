"""Other people's Thorlabs SC10 client against the simulated shutter controller (research/peer-clients.md):
InstrumentKit's ``ik.thorlabs.SC10`` (0.6.0) over TCP (``SC10.open_tcpip``, the simulator served in this
process by ``SimBench.serve``), in a venv of its own (scripts/setup-peers.sh).

InstrumentKit 0.6.0 expects the prompt ``>``; its own upstream tests, and the controller as the simulator
answers, use ``"> "``, so the session sets ``sc.prompt = "> "``.

Two sessions:

* against the simulator as the SC10 manual describes it: the session reads every property, sets every
  setting and reads it back, opens and closes the shutter with the manual's toggle ``ens`` (sent with
  ``sendcmd``) and switches the mode; finally it tries InstrumentKit's ``enable = False``, which sends
  ``ens=0`` — not in the manual, so the controller answers ``Command error CMD_NOT_DEFINED`` where
  InstrumentKit waits for the prompt: InstrumentKit raises, nothing hangs and the shutter stays open;
* against the simulator with InstrumentKit's two readings as options (``accept_ens_value``,
  ``action_reply``): ``enable = True/False`` opens and closes, and ``save()``, ``save_mode()``, ``restore()``
  and ``default()`` read their answer line.

The test checks the simulated shutter itself, and that no call waited on a timeout (the session's socket
timeout is 2 s; every call is timed against a small fraction of it).
"""

from __future__ import annotations

from peers.peer import host_port, run_peer, served, slow_calls

from drivers.sim.bench import SimBench, SimBenchConfig

SOCKET_TIMEOUT_S = 2.0
CALL_LIMIT_S = 0.25

PREAMBLE = """
import time
import instruments as ik

get = lambda sc, name: timed(name, getattr, sc, name)
put = lambda sc, name, value: timed(name + "=", setattr, sc, name, value)

sc = timed("connect", ik.thorlabs.SC10.open_tcpip, ARGS["host"], ARGS["port"])
sc.prompt = "> "
# InstrumentKit's timeout setter hands socket.settimeout a 0-d numpy array, which it refuses: set it directly
sc._file._conn.settimeout(ARGS["socket_timeout_s"])
out = {}
"""

MANUAL_SESSION = PREAMBLE + """
out["name"] = get(sc, "name")
out["read"] = {name: str(get(sc, name)) for name in ("enable", "closed", "interlock", "repeat", "trigger",
                                                     "out_trigger", "open_time", "shut_time", "baud_rate")}
out["mode"] = int(get(sc, "mode"))
for name, value in (("repeat", 7), ("trigger", 1), ("out_trigger", 1), ("open_time", 250), ("shut_time", 750),
                    ("baud_rate", 115200), ("trigger", 0)):
    put(sc, name, value)
out["set"] = {name: str(get(sc, name)) for name in ("repeat", "trigger", "out_trigger", "open_time", "shut_time",
                                                    "baud_rate")}
put(sc, "mode", sc.Mode.auto)
out["mode_auto"] = int(get(sc, "mode"))
put(sc, "mode", sc.Mode.manual)
out["mode_manual"] = int(get(sc, "mode"))
timed("ens", sc.sendcmd, "ens")  # the manual's toggle: opens
out["opened"] = [get(sc, "enable"), get(sc, "closed")]
timed("ens", sc.sendcmd, "ens")  # and closes
out["closed"] = [get(sc, "enable"), get(sc, "closed")]
timed("ens", sc.sendcmd, "ens")  # open again, and leave it open
out["open_again"] = get(sc, "closed")
for command in ("savp", "save", "resp"):  # as commands: echo and prompt
    timed(command, sc.sendcmd, command)
t0 = time.monotonic()
try:
    sc.enable = False  # sends ens=0, which the manual does not have
    out["ens_value"] = "accepted"
except Exception as exc:
    out["ens_value"] = type(exc).__name__
calls["ens=0"] = time.monotonic() - t0
out["calls"] = calls
print(json.dumps(out))
"""

CLIENT_SESSION = PREAMBLE + """
put(sc, "enable", True)
out["enabled"] = [get(sc, "enable"), get(sc, "closed")]
put(sc, "enable", False)
out["disabled"] = [get(sc, "enable"), get(sc, "closed")]
put(sc, "open_time", 40)
out["save"] = timed("save", sc.save)
put(sc, "open_time", 60)
out["restore"] = timed("restore", sc.restore)
out["restored"] = str(get(sc, "open_time"))
out["save_mode"] = timed("save_mode", sc.save_mode)
out["default"] = timed("default", sc.default)
out["defaulted"] = str(get(sc, "open_time"))
put(sc, "enable", True)
out["calls"] = calls
print(json.dumps(out))
"""


def _run(bench, script: str) -> dict:
    """Run an InstrumentKit `script` against the bench's SC10 over TCP."""
    with served(bench) as server:
        host, port = host_port(server.urls["shutter"])
        return run_peer("instrumentkit", script, host=host, port=port, socket_timeout_s=SOCKET_TIMEOUT_S)


def test_instrumentkit_sc10_as_the_manual_says():
    bench = SimBench(SimBenchConfig(source="xenon", time_scale=0.0))
    sim, lamp = bench.devices["shutter"], bench.world.lamp
    states = []
    handle = sim.handle_line

    def watch(line: bytes) -> bytes:  # the shutter as each command leaves it
        reply = handle(line)
        states.append((line.decode(), lamp.shutter_open))
        return reply

    sim.handle_line = watch
    out = _run(bench, MANUAL_SESSION)

    assert out["name"] == "THORLABS SC10 (simulated) VERSION 1.0"
    assert out["read"] == {"enable": "False", "closed": "True", "interlock": "False", "repeat": "1", "trigger": "0",
                           "out_trigger": "0", "open_time": "100.0 ms", "shut_time": "100.0 ms", "baud_rate": "9600"}
    assert out["set"] == {"repeat": "7", "trigger": "0", "out_trigger": "1", "open_time": "250.0 ms",
                          "shut_time": "750.0 ms", "baud_rate": "115200"}
    assert out["mode"] == 1 and out["mode_auto"] == 2 and out["mode_manual"] == 1  # SC10.Mode.manual, .auto
    # the toggle opens and closes the simulated shutter
    assert out["opened"] == [True, False] and out["closed"] == [False, True] and out["open_again"] is False
    toggles = [open_ for command, open_ in states if command == "ens"]
    assert toggles == [True, False, True]
    # the stored configuration and mode information (savp, save)
    assert sim.stored["rep"] == 7 and sim.stored["open"] == 250 and sim.stored["xto"] == 1
    assert sim.stored["baud"] == 1
    # ens=0 is refused loudly (InstrumentKit finds the error where it waits for the prompt), and changes nothing
    assert out["ens_value"] == "PromptError"
    assert states[-1] == ("ens=0", True) and lamp.shutter_open and sim.enabled

    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"


def test_instrumentkit_sc10_with_its_own_readings():
    bench = SimBench(SimBenchConfig(source="xenon", time_scale=0.0))
    sim, lamp = bench.devices["shutter"], bench.world.lamp
    sim.accept_ens_value, sim.action_reply = True, "1"
    out = _run(bench, CLIENT_SESSION)

    assert out["enabled"] == [True, False] and out["disabled"] == [False, True]
    assert [out["save"], out["restore"], out["save_mode"], out["default"]] == [1, 1, 1, 1]
    assert out["restored"] == "40.0 ms" and out["defaulted"] == "100.0 ms"
    assert lamp.shutter_open and sim.enabled  # the last `enable = True`

    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"
