"""`sunbench serve`: the API on a real socket, with the token created at first start."""

import json
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_binds_loopback_and_guards_commands(tmp_path):
    port = _free_port()
    env = {"XDG_CONFIG_HOME": str(tmp_path / "cfg"), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    exe = Path(sys.executable).parent / "sunbench"
    proc = subprocess.Popen([str(exe), "serve", "--catalogue", str(tmp_path / "c.sqlite"), "--port", str(port),
                             "--time-scale", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env, text=True)
    try:
        token_file = tmp_path / "cfg" / "sunbench" / "token"
        base = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 30
        while True:
            assert proc.poll() is None, proc.stdout.read()
            assert time.monotonic() < deadline, "the server did not come up"
            try:
                urllib.request.urlopen(base + "/openapi.json", timeout=1)
                break
            except (urllib.error.URLError, ConnectionError):
                time.sleep(0.2)
        token = token_file.read_text().strip()
        assert oct(token_file.stat().st_mode & 0o777) == "0o600"
        request = urllib.request.Request(base + "/api/status", headers={"Authorization": f"Bearer {token}"})
        status = json.load(urllib.request.urlopen(request, timeout=5))
        assert status["engine"]["state"] == "idle"
        try:
            urllib.request.urlopen(urllib.request.Request(base + "/api/run/pause", method="POST"), timeout=5)
            raise AssertionError("a command without the token was accepted")
        except urllib.error.HTTPError as exc:
            assert exc.code == 401
    finally:
        proc.terminate()
        proc.wait(timeout=15)
    output = proc.stdout.read()
    assert token in output and "Traceback" not in output
