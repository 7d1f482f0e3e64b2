"""`sunbench serve`: the API on a real socket, with the token created at first start."""

import json
import os
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


def _wait_until_up(proc, base, timeout_s=60.0):
    deadline = time.monotonic() + timeout_s
    while True:
        assert proc.poll() is None, proc.stdout.read()
        assert time.monotonic() < deadline, "the server did not come up"
        try:
            urllib.request.urlopen(base + "/openapi.json", timeout=1)
            return
        except (urllib.error.URLError, ConnectionError):
            time.sleep(0.2)


def test_serve_binds_loopback_and_guards_commands(tmp_path):
    port = _free_port()
    env = {"XDG_CONFIG_HOME": str(tmp_path / "cfg"), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    exe = Path(sys.executable).parent / "sunbench"
    proc = subprocess.Popen([str(exe), "serve", "--catalogue", str(tmp_path / "c.sqlite"), "--port", str(port),
                             "--time-scale", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env, text=True)
    try:
        token_file = tmp_path / "cfg" / "sunbench" / "token"
        base = f"http://127.0.0.1:{port}"
        _wait_until_up(proc, base)
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


def test_the_readme_main_command_serves_the_dashboard_on_the_simulated_bench(tmp_path):
    """`bash scripts/run.sh`, as the README gives it (with a free port and a scratch catalogue)."""
    port = _free_port()
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "cfg"), "HOME": str(tmp_path)}
    proc = subprocess.Popen(["bash", str(root / "scripts" / "run.sh"), "--port", str(port), "--catalogue",
                             str(tmp_path / "c.sqlite")], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            env=env, text=True, cwd=tmp_path)
    try:
        base = f"http://127.0.0.1:{port}"
        _wait_until_up(proc, base, timeout_s=120)  # set-up runs first (a no-op once .venv is current)
        page = urllib.request.urlopen(base + "/", timeout=5).read().decode()
        assert "<title>sunbench · Bench</title>" in page and "/static/bench.js" in page
        token = (tmp_path / "cfg" / "sunbench" / "token").read_text().strip()
        request = urllib.request.Request(base + "/api/status", headers={"Authorization": f"Bearer {token}"})
        assert json.load(urllib.request.urlopen(request, timeout=5))["engine"]["state"] == "idle"
    finally:
        proc.terminate()
        proc.wait(timeout=15)
    output = proc.stdout.read()
    assert f"sunbench dashboard on http://127.0.0.1:{port}/ (the simulated bench, simulated time ×10)" in output
    assert token in output and "Traceback" not in output
