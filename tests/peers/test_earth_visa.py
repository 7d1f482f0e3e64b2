"""PyVISA (with its pure-Python backend pyvisa-py, in its own venv: scripts/setup-peers.sh) against the simulated IR
Earth simulator's controller of the horizon bench, ``TCPIP0::127.0.0.1::PORT::SOCKET`` with LF terminations — the
resource `sunbench sim` prints for it. The session heats the disc, sets the iris, opens the cover, reads everything
back and provokes the documented errors; the test checks the simulated instrument did what the client asked, and that
no query waited on the client's timeout (every program message with a query was answered within its own write)."""

from __future__ import annotations

import pytest
from peers.peer import host_port, run_peer, served, slow_calls
from peers.test_scpi import QueryWatch

from drivers.sim.bench import SimBench, SimBenchConfig

VISA_TIMEOUT_MS = 2000
CALL_LIMIT_S = 0.25  # an eighth of the client's timeout

SESSION = """
import time
import pyvisa

out = {}
rm = pyvisa.ResourceManager("@py")
inst = timed("open", rm.open_resource, ARGS["resource"], read_termination="\\n", write_termination="\\n",
             timeout=ARGS["timeout_ms"])
ask = lambda text: timed("query", inst.query, text)
tell = lambda text: timed("write", inst.write, text)

out["idn"] = ask("*IDN?")
out["ranges"] = [ask("HEAT:RANG?"), ask("IRIS:LIM?")]
tell("HEATer:TEMPerature 300;:HEAT ON")
out["heater"] = [ask("HEAT?"), ask("HEAT:TEMP?")]
tell("iris:radius 66.5")
out["moving"] = ask("IRIS:MOV?")
out["iris"] = [ask("IRIS:TARG?"), ask("IRIS?")]
tell("COV OPEN")
out["cover"] = ask("COV?")
out["disc"] = ask("MEAS:TEMP?")
out["status"] = ask("STAT?")
tell("IRIS 120")       # outside its limits
tell("FOO:BAR 1")      # no such header
tell("HEAT:TEMP")      # a set without its value
out["errors"] = [ask("SYST:ERR?") for _ in range(4)]
tell("*RST")
out["after_rst"] = [ask("HEAT?"), ask("COV?"), ask("IRIS?")]
inst.close()
out["calls"] = calls
print(json.dumps(out))
"""


def test_pyvisa_drives_the_earth_simulator():
    bench = SimBench(SimBenchConfig(family="horizon", time_scale=0.0))
    sim = bench.devices["earth"]
    watch = QueryWatch(sim)
    with served(bench) as server:
        host, port = host_port(server.urls["earth"])
        out = run_peer("pyvisa", SESSION, resource=f"TCPIP0::{host}::{port}::SOCKET", timeout_ms=VISA_TIMEOUT_MS)

    assert out["idn"].startswith("SUNBENCH,EARTH-SIM,")
    low_k, high_k = (float(v) for v in out["ranges"][0].split(","))
    low_deg, high_deg = (float(v) for v in out["ranges"][1].split(","))
    assert low_k < 300 < high_k and low_deg < 66.5 < high_deg < 120
    assert out["heater"][0] == "1" and float(out["heater"][1]) == 300.0
    assert float(out["iris"][0]) == 66.5 and float(out["iris"][1]) == pytest.approx(66.5, abs=0.01)
    assert out["cover"] == "OPEN" and float(out["disc"]) == pytest.approx(300.0, abs=1.0)  # instant mode: settled
    status = int(out["status"])
    assert status & 0x01 and status & 0x08 and not status & 0x04  # heater on, cover open, iris still
    codes = [int(e.split(",")[0]) for e in out["errors"]]
    assert codes == [-222, -113, -109, 0], out["errors"]
    assert out["after_rst"][:2] == ["0", "CLOSED"] and float(out["after_rst"][2]) == pytest.approx(66.5, abs=0.01)
    # what the client set is what the simulated instrument does: the horizon sensor sees this disc
    assert bench.earth.true_radius_deg() == pytest.approx(66.5, abs=0.05) and not bench.earth.cover_open()

    assert watch.queries >= 15 and not watch.unanswered, watch.unanswered
    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"
