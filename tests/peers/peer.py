"""Running other people's client software against the simulators: each client lives in a virtual environment
of its own (.venv-peers/NAME, made by scripts/setup-peers.sh, so its pins never touch sunbench's), and a test
runs a short script in it as a subprocess. A client that is not installed fails its test with the command
that installs it; nothing is skipped."""

from __future__ import annotations

import json
import shutil
import subprocess
import textwrap
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
INSTALL = "bash scripts/setup-peers.sh"


def peer_python(name: str) -> Path:
    """The interpreter of the peer client `name`; fails the test, saying how to install it, when missing."""
    python = ROOT / ".venv-peers" / name / "bin" / "python"
    installed = ROOT / ".venv-peers" / name / ".installed"
    if not python.exists() or not installed.exists():
        raise AssertionError(f"the peer client {name!r} is not installed: run `{INSTALL}`")
    return python


#: What every peer script has: ``timed(name, call, *args, **kwargs)`` calls and records in ``calls[name]`` the
#: longest wall time [s] that call took, so a test can assert no client waited on a timeout.
_PRELUDE = """\
import json, time
calls = {}
def timed(name, call, *args, **kwargs):
    t0 = time.monotonic()
    value = call(*args, **kwargs)
    calls[name] = max(calls.get(name, 0.0), time.monotonic() - t0)
    return value
"""


def run_peer(name: str, script: str, *, timeout_s: float = 60.0, **values) -> dict:
    """Run `script` (dedented) with the peer's interpreter; `values` are given to it as the dict ``ARGS``, and
    ``timed`` and ``calls`` of the prelude (above) are defined.

    The script prints one JSON object on its last line; that object is returned. A non-zero exit or a
    timeout fails the test with the script's output.
    """
    code = _PRELUDE + f"ARGS = json.loads({json.dumps(json.dumps(values))})\n" + textwrap.dedent(script)
    result = subprocess.run([str(peer_python(name)), "-c", code], capture_output=True, text=True,
                            timeout=timeout_s, cwd=ROOT)
    if result.returncode != 0:
        raise AssertionError(f"peer {name} failed (exit {result.returncode}):\n{result.stdout}\n{result.stderr}")
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    if not lines:
        raise AssertionError(f"peer {name} printed nothing:\n{result.stderr}")
    return json.loads(lines[-1])


def indi_tool(tool: str) -> str:
    """The path of an INDI program (indiserver, indi_getprop …); fails the test, saying how to install it."""
    path = shutil.which(tool)
    if path is None:
        raise AssertionError(f"{tool} is not installed: run `{INSTALL}` (Debian's indi-bin)")
    return path


@contextmanager
def served(bench):
    """`bench` (a :class:`~drivers.sim.bench.SimBench`) served on free TCP ports of 127.0.0.1 for the block; the
    server is given (its ``urls``: role → ``socket://127.0.0.1:PORT``) and stopped at the end."""
    server = bench.serve(host="127.0.0.1", base_port=0)
    try:
        yield server
    finally:
        server.stop()


def host_port(url: str) -> tuple[str, int]:
    """Host and port of a ``socket://HOST:PORT`` URL."""
    host, port = url.removeprefix("socket://").rsplit(":", 1)
    return host, int(port)


def slow_calls(out: dict, limit_s: float, *, besides=()) -> dict[str, float]:
    """The calls a peer script timed (its ``calls``, see ``timed``) that took longer than `limit_s` [s], but
    those named in `besides`: name → longest wall time [s]."""
    return {name: s for name, s in out["calls"].items() if name not in besides and s > limit_s}
