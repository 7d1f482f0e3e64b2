"""`sunbench serve` (or the README's scripts/run.sh) in a child process on a free loopback port, for the
tests that need a real server: its own config folder (so its own token) and catalogue, its output in a file."""

import contextlib
import os
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SUNBENCH = Path(sys.executable).parent / "sunbench"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Served:
    base: str
    home: Path
    log: Path
    proc: subprocess.Popen | None = None  # to kill it as a crash would (SIGKILL)

    @property
    def token_file(self) -> Path:
        return self.home / "cfg" / "sunbench" / "token"

    @property
    def token(self) -> str:
        return self.token_file.read_text().strip()

    def output(self) -> str:
        return self.log.read_text()


@contextlib.contextmanager
def serving(home: Path, command: list[str] | None = None, *options: str, timeout_s: float = 60.0):
    """Run ``command`` (default: ``sunbench serve``) with ``--port P --catalogue HOME/bench.sqlite`` and
    `options` until it answers, yield a :class:`Served`, then stop it (SIGTERM, as Ctrl-C would).

    The server's output must not hold a traceback, even after it stopped."""
    port = free_port()
    env = {**os.environ, "XDG_CONFIG_HOME": str(home / "cfg"), "HOME": str(home)}
    argv = [*(command or [str(SUNBENCH), "serve"]), "--port", str(port), "--catalogue", str(home / "bench.sqlite"),
            *options]
    served = Served(f"http://127.0.0.1:{port}", home, home / "serve.log")
    with open(served.log, "w") as log:
        proc = served.proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=home)
        try:
            deadline = time.monotonic() + timeout_s
            while True:
                assert proc.poll() is None, served.output()
                assert time.monotonic() < deadline, f"the server did not come up:\n{served.output()}"
                try:
                    urllib.request.urlopen(served.base + "/openapi.json", timeout=5)
                    break
                except (urllib.error.URLError, ConnectionError, TimeoutError):  # not listening yet, or still building
                    # the schema (1-2 s on a loaded machine): ask again
                    time.sleep(0.2)
            yield served
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:  # a server that does not stop on SIGTERM is a failure, not a leak
                proc.kill()
                proc.wait()
                raise AssertionError(f"the server did not stop on SIGTERM:\n{served.output()}") from None
    assert "Traceback" not in served.output(), served.output()
