"""The horizon family on the command line: `fit horizon` of a Horizon bench data CSV (scans made the long way round by
tests/horizontools.py, not by the fit's model), the calibration document and C header it writes, `header` and `apply`
with a horizon calibration, and bad input refused as a user error."""

from __future__ import annotations

import csv
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ccompiler import c_compiler
from clitools import assert_user_error, assert_user_error_text, flat, invoke, sunbench_process
from horizontools import RADII, RECOVERABLE, TRUTH, synthetic

from bench.horizon_datafile import write_horizon_csv
from calibration.horizon.bench_document import sensor_parameters_from_document
from calibration.horizon.bench_fit import PARAMETERS, mount_rotation

CHECKS = [(-25.0, 12.0, RADII[1]), (17.0, -9.0, RADII[0]), (5.0, 4.0, RADII[2]), (28.0, 14.0, RADII[1])]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli-horizon")


@pytest.fixture(scope="module")
def data_csv(workdir) -> Path:
    path = workdir / "hz.csv"
    data = synthetic(rolls=np.arange(-30.0, 30.1, 15.0), pitches=np.array([-15.0, 0.0, 15.0]), repeats=3, check=CHECKS)
    write_horizon_csv(path, type(data)(data.roll_deg, data.pitch_deg, data.cone, data.phase_out_deg,
                                       data.phase_in_deg, data.disc_radius_deg, scan=data.scan, repeat=data.repeat,
                                       check=data.check, sensor_id="HZ-0042"))
    return path


@pytest.fixture(scope="module")
def fitted(workdir, data_csv):
    """`fit horizon hz.csv -o CAL.json --header CAL.h`, run once for the module."""
    cal, header = workdir / "CAL.json", workdir / "CAL.h"
    result = invoke("fit", "horizon", data_csv, "-o", cal, "--header", header)
    assert result.exit_code == 0, result.output
    return result, cal, header


def test_fit_prints_the_parameters_the_held_out_figures_and_the_warnings(fitted):
    result, cal, _ = fitted
    text = flat(result.stdout)
    assert "each fitted parameter ± 1σ" in text
    for name in PARAMETERS:
        line = next(line for line in result.stdout.splitlines() if line.strip("│ ").startswith(name))
        assert len(re.findall(r"\d+\.\d+", line)) >= 2, line  # the value and its 1σ
    assert "mount_pitch_deg (folded into the offsets)" in text
    assert "χ²/dof" in text and "check points *" in text and "check points, nominal sensor" in text
    for radius in RADII:
        assert f"ρ {radius:.3f}° left out" in text
    # the file's counts: 5 rolls × 3 pitches × 3 radii × 3 repeats + 4 check poses × 3, two cones each
    assert "135 scans (294 rows, 24 check rows)" in text and "sensor HZ-0042" in text
    document = json.loads(cal.read_text())
    assert all(f"warning: {flat(w)}" in text for w in document["warnings"])


def test_the_document_holds_the_recovered_errors_with_their_uncertainty(fitted, data_csv):
    _, cal, _ = fitted
    document = json.loads(cal.read_text())
    assert (document["format"], document["version"], document["family"]) == ("sunbench-horizon-calibration", 1,
                                                                              "horizon")
    assert document["sensor_id"] == "HZ-0042" and document["source"] == str(data_csv)
    assert document["software"].startswith("sunbench ") and document["created_utc"]
    recovered = sensor_parameters_from_document(document)
    for name in PARAMETERS:
        entry = document["parameters"][name]
        assert entry["fitted"] and entry["sd"] > 0
        assert abs(entry["value"] - getattr(RECOVERABLE, name)) < 4 * entry["sd"], (name, entry)
    assert recovered.mount_pitch_deg == 0.0 and TRUTH.mount_pitch_deg != 0.0  # folded into the phase offsets
    names = document["covariance"]["names"]
    assert names == list(PARAMETERS) and np.array(document["covariance"]["matrix"]).shape == (7, 7)
    check = document["heldout"]["check"]
    assert check["calibrated"]["n_scans"] == 12 and check["calibrated"]["roll_rms_deg"] < 0.02
    assert check["nominal"]["roll_rms_deg"] > 10 * check["calibrated"]["roll_rms_deg"]


def test_the_header_compiles_and_holds_the_calibration(workdir, fitted):
    _, cal, header = fitted
    document = json.loads(cal.read_text())
    text = header.read_text()
    assert "HZ-0042" in text and "check points: roll RMS" in text
    compiler = c_compiler()
    program = workdir / "print.c"
    program.write_text(f'#include <stdio.h>\n#include "{header}"\n'
                       "int main(void) { int i, j;\n"
                       '  printf("%.9g %.9g %.9g %.9g %.9g\\n",'
                       " SUNBENCH_HORIZON_GAMMA1_DEG, SUNBENCH_HORIZON_GAMMA2_DEG,"
                       " SUNBENCH_HORIZON_PHASE_OFFSET1_DEG, SUNBENCH_HORIZON_PHASE_OFFSET2_DEG,"
                       " SUNBENCH_HORIZON_RADIUS_BIAS_DEG);\n"
                       '  for (i = 0; i < 3; i++) for (j = 0; j < 3; j++) printf("%.17g\\n",'
                       " SUNBENCH_HORIZON_MOUNT[i][j]);\n  return 0; }\n")
    exe = workdir / "print"
    done = subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-Werror", str(program), "-o", str(exe)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    numbers = [float(v) for v in subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()]
    p = sensor_parameters_from_document(document)
    assert numbers[:5] == pytest.approx([p.gamma1_deg, p.gamma2_deg, p.phase_offset1_deg, p.phase_offset2_deg,
                                         p.radius_bias_deg], abs=1e-6)  # %.9g
    assert np.allclose(np.reshape(numbers[5:], (3, 3)), mount_rotation(p), atol=1e-9)
    again = workdir / "again.h"
    result = invoke("header", cal, "-o", again)
    assert result.exit_code == 0 and again.read_text() == text


def test_apply_gives_each_scans_roll_and_pitch_and_its_error_against_the_table(workdir, fitted, data_csv):
    _, cal, _ = fitted
    output = workdir / "applied.csv"
    result = invoke("apply", cal, data_csv, "-o", output)
    assert result.exit_code == 0, result.output
    assert "147 scans' roll and pitch written" in flat(result.stdout)
    with output.open() as fh:
        rows = list(csv.DictReader(fh))
    roll_error = np.array([float(r["roll_error_deg"]) for r in rows])
    pitch_error = np.array([float(r["pitch_error_deg"]) for r in rows])
    assert np.sqrt(np.mean(roll_error ** 2)) < 0.02 and np.sqrt(np.mean(pitch_error ** 2)) < 0.01
    # the sensor's own attitude is the table's turned by the mount: about the table's plus the mount's roll
    sensor_roll = np.array([float(r["sensor_roll_deg"]) for r in rows])
    table_roll = np.array([float(r["roll_deg"]) for r in rows])
    assert np.abs(sensor_roll - table_roll - TRUTH.mount_roll_deg).max() < 0.1


@pytest.mark.parametrize("text, fragments", [
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg\n0,0,3,66,294,68\n",
     ("row 1 (line 2)", "column 'cone'", "a cone is 1 or 2")),
    ("roll_deg,pitch_deg,cone,t_out_s,t_in_s,period_s,disc_radius_deg\n0,0,1,184,815,1000,68\n",
     ("row 1 (line 2)", "column 'period_s'", "times are in seconds")),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg\n" + "0,0,1,66,294,68\n0,0,2,66,294,68\n" * 3,
     ("every fitted scan is at one pose",)),
])
def test_fit_refuses_bad_input_as_a_user_error(tmp_path, text, fragments):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    assert_user_error(invoke("fit", "horizon", path, "-o", tmp_path / "cal.json"), *fragments)
    assert not (tmp_path / "cal.json").exists()


def test_a_broken_calibration_is_refused_by_header_and_apply(tmp_path, fitted, data_csv):
    _, cal, _ = fitted
    document = json.loads(cal.read_text())
    document["parameters"]["gamma1_deg"]["value"] = 95.0
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps(document))
    assert_user_error(invoke("header", broken, "-o", tmp_path / "x.h"), "gamma1_deg", "not in (0, 90)")
    assert_user_error(invoke("apply", broken, data_csv, "-o", tmp_path / "x.csv"), "gamma1_deg")


def test_the_console_script_refuses_bad_input_without_a_traceback(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg\n0,nan,1,66,294,68\n")
    done = sunbench_process("fit", "horizon", path, cwd=tmp_path)
    assert_user_error_text(done.stderr, done.returncode, "row 1 (line 2)", "column 'pitch_deg'", "not a finite number")
    assert done.stdout == ""


def test_a_horizon_run_is_shown_and_exported_from_the_command_line(tmp_path):
    """`sunbench run` of a small horizon-grid campaign on the example bench (time scale 0), then `show` prints the
    sensor's errors ± 1σ and roll/pitch held out, and `export` writes the CSV `fit horizon` reads."""
    root = Path(__file__).resolve().parents[1]
    campaign = tmp_path / "small.yaml"
    campaign.write_text("name: small\nplan: horizon-grid\nsensors: [HZ-0001]\nhorizon_grid:\n"
                        "  altitudes_km: [400, 700]\n  roll_range_deg: 30\n  roll_step_deg: 15\n"
                        "  pitch_range_deg: 15\n  pitch_step_deg: 15\n  repeats: 2\n  check_points: 2\n")
    db = tmp_path / "c.sqlite"
    run = sunbench_process("run", campaign, "--bench", root / "examples" / "bench-sim-horizon.yaml", "--time-scale", 0,
                           "--catalogue", db, cwd=tmp_path, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    shown = sunbench_process("show", "1", "--catalogue", db, cwd=tmp_path)
    assert shown.returncode == 0 and "Traceback" not in shown.stdout + shown.stderr, shown.stdout + shown.stderr
    text = flat(shown.stdout)
    names = ["gamma1_deg", "gamma2_deg", "phase_offset1_deg", "phase_offset2_deg", "radius_bias_deg", "mount_roll_deg"]
    assert [text.index(n) for n in names] == sorted(text.index(n) for n in names)  # the document's order
    assert "check points *" in text and "nominal sensor" in text and "χ²/dof" in text
    exported = sunbench_process("export", "1", "-o", tmp_path / "hz.csv", "--catalogue", db, cwd=tmp_path)
    assert exported.returncode == 0, exported.stderr
    fitted = invoke("fit", "horizon", tmp_path / "hz.csv")
    assert fitted.exit_code == 0 and "gamma1_deg" in flat(fitted.output), fitted.output


def test_sim_serves_the_horizon_bench_and_its_drivers_talk_to_it_over_tcp(tmp_path):
    """`sunbench sim --config examples/bench-sim-horizon.yaml`: the fork, the Earth simulator and the horizon sensor on
    TCP, each with how to connect (the sensor's own driver named, not another family's); the Earth simulator's driver
    heats the disc and sets the iris, and the sensor's driver reads a revolution with both cones' edges."""
    import signal

    from clitools import ENV, SUNBENCH, read_sim_listing

    from drivers.earth_simulator import EarthSimulatorSource
    from drivers.horizon_sensor import HorizonSensorModule
    from drivers.transport import open_port

    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([str(SUNBENCH), "sim", "--config", str(root / "examples" / "bench-sim-horizon.yaml"),
                             "--time-scale", "0", "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV, cwd=tmp_path, stdin=subprocess.DEVNULL)
    try:
        urls, hints = read_sim_listing(proc.stdout)
        assert set(urls) == {"table", "earth", "sensor"}, (urls, proc.stderr.read())
        assert any("HorizonSensorModule(" in h for h in hints["sensor"]), hints["sensor"]
        assert any("EarthSimulatorSource(" in h for h in hints["earth"]), hints["earth"]
        earth = EarthSimulatorSource(open_port(urls["earth"], timeout_s=2.0))
        earth.lamp_on()
        earth.open_shutter()
        earth.set_disc_radius_deg(68.0)
        assert abs(earth.disc_radius_deg() - 68.0) < 0.02
        sensor = HorizonSensorModule(open_port(urls["sensor"], timeout_s=5.0))
        (scan,) = sensor.read_scans(1)
        assert all(scan.valid) and 0.9 < scan.period_s < 1.1, scan
        earth.standby()
        assert not earth.status().shutter_open
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=20)


def test_the_headers_model_radius_is_the_fits_to_a_few_microdegrees(workdir, fitted):
    """The header's ρ − b + Δρ (b's leading term cot ρ · a²/6 with a the IFOV half-angle in radians, as its comment
    says) against the fit's model (the exact overlap of the IFOV's and the disc's caps,
    calibration.horizon.bench_fit.model_disc_radius_deg) over the iris's range: within 3e-6° at the design's 2° (the
    next term, ≈ 2e-4 · b, peaks at 2.3e-6° at 50°), a thousandth of b and far below the phases' noise."""
    from calibration.horizon.bench_fit import model_disc_radius_deg

    _, cal, header = fitted
    text = header.read_text()
    assert "a = radians(SUNBENCH_HORIZON_IFOV_HALF_ANGLE_DEG)" in text and "a^2 / 6 [rad]" in text
    radii = [50.0, 64.3, 67.9, 70.2, 78.0]
    program = workdir / "radius.c"
    program.write_text(f'#include <stdio.h>\n#include "{header}"\n'
                       "int main(void) { const double rho[] = {" + ", ".join(map(repr, radii)) + "}; int i;\n"
                       '  for (i = 0; i < 5; i++) printf("%.17g\\n", sunbench_horizon_model_radius_deg(rho[i]));\n'
                       "  return 0; }\n")
    exe = workdir / "radius"
    done = subprocess.run([c_compiler(), "-std=c99", "-Wall", "-Wextra", "-Werror", str(program), "-o", str(exe),
                           "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    got = np.array([float(v) for v in subprocess.run([str(exe)], capture_output=True, text=True,
                                                     check=True).stdout.split()])
    p = sensor_parameters_from_document(json.loads(cal.read_text()))
    want = model_disc_radius_deg(np.array(radii), p)
    bias = np.array(radii) + p.radius_bias_deg - want  # b itself: 2.5 … 9.8 mdeg
    print(f"\nb {bias.round(6).tolist()} °; header − fit {(got - want).tolist()} °")
    assert p.ifov_half_angle_deg == 2.0 and bias.min() > 2e-3
    assert np.abs(got - want).max() < 3e-6
