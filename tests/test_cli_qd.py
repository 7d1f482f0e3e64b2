"""The QD family on the command line: `sunbench export` of a QD run, `fit qd`, `apply` and `header` of a QD
calibration, and how they refuse bad input. The data come from a small QD campaign on the simulated bench
(examples/bench-sim-qd.yaml): the simulator's own optics, not the fit's model."""

from __future__ import annotations

import csv
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from ccompiler import c_compiler
from clitools import assert_user_error, assert_user_error_text, flat, invoke, method_rows, sunbench_process

from bench.benchfile import BenchFile
from bench.campaign import Campaign, QdDarkSweep, QdGridProcedure
from bench.catalogue import Catalogue
from bench.families.qd import bench_data
from bench.qd_datafile import read_qd_csv
from bench.runner import open_session, run_campaign
from calibration.qd.document import apply_document

ROOT = Path(__file__).resolve().parents[1]
QD_METHODS = ("physical", "polynomial", "geometric")


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli-qd")


@pytest.fixture(scope="module")
def qd_run(workdir):
    """A small seed 002 campaign (a 10° grid) on the simulated QD bench: (catalogue path, run id). The module is
    the ideal one the physical model describes (no mask thickness, stray light or crosstalk): these tests are of
    the commands; the realistic module's accuracy, which needs the default 5° grid, is tested in
    tests/bench/test_qd_family.py."""
    path = workdir / "catalogue.sqlite"
    catalogue = Catalogue(path)
    document = yaml.safe_load((ROOT / "examples" / "bench-sim-qd.yaml").read_text())
    document["simulation"]["qd"].update(diaphragm_thickness_um=0.0, wall_reflectance=0.0, crosstalk=[0.0] * 4)
    session = open_session(BenchFile.model_validate(document), catalogue, time_scale=0.0)
    try:
        campaign = Campaign(name="qd-small", plan="qd-grid", sensors=("QD-0001",),
                            qd_grid=QdGridProcedure(step_deg=10, repeats=2,
                                                    dark=QdDarkSweep(temperatures_c=(15, 35), repeats=4)))
        (run_id,) = run_campaign(campaign, session, confirm_mount=lambda *a: True)
    finally:
        session.close()
        catalogue.close()
    return path, run_id


@pytest.fixture(scope="module")
def qd_csv(workdir, qd_run) -> Path:
    """`sunbench export RUN --format csv -o qd.csv` of the QD run."""
    catalogue, run_id = qd_run
    path = workdir / "qd.csv"
    result = invoke("export", run_id, "--format", "csv", "-o", path, "--catalogue", catalogue)
    assert result.exit_code == 0, result.output
    return path


@pytest.fixture(scope="module")
def fitted(workdir, qd_csv):
    """`fit qd qd.csv -o CAL.json --header CAL.h`, run once for the module."""
    cal, header = workdir / "CAL.json", workdir / "CAL.h"
    result = invoke("fit", "qd", qd_csv, "-o", cal, "--header", header)
    assert result.exit_code == 0, result.output
    return result, cal, header


# --- export -------------------------------------------------------------------------------------------------

def test_export_of_a_qd_run_is_the_qd_bench_csv(qd_run, qd_csv):
    catalogue, run_id = qd_run
    header = qd_csv.read_text().splitlines()[0]
    assert header == "zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,i4_a,temperature_c,repeat,dark,check,sensor_id"
    data = read_qd_csv(qd_csv)
    with Catalogue(catalogue, readonly=True) as cat:
        truth = bench_data(cat, cat.lineage(run_id), sensor_id="QD-0001")
    assert len(data) == len(truth) == 8 + 2 * (9 * 9 + 8 * 8)  # dark, then nodes and check points, 2 repeats
    assert data.sensor_id == "QD-0001"
    assert data.currents_a.tobytes() == truth.currents_a.tobytes()
    light = ~truth.dark
    assert data.zenith_deg[light].tobytes() == truth.zenith_deg[light].tobytes()
    assert data.azimuth_deg[light].tobytes() == truth.azimuth_deg[light].tobytes()
    for name in ("temperature_c", "repeat", "dark", "check"):
        np.testing.assert_array_equal(getattr(data, name), getattr(truth, name), err_msg=name)
    assert int(data.dark.sum()) == 8 and int(data.check.sum()) == 2 * 64


def test_export_to_stdout_names_no_file(qd_run):
    catalogue, run_id = qd_run
    result = invoke("export", run_id, "--catalogue", catalogue, "--format", "json")
    assert result.exit_code == 0 and json.loads(result.stdout)["run"]["family"] == "qd"


# --- fit qd -------------------------------------------------------------------------------------------------

def test_fit_prints_every_method_and_the_chosen_one(fitted):
    result, _, _ = fitted
    rows = method_rows(result.stdout, QD_METHODS)
    assert set(rows) == set(QD_METHODS), result.stdout
    assert [m for m, chosen in rows.items() if chosen] == ["physical"]
    text = flat(result.stdout)
    for words in ("held-out", "p99", "max by scheme", "nodes", "χ²/dof", "* = chosen", "check", "columns",
                  "rows"):  # (column heads may wrap)
        assert words in text, words
    assert "298 readings (8 dark, 128 check) at 145 directions" in text
    assert "298 readings from" in text and "sensor QD-0001" in text and "method physical" in text


def test_fit_prints_the_dark_current_per_quadrant(fitted):
    result, _, _ = fitted
    text = flat(result.stdout)
    assert "Dark current per quadrant (seed 002 §2.1): linear" in text and "8 dark readings" in text
    for q in ("Q1", "Q2", "Q3", "Q4"):
        line = next(line for line in result.stdout.splitlines() if re.search(rf"\b{q}\b", line))
        assert line.count("±") == 2, line  # offset and slope, each with its 1σ


def test_fit_states_the_geometric_models_strong_correlations(fitted):
    text = flat(fitted[0].stdout)
    assert "Geometric model (eq. 2.2), strong correlations" in text
    assert "x0_m and alpha0_deg are correlated" in text and "y0_m and beta0_deg are correlated" in text


def test_fit_is_accurate_held_out_on_the_simulated_bench(fitted):
    _, cal, _ = fitted
    document = json.loads(cal.read_text())
    metrics = document["metrics"]
    assert metrics["heldout"]["max_deg"] <= 0.1
    assert metrics["heldout_scheme"] in ("check", "columns", "rows")
    assert set(metrics["heldout_by_scheme"]) == {"check", "columns", "rows"}


def test_fit_writes_the_qd_calibration_document(fitted, qd_csv):
    result, cal, _ = fitted
    document = json.loads(cal.read_text())
    assert (document["format"], document["family"], document["version"]) == ("sunbench.calibration", "qd", 1)
    assert document["method"] == "physical" and document["sensor_id"] == "QD-0001"
    assert document["source"] == str(qd_csv) and document["software"].startswith("sunbench ")
    assert document["dark"]["model"] == "linear" and len(document["dark"]["quadrants"]) == 4
    assert document["rejected"] == [] and isinstance(document["warnings"], list)
    printed = flat(result.stdout)
    assert all(f"warning: {flat(w)}" in printed for w in document["warnings"])  # what the fit said, kept
    # the document alone turns the file's currents into its directions
    data = read_qd_csv(qd_csv)
    light = ~data.dark
    alpha, beta, _, _ = apply_document(document, data.currents_a[light], data.temperature_c[light])
    assert np.max(np.hypot(alpha - data.alpha_deg[light], beta - data.beta_deg[light])) < 0.1


def test_fit_writes_a_c_header_that_compiles(fitted):
    _, _, header = fitted
    text = header.read_text()
    assert "sunbench_qd_sun_direction" in text and "QD-0001" in text and "held-out error: max" in text
    compiler = c_compiler()
    done = subprocess.run([compiler, "-fsyntax-only", "-Wall", "-Werror", "-x", "c", str(header)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_fit_with_a_method_keeps_that_method(workdir, qd_csv):
    cal = workdir / "geometric.json"
    result = invoke("fit", "qd", qd_csv, "--method", "geometric", "-o", cal)
    assert result.exit_code == 0, result.output
    assert [m for m, chosen in method_rows(result.stdout, QD_METHODS).items() if chosen] == ["geometric"]
    assert "method geometric (asked for; the best held out is physical)" in flat(result.stdout)
    document = json.loads(cal.read_text())
    assert document["method"] == "geometric" and set(document["parameters"]) >= {"x0_m", "d_m", "phi0_deg"}


def test_fit_names_a_rejected_reading_by_its_csv_row(workdir, qd_csv):
    lines = qd_csv.read_text().splitlines()
    rows = list(csv.reader(lines))
    header = rows[0]
    i = next(k for k, r in enumerate(rows) if k and r[header.index("dark")] == "0"
             and r[header.index("check")] == "0" and r[header.index("zenith_deg")].startswith("14."))
    glint = rows[i]
    for q in ("i1_a", "i2_a"):  # stray light on two quadrants of one reading
        glint[header.index(q)] = repr(float(glint[header.index(q)]) * 1.3)
    bad = workdir / "glint.csv"
    with bad.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    result = invoke("fit", "qd", bad)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "1 rejected row(s)" in text and f"row {i} (line {i + 1})" in text, text


# --- apply and header ----------------------------------------------------------------------------------------

def test_apply_gives_the_direction_and_its_error_per_row(workdir, fitted, qd_csv):
    _, cal, _ = fitted
    output = workdir / "applied.csv"
    result = invoke("apply", cal, qd_csv, "-o", output)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "290 directions written" in text and "8 dark row(s)" in text and "angular error" in text
    with output.open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0])[:2] == ["input_zenith_deg", "input_azimuth_deg"]
    assert list(rows[0])[-5:] == ["alpha_deg", "beta_deg", "zenith_deg", "azimuth_deg", "error_deg"]
    light = [r for r in rows if r["dark"] == "0"]
    dark = [r for r in rows if r["dark"] == "1"]
    assert len(light) == 290 and len(dark) == 8
    assert all(r["alpha_deg"] == r["error_deg"] == "" for r in dark)
    errors = np.array([float(r["error_deg"]) for r in light])
    assert errors.max() <= 0.1
    zen = np.array([float(r["zenith_deg"]) for r in light])
    assert np.max(np.abs(zen - np.array([float(r["input_zenith_deg"]) for r in light]))) <= 0.1


def test_apply_to_readings_without_the_truth(workdir, fitted, qd_csv):
    _, cal, _ = fitted
    data = read_qd_csv(qd_csv)
    plain = workdir / "readings.csv"
    with plain.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["i1_a", "i2_a", "i3_a", "i4_a", "temperature_c"])
        for i in np.flatnonzero(~data.dark)[:5]:
            w.writerow([*map(repr, data.currents_a[i].tolist()), repr(float(data.temperature_c[i]))])
    output = workdir / "readings-applied.csv"
    result = invoke("apply", cal, plain, "-o", output)
    assert result.exit_code == 0, result.output
    header = output.read_text().splitlines()[0]
    assert header == "i1_a,i2_a,i3_a,i4_a,temperature_c,alpha_deg,beta_deg,zenith_deg,azimuth_deg"
    assert "angular error" not in result.stdout


def test_header_command_writes_the_same_header(workdir, fitted):
    _, cal, header = fitted
    again = workdir / "again.h"
    result = invoke("header", cal, "-o", again)
    assert result.exit_code == 0, result.output
    assert again.read_text() == header.read_text()


# --- bad input -----------------------------------------------------------------------------------------------

def test_unknown_method(qd_csv):
    assert_user_error(invoke("fit", "qd", qd_csv, "--method", "seed003"), "--method must be one of", "geometric")


def test_bad_cell(tmp_path, qd_csv):
    lines = qd_csv.read_text().splitlines()
    lines[20] = lines[20].replace(lines[20].split(",")[4], "abc", 1)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    assert_user_error(invoke("fit", "qd", bad), str(bad), "row 20 (line 21)", "column 'i3_a'", "'abc' is not a number")


def test_missing_file(tmp_path, fitted, qd_csv):
    _, cal, _ = fitted
    absent = tmp_path / "absent.csv"
    assert_user_error(invoke("fit", "qd", absent), str(absent), "no such file")
    assert_user_error(invoke("apply", cal, absent, "-o", tmp_path / "o.csv"), "no such file")
    assert_user_error(invoke("apply", tmp_path / "none.json", qd_csv, "-o", tmp_path / "o.csv"), "no such file")


def test_a_cmos_file_given_to_fit_qd(tmp_path):
    path = tmp_path / "cmos.csv"
    path.write_text("zenith_deg,azimuth_deg,x_px,y_px\n0,0,320,240\n")
    assert_user_error(invoke("fit", "qd", path), "CMOS", "sunbench fit cmos")


def test_a_qd_file_given_to_fit_cmos(qd_csv):
    assert_user_error(invoke("fit", "cmos", qd_csv), "missing column(s) x_px, y_px")


def test_only_dark_readings(tmp_path, qd_csv):
    lines = qd_csv.read_text().splitlines()
    dark = [lines[0]] + [line for line in lines[1:] if line.startswith(",,")]
    path = tmp_path / "dark.csv"
    path.write_text("\n".join(dark) + "\n")
    assert_user_error(invoke("fit", "qd", path), str(path), "needs light readings at 8 directions")


def test_a_mixed_sensor_file(tmp_path, qd_csv):
    lines = qd_csv.read_text().splitlines()
    lines[-1] = lines[-1].replace("QD-0001", "QD-0002")
    path = tmp_path / "two.csv"
    path.write_text("\n".join(lines) + "\n")
    assert_user_error(invoke("fit", "qd", path), "holds 2 sensors", "--sensor", "column 'sensor_id'")
    result = invoke("fit", "qd", path, "--sensor", "QD-0001")
    assert result.exit_code == 0, result.output
    assert "297 readings from" in flat(result.stdout)


def test_a_qd_calibration_of_another_version(tmp_path, fitted, qd_csv):
    _, cal, _ = fitted
    document = json.loads(cal.read_text())
    document["version"] = 99
    other = tmp_path / "v99.json"
    other.write_text(json.dumps(document))
    assert_user_error(invoke("apply", other, qd_csv, "-o", tmp_path / "o.csv"), str(other), "version 99",
                      "not supported")
    assert_user_error(invoke("header", other, "-o", tmp_path / "o.h"), "version 99")
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "o.h").exists()


def test_a_qd_calibration_applied_to_a_spot_file(tmp_path, fitted):
    _, cal, _ = fitted
    spots = tmp_path / "spots.csv"
    spots.write_text("x_px,y_px\n1,2\n")
    assert_user_error(invoke("apply", cal, spots, "-o", tmp_path / "o.csv"), "CMOS", "not a QD one")


def test_the_console_script_refuses_bad_input_without_a_traceback(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,i4_a,temperature_c\n10,0,1e-7,nan,1e-7,1e-7,20\n")
    done = sunbench_process("fit", "qd", path, cwd=tmp_path)
    assert_user_error_text(done.stderr, done.returncode, "row 1 (line 2)", "column 'i2_a'", "not a finite number")
    assert done.stdout == ""
