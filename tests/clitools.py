"""What the command-line tests share: an in-process runner of `sunbench`, the rows of its metrics table, and
the check that bad input is refused as a user error. (tests/ is on pytest's path: pyproject's `pythonpath`.)"""

import os
import re
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from cli.main import app  # the composed `sunbench` app (pyproject's console script)

ALL_METHODS = ("seed003", "seed003-tilt", "seed003-sector", "physical", "physical-mask")
# no colour codes, wide enough that nothing wraps
runner = CliRunner(env={"COLUMNS": "160", "FORCE_COLOR": None, "NO_COLOR": "1", "TERM": "dumb"})


def invoke(*args):
    """`sunbench ARGS` in-process; an exception other than the exit itself fails the test."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result


SUNBENCH = Path(sys.executable).with_name("sunbench")
# no SUNBENCH_CATALOGUE from the caller's shell: every test names its catalogue
ENV = {**{k: v for k, v in os.environ.items() if k != "SUNBENCH_CATALOGUE"},
       "COLUMNS": "160", "NO_COLOR": "1", "TERM": "dumb"}


def sunbench_process(*args, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    """`sunbench ARGS` as its own process (its own catalogue connection and locks), output captured."""
    return subprocess.run([str(SUNBENCH), *map(str, args)], capture_output=True, text=True, env=ENV, cwd=cwd,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def method_rows(stdout: str) -> dict[str, bool]:
    """Method name → chosen ('*'), from the rows of the metrics table."""
    rows = {}
    for line in stdout.splitlines():
        m = re.match(r"^\W*(seed003-tilt|seed003-sector|seed003|physical-mask|physical)( \*)?\s", line)
        if m:
            rows[m.group(1)] = bool(m.group(2))
    return rows


def flat(text: str) -> str:
    return " ".join(text.split())


def assert_user_error_text(stderr: str, returncode: int, *fragments: str) -> str:
    """Exit code 2, an error message naming the problem (every fragment), no traceback; the message, flat."""
    assert returncode == 2, (returncode, stderr)
    assert stderr.startswith("error:"), stderr
    assert "Traceback" not in stderr
    message = flat(stderr)
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message
