"""The CSS family on the command line: `sunbench export` of a CSS run, `fit css`, `apply` and `header` of a CSS
calibration, and how they refuse bad input. The data come from a small CSS campaign on the simulated bench
(examples/bench-sim-css.yaml with a head whose detectors follow the Kelly law): the simulator's own physics, not the
fit's model."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from ccompiler import c_compiler
from clitools import assert_user_error, assert_user_error_text, flat, invoke, sunbench_process

from bench.benchfile import BenchFile
from bench.campaign import Campaign, CssSweepProcedure
from bench.catalogue import Catalogue
from bench.css_datafile import read_css_csv
from bench.families.css import bench_data
from bench.runner import open_session, run_campaign
from calibration.css.calibrate import diode_parameters_from_document
from calibration.css.head import CHANNELS, COLUMNS

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli-css")


@pytest.fixture(scope="module")
def css_run(workdir):
    """A small CSS sweep (rings every 15°, two temperatures) on the simulated head: (catalogue path, run id)."""
    path = workdir / "catalogue.sqlite"
    catalogue = Catalogue(path)
    document = yaml.safe_load((ROOT / "examples" / "bench-sim-css.yaml").read_text())
    document["simulation"]["css"]["response"] = "kelly"
    session = open_session(BenchFile.model_validate(document), catalogue, time_scale=0.0)
    try:
        campaign = Campaign(name="css-small", plan="css-sweep", sensors=("CSS-0001",), methods=("kelly",),
                            css_sweep=CssSweepProcedure(step_deg=15, around=6, repeats=2, temperatures_c=(25, 40),
                                                        dark_repeats=4, check_directions=12))
        (run_id,) = run_campaign(campaign, session, confirm_mount=lambda *a: True)
    finally:
        session.close()
        catalogue.close()
    return path, run_id


@pytest.fixture(scope="module")
def css_csv(workdir, css_run) -> Path:
    """`sunbench export RUN --format csv -o css.csv` of the CSS run."""
    catalogue, run_id = css_run
    path = workdir / "css.csv"
    result = invoke("export", run_id, "--format", "csv", "-o", path, "--catalogue", catalogue)
    assert result.exit_code == 0, result.output
    return path


@pytest.fixture(scope="module")
def fitted(workdir, css_csv):
    """`fit css css.csv -o CAL.json --header CAL.h --json FIG.json`, run once for the module."""
    cal, header, figures = workdir / "CAL.json", workdir / "CAL.h", workdir / "FIG.json"
    result = invoke("fit", "css", css_csv, "-o", cal, "--header", header, "--json", figures)
    assert result.exit_code == 0, result.output
    return result, cal, header, figures


# --- export -------------------------------------------------------------------------------------------------

def test_export_of_a_css_run_is_the_css_bench_csv(css_run, css_csv):
    catalogue, run_id = css_run
    header = css_csv.read_text().splitlines()[0]
    assert header == ",".join(["zenith_deg", "azimuth_deg", *COLUMNS, "temperature_c", "repeat", "dark", "check",
                               "sensor_id"])
    data = read_css_csv(css_csv)
    with Catalogue(catalogue, readonly=True) as cat:
        truth = bench_data(cat, cat.lineage(run_id), sensor_id="CSS-0001")
        assert len(data) == len(truth) == len(cat.readings(run_id))
    assert data.sensor_id == "CSS-0001" and data.channels == CHANNELS
    assert np.nan_to_num(data.signals).tobytes() == np.nan_to_num(truth.signals).tobytes()
    light = ~truth.dark
    assert data.zenith_deg[light].tobytes() == truth.zenith_deg[light].tobytes()
    assert np.nanmax(data.zenith_deg) == pytest.approx(180.0, abs=0.01)  # the bottom face's centre: behind the head
    for name in ("temperature_c", "repeat", "dark", "check"):
        np.testing.assert_array_equal(getattr(data, name), getattr(truth, name), err_msg=name)
    assert int(data.dark.sum()) == 8 and int(data.check.sum()) == 2 * 12


def test_export_as_json_names_the_family(css_run):
    catalogue, run_id = css_run
    result = invoke("export", run_id, "--catalogue", catalogue, "--format", "json")
    assert result.exit_code == 0 and json.loads(result.stdout)["run"]["family"] == "css"


def test_show_prints_the_held_out_figures(css_run):
    catalogue, run_id = css_run
    result = invoke("show", run_id, "--catalogue", catalogue)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "(css)" in text and "calibration kelly law (chosen): 18 detector(s)" in text
    assert "the Sun's direction held out RMS" in text and "check directions RMS" in text


# --- fit css ------------------------------------------------------------------------------------------------

def test_fit_prints_every_detector_and_the_held_out_figures(fitted):
    result, _, _, _ = fitted
    text = flat(result.stdout)
    assert "Detectors (kelly law)" in text and "each fitted parameter ± 1σ" in text
    for channel in CHANNELS:
        line = next(line for line in result.stdout.splitlines() if line.strip("│ ").startswith(channel + " "))
        assert line.count("±") >= 3, line  # scale, offset, shape … each with its 1σ
    assert "The Sun's direction [°]" in text and "held out *" in text and "check directions" in text
    assert "fitted directions" in text and "RMS / stated 1σ" in text
    assert "of 18 detector(s) from" in text and "sensor CSS-0001" in text and "18 calibrated, kelly law" in text
    # without --response both laws are fitted and the better held out kept: on this Kelly-law head, the Kelly law
    assert "response laws fitted: kelly (held-out RMS" in text and "spline (held-out RMS" in text
    assert "the kelly law kept" in text


def test_fit_writes_the_css_calibration_document(fitted, css_csv):
    result, cal, _, figures = fitted
    document = json.loads(cal.read_text())
    assert (document["family"], document["version"], document["response"]) == ("css", 1, "kelly")
    assert document["sensor_id"] == "CSS-0001" and document["source"] == str(css_csv)
    assert document["software"].startswith("sunbench ") and document["created_utc"]
    assert set(document["diodes"]) == set(CHANNELS) and all(d["valid"] for d in document["diodes"].values())
    assert document["heldout"]["sun"]["heldout"]["n_points"] > 50
    printed = flat(result.stdout)
    assert all(f"warning: {flat(w)}" in printed for w in document["warnings"])  # what the fit said, kept
    numbers = json.loads(figures.read_text())
    assert numbers["metrics"]["held_out"] == document["heldout"]["sun"]["heldout"]
    assert numbers["metrics"]["channels"] == list(CHANNELS) and numbers["sensor_id"] == "CSS-0001"


def test_fit_of_a_subset_of_detectors_with_the_power_law(workdir, css_csv):
    rows = list(csv.reader(css_csv.read_text().splitlines()))
    keep = [i for i, name in enumerate(rows[0]) if not name.endswith(("_uv_a", "_ir_v"))]
    path = workdir / "vis.csv"
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows([[row[i] for i in keep] for row in rows])
    cal = workdir / "vis.json"
    result = invoke("fit", "css", path, "--response", "power", "-o", cal)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "Detectors (power law)" in text and "of 6 detector(s) from" in text and "6 calibrated, power law" in text
    document = json.loads(cal.read_text())
    assert set(document["diodes"]) == {f"{f}_vis" for f in ("px", "py", "mx", "my", "pz", "mz")}
    assert document["response"] == "power" and "power" in document["diodes"]["pz_vis"]["parameters"]


# --- apply and header -----------------------------------------------------------------------------------------

def test_apply_gives_the_direction_its_uncertainty_and_its_error_per_row(workdir, fitted, css_csv):
    _, cal, _, _ = fitted
    output = workdir / "applied.csv"
    result = invoke("apply", cal, css_csv, "-o", output)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "directions written" in text and "8 dark row(s)" in text and "angular error" in text
    with output.open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0])[:2] == ["input_zenith_deg", "input_azimuth_deg"]
    assert list(rows[0])[-5:] == ["zenith_deg", "azimuth_deg", "sigma_deg", "faces_lit", "error_deg"]
    dark = [r for r in rows if r["dark"] == "1"]
    assert len(dark) == 8 and all(r["zenith_deg"] == r["error_deg"] == "" and r["faces_lit"] == "0" for r in dark)
    found = [r for r in rows if r["zenith_deg"]]
    assert len(found) > len(rows) / 2
    errors = np.array([float(r["error_deg"]) for r in found])
    assert np.median(errors) < 0.5  # the estimator's own figures are the calibration's (its held-out ones)
    assert all(float(r["sigma_deg"]) > 0 and int(r["faces_lit"]) >= 2 for r in found)


def test_apply_to_readings_without_the_truth(workdir, fitted, css_csv):
    _, cal, _, _ = fitted
    data = read_css_csv(css_csv)
    plain = workdir / "readings.csv"
    with plain.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*COLUMNS, "temperature_c"])
        for i in np.flatnonzero(~data.dark)[:5]:
            w.writerow([*map(repr, data.signals[i].tolist()), repr(float(data.temperature_c[i]))])
    output = workdir / "readings-applied.csv"
    result = invoke("apply", cal, plain, "-o", output)
    assert result.exit_code == 0, result.output
    assert output.read_text().splitlines()[0] == ",".join([*COLUMNS, "temperature_c", "zenith_deg", "azimuth_deg",
                                                            "sigma_deg", "faces_lit"])
    assert "angular error" not in result.stdout


def test_the_header_compiles_and_computes_the_models_signals(workdir, fitted):
    _, cal, header, _ = fitted
    text = header.read_text()
    assert "sunbench_css_signal" in text and "CSS-0001" in text and "held-out error: the Sun's direction RMS" in text
    assert "SBCSS_AZIMUTH_DECIDEG" in text and "bpw_sun, epd_sun rebuilt from this calibration" in text
    assert_header_computes_the_model(workdir / "kelly", header, cal, 1e-12)


def test_the_spline_law_is_fitted_written_and_exported_to_c(workdir, css_csv):
    """`fit css --response spline` of the visible photodiodes: the document holds each detector's knots and
    coefficients, the table says so, and the C header evaluates the very same spline (to 1e-12 of the signal)."""
    rows = list(csv.reader(css_csv.read_text().splitlines()))
    keep = [i for i, name in enumerate(rows[0]) if not name.endswith(("_uv_a", "_ir_v"))]
    path = workdir / "vis-spline.csv"
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows([[row[i] for i in keep] for row in rows])
    cal, header = workdir / "spline.json", workdir / "spline.h"
    result = invoke("fit", "css", path, "--response", "spline", "-o", cal, "--header", header)
    assert result.exit_code == 0, result.output
    text = flat(result.stdout)
    assert "Detectors (spline law)" in text and "6 calibrated, spline law" in text and "spline knots" in text
    assert "response laws fitted" not in text  # one law asked for, one fitted
    document = json.loads(cal.read_text())
    entry = document["diodes"]["pz_vis"]
    knots = entry["spline_knots_deg"]
    assert document["response"] == "spline" and knots[0] == 0.0 and 60.0 < knots[-1] <= 90.0
    assert [f"spline_{k}" for k in range(1, len(knots) + 1)] == [n for n in entry["parameters"] if
                                                                 n.startswith("spline_")]
    assert "spline_1" in entry["covariance"]["names"] and "kappa" not in entry["parameters"]
    again = workdir / "spline-again.h"
    assert invoke("header", cal, "-o", again).exit_code == 0 and again.read_text() == header.read_text()
    assert "SUNBENCH_CSS_SPLINE_C" in header.read_text()
    assert_header_computes_the_model(workdir / "spline", header, cal, 1e-12)


def assert_header_computes_the_model(folder: Path, header: Path, cal: Path, tolerance: float) -> None:
    """The header compiles warning-free, and its sunbench_css_signal() gives the Python model's signals of the
    document's detectors at 400 random directions and temperatures to `tolerance` (relative)."""
    folder.mkdir(exist_ok=True)
    compiler = c_compiler()
    done = subprocess.run([compiler, "-fsyntax-only", "-Wall", "-Wextra", "-Werror", "-x", "c", str(header)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    # the C model gives the Python model's signals, to rounding
    program = folder / "signals.c"
    program.write_text(f'#include <stdio.h>\n#include "{header}"\n'
                       "int main(void) { int k; double s[3], t;\n"
                       '  while (scanf("%d %lf %lf %lf %lf", &k, &s[0], &s[1], &s[2], &t) == 5)\n'
                       '    printf("%.17g\\n", sunbench_css_signal(k, s, t));\n  return 0; }\n')
    exe = folder / "signals"
    done = subprocess.run([compiler, "-std=c99", "-Wall", "-Werror", str(program), "-o", str(exe), "-lm"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rng = np.random.default_rng(3)
    vectors = rng.normal(size=(400, 3))
    vectors /= np.linalg.norm(vectors, axis=1, keepdims=True)
    temperatures = rng.uniform(10, 40, 400)
    lines, want = [], []
    for diode in diode_parameters_from_document(json.loads(cal.read_text())):
        k = CHANNELS.index(diode.channel)
        lines += [f"{k} {v[0]!r} {v[1]!r} {v[2]!r} {t!r}" for v, t in zip(vectors.tolist(), temperatures.tolist())]
        want.append(diode.signal(vectors, temperatures))
    done = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True, text=True)
    got = np.array(done.stdout.split(), float).reshape(len(want), -1)
    want = np.array(want)
    assert np.max(np.abs(got - want) / np.maximum(np.abs(want), 1e-15)) < tolerance


def test_header_command_writes_the_same_header(workdir, fitted):
    _, cal, header, _ = fitted
    again = workdir / "again.h"
    result = invoke("header", cal, "-o", again)
    assert result.exit_code == 0, result.output
    assert again.read_text() == header.read_text()


# --- bad input -----------------------------------------------------------------------------------------------

def test_unknown_response(css_csv):
    assert_user_error(invoke("fit", "css", css_csv, "--response", "cosine"),
                      "--response must be kelly, power or spline")


def test_bad_cell(tmp_path, css_csv):
    lines = css_csv.read_text().splitlines()
    cells = lines[20].split(",")
    cells[COLUMNS.index("py_vis_a") + 2] = "abc"
    lines[20] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    assert_user_error(invoke("fit", "css", bad), str(bad), "row 20 (line 21)", "column 'py_vis_a'",
                      "'abc' is not a number")


def test_currents_in_microamperes(tmp_path, css_csv):
    lines = css_csv.read_text().splitlines()
    cells = lines[30].split(",")
    j = COLUMNS.index("pz_vis_a") + 2
    cells[j] = repr(float(cells[j] or 0) * 1e6 + 1.0)
    lines[30] = ",".join(cells)
    bad = tmp_path / "micro.csv"
    bad.write_text("\n".join(lines) + "\n")
    assert_user_error(invoke("fit", "css", bad), "row 30 (line 31)", "column 'pz_vis_a'", "in amperes")


def test_missing_file(tmp_path, fitted, css_csv):
    _, cal, _, _ = fitted
    absent = tmp_path / "absent.csv"
    assert_user_error(invoke("fit", "css", absent), str(absent), "no such file")
    assert_user_error(invoke("apply", cal, absent, "-o", tmp_path / "o.csv"), "no such file")


def test_other_families_files(tmp_path, css_csv):
    path = tmp_path / "cmos.csv"
    path.write_text("zenith_deg,azimuth_deg,x_px,y_px\n0,0,320,240\n")
    assert_user_error(invoke("fit", "css", path), "CMOS or camera", "not a CSS one")
    assert_user_error(invoke("fit", "qd", css_csv), "missing column(s) i1_a")


def test_a_mixed_sensor_file(tmp_path, css_csv):
    lines = css_csv.read_text().splitlines()
    lines[-1] = lines[-1].replace("CSS-0001", "CSS-0002")
    path = tmp_path / "two.csv"
    path.write_text("\n".join(lines) + "\n")
    assert_user_error(invoke("fit", "css", path), "holds 2 sensors", "--sensor", "column 'sensor_id'")


def test_a_css_calibration_of_another_version(tmp_path, fitted, css_csv):
    _, cal, _, _ = fitted
    document = json.loads(cal.read_text())
    document["version"] = 99
    other = tmp_path / "v99.json"
    other.write_text(json.dumps(document))
    assert_user_error(invoke("apply", other, css_csv, "-o", tmp_path / "o.csv"), str(other), "version 99",
                      "not supported")
    assert_user_error(invoke("header", other, "-o", tmp_path / "o.h"), "version 99")
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "o.h").exists()


def test_a_css_calibration_applied_to_a_spot_file(tmp_path, fitted):
    _, cal, _, _ = fitted
    spots = tmp_path / "spots.csv"
    spots.write_text("x_px,y_px\n1,2\n")
    assert_user_error(invoke("apply", cal, spots, "-o", tmp_path / "o.csv"), "CMOS or camera", "not a CSS one")


def test_the_console_script_refuses_bad_input_without_a_traceback(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("zenith_deg,azimuth_deg,pz_vis_a,temperature_c\n10,0,nan,20\n")
    done = sunbench_process("fit", "css", path, cwd=tmp_path)
    assert_user_error_text(done.stderr, done.returncode, "row 1 (line 2)", "column 'pz_vis_a'", "not a finite number")
    assert done.stdout == ""


def test_the_example_campaign_dry_runs_on_the_example_bench(tmp_path):
    """The README's commands: examples/css-sweep.yaml on examples/bench-sim-css.yaml passes its preflight."""
    examples = ROOT / "examples"
    result = invoke("run", examples / "css-sweep.yaml", "--dry-run", "--time-scale", 0, "--catalogue",
                    tmp_path / "c.sqlite", "--bench", examples / "bench-sim-css.yaml")
    assert result.exit_code == 0, result.output
    assert flat(result.stdout).startswith("preflight: 753 points, 1524 frames"), result.stdout
