"""The `sunbench` command line: fit, apply, header, demo, and how it refuses bad input."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from clitools import ALL_METHODS, assert_user_error, flat, invoke, method_rows

from bench.datafile import read_calibration, write_bench_csv
from calibration.geometry import angular_error_deg
from calibration.models import METHODS
from calibration.synthetic import synthetic_bench_data


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli")


@pytest.fixture(scope="module")
def bench_csv(workdir) -> Path:
    path = workdir / "DATA.csv"
    write_bench_csv(path, synthetic_bench_data(seed=7, sensor_id="SN-0042"))
    return path


@pytest.fixture(scope="module")
def fitted(workdir, bench_csv):
    """`fit cmos DATA.csv -o CAL.json --header CAL.h`, run once for the module."""
    cal, header = workdir / "CAL.json", workdir / "CAL.h"
    result = invoke("fit", "cmos", bench_csv, "-o", cal, "--header", header)
    return result, cal, header


# --- fit ----------------------------------------------------------------------------------------------------

def test_fit_prints_every_method_and_marks_the_chosen_one(fitted):
    result, _, _ = fitted
    assert result.exit_code == 0, result.output
    rows = method_rows(result.stdout)
    assert set(rows) == set(ALL_METHODS), result.stdout
    assert [m for m, chosen in rows.items() if chosen] == ["physical"]
    assert "* = chosen" in result.stdout
    assert "264 frames from" in result.stdout and "method physical" in result.stdout
    assert "Physical model: fitted build" in result.stdout
    assert "Traceback" not in result.output


def test_fit_writes_calibration_json(fitted):
    result, cal, _ = fitted
    document = json.loads(cal.read_text())
    assert document["format"] == "sunbench.calibration"
    assert document["version"] == 1
    assert document["method"] == "physical"
    assert document["sensor_id"] == "SN-0042"
    assert document["source"].endswith("DATA.csv")
    assert set(document["metrics"]) == set(ALL_METHODS)
    for method, metrics in document["metrics"].items():
        assert metrics["method"] == method
        assert metrics["fitted"]["rms_vector_deg"] >= 0
        assert metrics["heldout"]["rms_vector_deg"] >= 0
    # the chosen method really is the best held out
    best = min(document["metrics"], key=lambda m: document["metrics"][m]["heldout"]["rms_vector_deg"])
    assert best == "physical"
    calibration, _ = read_calibration(cal)
    assert calibration.method == "physical"


def test_fit_writes_c_header(fitted):
    _, _, header = fitted
    text = header.read_text()
    assert "sunbench_sun_direction" in text
    assert "SN-0042" in text
    # the header says where it came from and how good it is
    assert "source: " in text and "DATA.csv" in text and "software: sunbench" in text and "created: " in text
    assert "held-out vector RMS: " in text


def test_fit_with_method_seed003(workdir, bench_csv):
    cal = workdir / "seed003.json"
    result = invoke("fit", "cmos", bench_csv, "--method", "seed003", "-o", cal)
    assert result.exit_code == 0, result.output
    rows = method_rows(result.stdout)
    assert set(rows) == set(ALL_METHODS)
    assert [m for m, chosen in rows.items() if chosen] == ["seed003"]
    document = json.loads(cal.read_text())
    assert document["method"] == "seed003"
    calibration, _ = read_calibration(cal)
    assert type(calibration) is METHODS["seed003"]


def test_fit_one_sensor_of_a_batch(workdir):
    a, b = synthetic_bench_data(seed=1, sensor_id="SN-A"), synthetic_bench_data(seed=2, sensor_id="SN-B")
    write_bench_csv(workdir / "a.csv", a)
    write_bench_csv(workdir / "b.csv", b)
    batch = workdir / "batch.csv"
    batch.write_text((workdir / "a.csv").read_text()
                     + "".join((workdir / "b.csv").read_text().splitlines(keepends=True)[1:]))
    assert_user_error(invoke("fit", "cmos", batch), str(batch), "2 sensors", "--sensor")
    cal = workdir / "b.json"
    result = invoke("fit", "cmos", batch, "--sensor", "SN-B", "--method", "seed003", "-o", cal)
    assert result.exit_code == 0, result.output
    assert f"{len(b)} frames" in result.stdout
    assert json.loads(cal.read_text())["sensor_id"] == "SN-B"


# --- apply / header -----------------------------------------------------------------------------------------

def test_apply_recovers_the_true_directions(workdir, fitted, bench_csv):
    _, cal, _ = fitted
    out = workdir / "OUT.csv"
    result = invoke("apply", cal, bench_csv, "-o", out)
    assert result.exit_code == 0, result.output
    assert "264 directions" in result.stdout

    with bench_csv.open() as fh:
        original = list(csv.reader(fh))
    with out.open() as fh:
        applied = list(csv.reader(fh))
    assert applied[0] == ["input_zenith_deg", "input_azimuth_deg", "x_px", "y_px", "repeat", "sensor_id",
                          "zenith_deg", "azimuth_deg"]
    assert len(applied) == len(original)
    for a, o in zip(applied[1:], original[1:]):
        assert a[:6] == o  # input cells are copied verbatim

    cols = {name: j for j, name in enumerate(applied[0])}
    values = lambda name: np.array([float(r[cols[name]]) for r in applied[1:]])  # noqa: E731
    error = angular_error_deg(values("input_zenith_deg"), values("input_azimuth_deg"),
                              values("zenith_deg"), values("azimuth_deg"))
    assert error.max() < 0.05, error.max()
    assert error.mean() > 0  # a real comparison, not the input echoed back


def test_apply_to_a_plain_spot_file(workdir, fitted):
    _, cal, _ = fitted
    calibration, _ = read_calibration(cal)
    spots = workdir / "spots.csv"
    normal = synthetic_bench_data(zenith_deg=[0.0], azimuth_deg=[0.0], noise_px=0.0)  # spot at normal incidence
    x_normal, y_normal = float(normal.x_px[0]), float(normal.y_px[0])
    spots.write_text(f"frame,x_px,y_px\nf1,{x_normal!r},{y_normal!r}\nf2,400.0,300.0\n")
    out = workdir / "spots-out.csv"
    result = invoke("apply", cal, spots, "--output", out)
    assert result.exit_code == 0, result.output
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["frame", "x_px", "y_px", "zenith_deg", "azimuth_deg"]
    assert [r[0] for r in rows[1:]] == ["f1", "f2"]
    z, a = calibration.apply(np.array([x_normal, 400.0]), np.array([y_normal, 300.0]))
    np.testing.assert_allclose([float(r[3]) for r in rows[1:]], z, atol=1e-6)
    np.testing.assert_allclose([float(r[4]) for r in rows[1:]], a, atol=1e-6)
    assert float(rows[1][3]) < 0.02 and float(rows[2][3]) > 20.0


def test_header_command(workdir, fitted):
    _, cal, _ = fitted
    out = workdir / "sub" / "X.h"
    result = invoke("header", cal, "-o", out)
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert "sunbench_sun_direction" in text and "SN-0042" in text


# --- demo ---------------------------------------------------------------------------------------------------

def test_demo_writes_files_that_fit_again(tmp_path):
    result = invoke("demo", "--out", tmp_path)
    assert result.exit_code == 0, result.output
    assert set(method_rows(result.stdout)) == set(ALL_METHODS)
    assert "truth" in result.stdout
    for name in ("bench-data.csv", "calibration.json", "calibration.h"):
        assert (tmp_path / name).is_file(), name
    assert json.loads((tmp_path / "calibration.json").read_text())["method"] == "physical"
    assert "sunbench_sun_direction" in (tmp_path / "calibration.h").read_text()

    refit = invoke("fit", "cmos", tmp_path / "bench-data.csv", "-m", "physical", "-o", tmp_path / "refit.json")
    assert refit.exit_code == 0, refit.output
    first = json.loads((tmp_path / "calibration.json").read_text())["parameters"]
    second = json.loads((tmp_path / "refit.json").read_text())["parameters"]
    for name in ("x0_px", "y0_px", "gap_mm", "rotation_deg"):
        assert second[name] == pytest.approx(first[name], rel=1e-9, abs=1e-12), name


# --- bad input ----------------------------------------------------------------------------------------------

HEADER = "zenith_deg,azimuth_deg,x_px,y_px"


def _csv(tmp_path, text: str, name: str = "bad.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_missing_column(tmp_path):
    path = _csv(tmp_path, "zenith_deg,azimuth_deg,x_px\n0,0,1\n")
    assert_user_error(invoke("fit", "cmos", path), str(path), "missing column", "y_px")


def test_non_numeric_cell(tmp_path, bench_csv):
    lines = bench_csv.read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[3], "12,5x", 1).replace("12,5x", "12;5x")
    path = _csv(tmp_path, "\n".join(lines) + "\n")
    assert_user_error(invoke("fit", "cmos", path), str(path), "row 5 (line 6)", "column 'y_px'",
                      "'12;5x' is not a number")


def test_nan_cell(tmp_path):
    path = _csv(tmp_path, f"{HEADER}\n0,0,1,1\n10,45,nan,2\n")
    assert_user_error(invoke("fit", "cmos", path), str(path), "row 2 (line 3)", "column 'x_px'", "not a finite number")


def test_too_few_points(tmp_path):
    data = synthetic_bench_data(zenith_deg=[0, 10, 10, 20, 20], azimuth_deg=[0, 0, 90, 0, 90])
    path = tmp_path / "few.csv"
    write_bench_csv(path, data)
    assert_user_error(invoke("fit", "cmos", path), str(path), "too few bench directions, 5")


def test_all_points_at_one_azimuth(tmp_path):
    zenith = np.arange(0.0, 61.0, 5.0)
    data = synthetic_bench_data(zenith_deg=zenith, azimuth_deg=np.full(zenith.size, 45.0))
    path = tmp_path / "one-azimuth.csv"
    write_bench_csv(path, data)
    assert_user_error(invoke("fit", "cmos", path), str(path), "column 'azimuth_deg'", "one azimuth (45°)")


def test_calibration_of_another_version(tmp_path, fitted, bench_csv):
    _, cal, _ = fitted
    document = json.loads(cal.read_text())
    document["version"] = 99
    bad = tmp_path / "v99.json"
    bad.write_text(json.dumps(document))
    assert_user_error(invoke("apply", bad, bench_csv, "-o", tmp_path / "o.csv"), str(bad), "version 99")
    assert not (tmp_path / "o.csv").exists()
    assert_user_error(invoke("header", bad, "-o", tmp_path / "o.h"), str(bad), "version 99")
    assert not (tmp_path / "o.h").exists()


@pytest.mark.parametrize("command", ["fit", "apply-cal", "apply-spots", "header"])
def test_missing_file(tmp_path, fitted, bench_csv, command):
    _, cal, _ = fitted
    missing = tmp_path / "nowhere.csv"
    args = {"fit": ["fit", "cmos", missing],
            "apply-cal": ["apply", missing, bench_csv, "-o", tmp_path / "o.csv"],
            "apply-spots": ["apply", cal, missing, "-o", tmp_path / "o.csv"],
            "header": ["header", missing, "-o", tmp_path / "o.h"]}[command]
    assert_user_error(invoke(*args), str(missing), "no such file")


def test_unknown_method(bench_csv):
    assert_user_error(invoke("fit", "cmos", bench_csv, "--method", "magic"), "--method must be one of",
                      ", ".join(ALL_METHODS), "'magic'")


def test_bad_bench_geometry(tmp_path, bench_csv):
    assert_user_error(invoke("fit", "cmos", bench_csv, "--source-distance-mm", "-5"), "source_distance_mm")


def test_error_text_is_not_read_as_markup(tmp_path):
    # a cell and a file name with square brackets are shown as they are, and '[/x]' does not crash rich
    path = _csv(tmp_path, f"{HEADER}\n0,0,[/x],1\n1,0,[bold],1\n", name="run[bold].csv")
    assert_user_error(invoke("fit", "cmos", path), "run[bold].csv", "'[/x]' is not a number")


# --- the installed console script ---------------------------------------------------------------------------

def test_console_script(tmp_path, fitted):
    _, cal, _ = fitted
    script = Path(sys.executable).parent / "sunbench"
    assert script.is_file()
    env = {"PATH": str(script.parent), "COLUMNS": "160", "NO_COLOR": "1", "TERM": "dumb"}

    ok = subprocess.run([str(script), "header", str(cal), "-o", str(tmp_path / "s.h")], capture_output=True,
                        text=True, timeout=60, env=env)
    assert ok.returncode == 0, ok.stderr
    assert "sunbench_sun_direction" in (tmp_path / "s.h").read_text()

    bad = _csv(tmp_path, f"{HEADER}\n0,0,1,1\n10,45,abc,2\n")
    proc = subprocess.run([str(script), "fit", "cmos", str(bad)], capture_output=True, text=True, timeout=60,
                          env=env)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith("error:")
    flat = " ".join(proc.stderr.split())
    assert str(bad) in flat and "row 2 (line 3)" in flat and "'abc' is not a number" in flat


COMMANDS = ("apply", "header", "demo", "sim", "run", "runs", "show", "resume", "export", "fleet", "serve", "fit",
            "field", "study")


def _listed_commands(help_text: str) -> list[str]:
    """The command names of a `--help` page's Commands panel, in its order."""
    panel = help_text.split("Commands", 1)[1]
    return [m.group(1) for m in (re.match(r"^\W*([a-z]+)\s{2,}\S", line) for line in panel.splitlines()) if m]


def test_every_command_is_on_the_app():
    """cli/main.py composes bench's commands and web's `serve` into one app, in this order."""
    result = invoke("--help")
    assert result.exit_code == 0, result.output
    assert _listed_commands(result.stdout) == list(COMMANDS)
    assert invoke().exit_code == 2  # no command: the help, as a usage error


def test_python_m_cli(tmp_path):
    """`python -m cli` is the console script."""
    env = {"PATH": str(Path(sys.executable).parent), "COLUMNS": "160", "NO_COLOR": "1", "TERM": "dumb"}
    proc = subprocess.run([sys.executable, "-m", "cli", "--help"], capture_output=True, text=True, timeout=60,
                          env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Usage: sunbench" in proc.stdout
    assert _listed_commands(proc.stdout) == list(COMMANDS)


def test_fit_glass_index_options(workdir, bench_csv):
    out = workdir / "cal-index.json"
    result = invoke("fit", "cmos", bench_csv, "--fit-index", "--glass-index", "1.6", "-o", out)
    assert result.exit_code == 0, result.output
    parameters = json.loads(out.read_text())["parameters"]
    assert "glass_index" in parameters["fitted"]
    assert abs(parameters["glass_index"] - 1.52) < 5 * parameters["uncertainties"]["glass_index"] + 0.01
    assert_user_error(invoke("fit", "cmos", bench_csv, "--glass-index", "0.5"), "--glass-index")


# --- issue 9: robust data, design and bench geometry from the command line ----------------------------------

def _traced_csv(path, *, header_comments="", stage=False, glint_rows=(), optics=None):
    """A bench data CSV from the simulator's own ray trace (never the fit's model), on the seed 003 grid."""
    from calibration.synthetic import seed003_grid
    from drivers.sim.raytrace import SensorOptics, body_direction_from_stage, trace_bench_frames

    optics = optics or SensorOptics(x0_px=325.8, y0_px=233.4, gap_mm=1.05, glass_mm=0.5, tilt_x_deg=0.22,
                                    tilt_y_deg=-0.21, rotation_deg=1.4)
    zen, az, rep = seed003_grid()
    body = body_direction_from_stage(az, zen, lever_arm_mm=136.2, source_distance_mm=7100.0) if stage else (zen, az)
    x, y = trace_bench_frames(*body, optics, noise_px=0.02, rng=np.random.default_rng(3))
    for row in glint_rows:  # data rows are 1-based
        x[row - 1] += 9.0
    columns = "stage_zenith_deg,stage_azimuth_deg" if stage else "zenith_deg,azimuth_deg"
    lines = [f"{columns},x_px,y_px,repeat"] + [f"{a},{b},{c:.6f},{d:.6f},{k}"
                                               for a, b, c, d, k in zip(zen, az, x, y, rep)]
    path.write_text(header_comments + "\n".join(lines) + "\n")
    return path


def test_fit_names_every_rejected_glint_by_its_row(tmp_path):
    path = _traced_csv(tmp_path / "glints.csv", glint_rows=(50, 120, 200))
    cal = tmp_path / "cal.json"
    result = invoke("fit", "cmos", path, "-o", cal)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "3 rejected frame(s)" in text
    for row in (50, 120, 200):
        assert f"row {row} (" in text
    document = json.loads(cal.read_text())
    assert sorted(r["row"] for r in document["rejected"]) == [50, 120, 200]
    assert document["quality"]["chi2_dof"] < 3 and document["quality"]["warnings"] == []
    assert document["uncertainty_map"]["max_deg"] > 0


def test_fit_takes_the_detector_design_from_the_csv_header_into_document_and_header(tmp_path):
    from drivers.sim.raytrace import SensorOptics

    optics = SensorOptics(x0_px=652.0, y0_px=505.0, gap_mm=1.05, glass_mm=0.5, tilt_x_deg=0.22, rotation_deg=1.4,
                          pixel_pitch_mm=0.0053, width_px=1280, height_px=1024)
    path = _traced_csv(tmp_path / "big.csv", optics=optics,
                       header_comments="# pixel_pitch_mm: 0.0053\n# width_px = 1280\n# height_px: 1024\n")
    cal, header = tmp_path / "cal.json", tmp_path / "cal.h"
    result = invoke("fit", "cmos", path, "--method", "physical", "-o", cal, "--header", header)
    assert result.exit_code == 0, result.output
    document = json.loads(cal.read_text())
    assert document["design"]["pixel_pitch_mm"] == 0.0053 and document["design"]["width_px"] == 1280
    p, u = document["parameters"], document["parameters"]["uncertainties"]
    assert abs(p["gap_mm"] - 1.05) <= 3 * u["gap_mm"] and abs(p["glass_mm"] - 0.5) <= 3 * u["glass_mm"]
    assert "#define SB_DETECTOR_WIDTH_PX 1280" in header.read_text()
    assert "pixel pitch not given" not in result.stdout


def test_fit_of_stage_angles_fits_the_bench_geometry_and_warns_of_a_wrong_one(tmp_path):
    path = _traced_csv(tmp_path / "stage.csv", stage=True)
    cal = tmp_path / "cal.json"
    result = invoke("fit", "cmos", path, "-o", cal, "--source-distance-mm", "7100", "--source-distance-sd-mm", "20")
    assert result.exit_code == 0, result.output
    assert "Bench geometry (from the stage angles)" in result.stdout
    geometry = json.loads(cal.read_text())["bench_geometry"]
    assert abs(geometry["lever_arm_mm"]["value"] - 136.2) <= 3 * geometry["lever_arm_mm"]["sd"]
    wrong = invoke("fit", "cmos", path, "--lever-arm-mm", "100", "--lever-arm-sd-mm", "0.5",
                   "--source-distance-mm", "7100", "--source-distance-sd-mm", "5")
    assert wrong.exit_code == 0, wrong.output
    assert "warning:" in wrong.stdout and "disagrees with what the spots say" in flat(wrong.stdout)


def test_an_unknown_header_comment_is_refused_naming_its_line(tmp_path):
    path = _csv(tmp_path, f"# pixel_pich_mm: 0.0053\n{HEADER}\n0,0,1,1\n", name="typo.csv")
    assert_user_error(invoke("fit", "cmos", path), "typo.csv", "line 1", "unknown header comment 'pixel_pich_mm'")


def test_sim_serves_the_chosen_table_and_says_how_clients_connect(tmp_path):
    """`sunbench sim --table smc100`: `role url` lines (what scripts parse), each followed by how known clients
    connect; the driver then homes and moves the served SMC100 over TCP. Ctrl-C stops it even when it was started
    with SIGINT ignored, as a shell starts a background job (`sunbench sim &`, a CI runner's)."""
    import signal

    from clitools import ENV, SUNBENCH, read_sim_listing

    from drivers.interfaces import AxisMotion
    from drivers.newport_smc100 import Smc100Axis

    proc = subprocess.Popen([str(SUNBENCH), "sim", "--table", "smc100", "--source", "led", "--time-scale", "0",
                             "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
                            cwd=tmp_path, stdin=subprocess.DEVNULL,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        urls, hints = read_sim_listing(proc.stdout)
        assert set(urls) == {"table-azimuth", "table-zenith", "led", "sensor"}, (urls, proc.stderr.read())
        port = urls["table-azimuth"].rsplit(":", 1)[1]
        assert any(h.startswith("QMI:") and f'"tcp:127.0.0.1:{port}"' in h for h in hints["table-azimuth"])
        assert any(h.startswith("pystages:") and "--pty" in h for h in hints["table-azimuth"])
        led_port = urls["led"].rsplit(":", 1)[1]
        assert any(f"TCPIP0::127.0.0.1::{led_port}::SOCKET" in h for h in hints["led"])

        axis = Smc100Axis.open(urls["table-azimuth"], timeout_s=2.0, reset_wait_s=0.0)
        try:
            axis.poll_s = 0.002
            assert axis.state() == "NOT REFERENCED"
            axis.home(timeout_s=10.0)
            axis.move_to(25.0, timeout_s=10.0)
            assert axis.position_deg() == pytest.approx(25.0, abs=1e-5) and axis.state() == "READY"
            assert axis.expected_motion() == AxisMotion(10.0, 20.0)
        finally:
            axis.close()
    finally:
        proc.send_signal(signal.SIGINT)  # Ctrl-C, as "serving; Ctrl-C to stop" says
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()  # never left behind; the assertion below then fails
            proc.wait()
    assert proc.returncode == 0, proc.stderr.read()  # stopped cleanly: servers closed, no traceback


def test_sim_refuses_an_unknown_table():
    result = invoke("sim", "--table", "k10cr1")
    assert result.exit_code == 2 and "--table must be one of apt, lx200, smc100, got 'k10cr1'" in flat(result.stderr)
