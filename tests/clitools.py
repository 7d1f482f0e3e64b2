"""What the command-line tests share: an in-process runner of `sunbench` and one as its own process, the rows of
its metrics tables, the check that bad input is refused as a user error, the bad cells every bench data CSV
refuses, and the listing `sunbench sim` prints. (tests/ is on pytest's path: pyproject's `pythonpath`.)"""

import os
import re
import subprocess
import sys
import time
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


def method_rows(stdout: str, methods=ALL_METHODS) -> dict[str, bool]:
    """Method name → chosen ('*'), from the rows of a metrics table (CMOS by default; `fit qd`'s with the QD
    methods): a row is a method's name, then its first figure (a number, or a dash when it has none)."""
    names = "|".join(map(re.escape, sorted(methods, key=len, reverse=True)))  # seed003-tilt before seed003
    rows = {}
    for line in stdout.splitlines():
        m = re.match(rf"^\W*({names})( \*)?\s+│?\s*[\d—]", line)
        if m:
            rows[m.group(1)] = bool(m.group(2))
    return rows


def flat(text: str) -> str:
    return " ".join(text.split())


def assert_user_error(result, *fragments: str, quiet: bool = True) -> str:
    """An in-process `invoke` refused as a user error: exit code 2, one error line naming the problem, no
    traceback and, when `quiet`, nothing on stdout; the message, flat."""
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.output
    message = assert_user_error_text(result.stderr, result.exit_code, *fragments)
    if quiet:
        assert result.stdout == "", result.stdout
    return message


def assert_user_error_text(stderr: str, returncode: int, *fragments: str) -> str:
    """Exit code 2, an error message naming the problem (every fragment), no traceback; the message, flat."""
    assert returncode == 2, (returncode, stderr)
    assert stderr.startswith("error:"), stderr
    assert "Traceback" not in stderr
    message = flat(stderr)
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message


#: Cells a bench data CSV (either family's) refuses in a numeric column, with the words that say why.
BAD_CELLS = [
    ("abc", "'abc' is not a number"),
    ("", "empty cell"),
    ("  ", "empty cell"),
    ("nan", "'nan' is not a finite number"),
    ("NaN", "'NaN' is not a finite number"),
    ("inf", "'inf' is not a finite number"),
    ("-Infinity", "'-Infinity' is not a finite number"),
]


def read_sim_listing(stdout, timeout_s: float = 30) -> tuple[dict[str, str], dict[str, list[str]]]:
    """What `sunbench sim` prints before "serving": role → URL (its `role url` lines, what scripts parse) and
    role → the indented lines under it (how known clients connect). `stdout` is the process's text pipe."""
    urls, hints, role = {}, {}, None
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = stdout.readline()
        if not line or line.startswith("serving"):
            break
        parts = line.split()
        if len(parts) == 2 and parts[1].startswith("socket://"):
            role = parts[0]
            urls[role] = parts[1]
        elif role and line.startswith(" "):
            hints.setdefault(role, []).append(line.strip())
    return urls, hints
