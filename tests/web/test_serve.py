"""`sunbench serve` and the README's main command: the API on a real socket, with the token created at first
start."""

import json
import urllib.error
import urllib.request

from serving import ROOT, serving


def _status(served) -> dict:
    request = urllib.request.Request(served.base + "/api/status", headers={"Authorization": f"Bearer {served.token}"})
    return json.load(urllib.request.urlopen(request, timeout=5))


def test_serve_binds_loopback_and_guards_commands(tmp_path):
    with serving(tmp_path, None, "--time-scale", "0") as served:
        assert oct(served.token_file.stat().st_mode & 0o777) == "0o600"
        assert _status(served)["engine"]["state"] == "idle"
        try:
            urllib.request.urlopen(urllib.request.Request(served.base + "/api/run/pause", method="POST"), timeout=5)
            raise AssertionError("a command without the token was accepted")
        except urllib.error.HTTPError as exc:
            assert exc.code == 401
    assert served.token in served.output()  # shown once, at first start


def test_the_readme_main_command_serves_the_dashboard_on_the_simulated_bench(tmp_path):
    """`bash scripts/run.sh`, as the README gives it (with a free port and a scratch catalogue); set-up runs
    first, a no-op once .venv is current."""
    with serving(tmp_path, ["bash", str(ROOT / "scripts" / "run.sh")], timeout_s=120) as served:
        page = urllib.request.urlopen(served.base + "/", timeout=5).read().decode()
        assert "<title>sunbench · Bench</title>" in page and "/static/bench.js" in page
        assert _status(served)["engine"]["state"] == "idle"
    assert f"sunbench dashboard on {served.base}/ (the simulated bench, simulated time ×10)" in served.output()
    assert served.token in served.output()
