"""The camera family on the command line: `sunbench run` of a camera campaign, `export`, `fit camera`, `apply` and
`header` of a camera calibration and how they refuse bad input; then the same camera outdoors, `field simulate`,
`field compare` and `field locate` with that calibration.

The bench data come from examples/camera-grid.yaml on the simulated camera bench (examples/bench-sim-camera.yaml):
the simulator's own optics, not the fit's model. The field day is seed 001's: Písek, 18 April 2013, 08–10 UTC, the
camera on a bracket tilted toward the Sun (its field of view is 44° × 33°)."""

from __future__ import annotations

import csv
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ccompiler import c_compiler
from clitools import BAD_CELLS, assert_user_error, flat, invoke

from bench.camera_datafile import read_camera_frames
from bench.field_datafile import read_field_csv
from calibration.camera import camera_from_document, zenith_azimuth
from calibration.field.locate import distance_km
from calibration.geometry import direction_vector

ROOT = Path(__file__).resolve().parents[1]
#: Seed 001's field day (digest §4: Písek, 18 Apr 2013, 08–10 UTC) and the bracket that keeps the Sun in the frame
FIELD = {"--start": "2013-04-18T08:00:00Z", "--lat": 49.3052028, "--lon": 14.1633511, "--alt": 378.0,
         "--heading": 115.0, "--roll": 19.97, "--pitch": 40.04}


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli-camera")


@pytest.fixture(scope="module")
def fitted(workdir):
    """`sunbench run` of the example camera campaign, `export` of its bench data and `fit camera` of it (with a C
    header), run once for the module."""
    catalogue = workdir / "catalogue.sqlite"
    ran = invoke("run", ROOT / "examples/camera-grid.yaml", "--bench", ROOT / "examples/bench-sim-camera.yaml",
                 "--time-scale", 0, "--catalogue", catalogue, "--yes")
    assert ran.exit_code == 0, ran.output
    run_id = ran.output.strip().splitlines()[-1]
    data = workdir / "camera.csv"
    assert invoke("export", run_id, "-o", data, "--catalogue", catalogue).exit_code == 0
    cal, header = workdir / "cal.json", workdir / "cal.h"
    result = invoke("fit", "camera", data, "-o", cal, "--header", header)
    assert result.exit_code == 0, result.output
    return result, data, cal, header


def _row(output: str, name: str) -> list[float]:
    line = next(ln for ln in output.splitlines() if re.match(rf"\W*{re.escape(name)}", ln))
    return [float(v) for v in re.findall(r"-?\d+\.\d+|\b\d+\b", line)]


# --- fit, apply, header ---------------------------------------------------------------------------------------

def test_fit_prints_the_held_out_figures_per_scheme_and_the_fit(fitted):
    result, data, cal, _ = fitted
    text = flat(result.stdout)
    groups, spots, rms, worst = _row(result.stdout, "rings out")
    assert groups == 7 and rms <= 0.02 and worst <= 0.02
    groups, spots, rms, worst = _row(result.stdout, "azimuths out")
    assert groups == 20 and rms <= 0.02 and worst <= 0.02
    assert _row(result.stdout, "fit (at the nodes)")[0] == 250
    for words in ("fx_px", "k1", "p2", "rot_z_deg", "± 1σ", "repeat scatter", "χ²/dof", "250 spots from",
                  "sensor CAM-0001", "frame 640×480 px", "held out RMS"):
        assert words in text, words
    document = json.loads(cal.read_text())
    assert (document["format"], document["version"], document["family"], document["method"]) == (
        "sunbench.calibration", 1, "camera", "opencv")
    assert document["sensor_id"] == "CAM-0001" and document["source"] == str(data)
    assert set(document["metrics"]["held_out"]) >= {"rings", "azimuths", "worst_scheme"}
    assert 25 < document["design"]["fov_half_deg"] < 30  # the frame's corners, through the fitted lens
    assert set(document["sigma"]) >= {"fx_px", "k1", "rot_z_deg"}


def test_the_c_header_compiles_and_agrees_with_the_model(fitted, workdir):
    _, _, cal, header = fitted
    text = header.read_text()
    assert "sunbench_sun_direction" in text and "CAM-0001" in text and "held-out error: RMS" in text
    model = camera_from_document(json.loads(cal.read_text()))
    pixels = np.random.default_rng(3).uniform([0, 0], [639, 479], (40, 2))
    calls = "".join(f'    s = sunbench_sun_direction({float(x)!r}, {float(y)!r}, &z, &a); '
                    f'printf("%d %.17g %.17g\\n", s, z, a);\n' for x, y in pixels)
    main = workdir / "main.c"
    main.write_text(f'#include <stdio.h>\n#include "{header.name}"\nint main(void) {{\n    double z, a; int s;\n'
                    f"{calls}    return 0;\n}}\n")
    program = workdir / "main"
    done = subprocess.run([c_compiler(), "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-o", str(program),
                           str(main), "-lm"], capture_output=True, text=True, cwd=workdir)
    assert done.returncode == 0, done.stderr
    rows = np.array([[float(v) for v in line.split()] for line in
                     subprocess.run([str(program)], capture_output=True, text=True, check=True).stdout.splitlines()])
    zenith, azimuth = zenith_azimuth(model, pixels)
    assert np.all(rows[:, 0] == 0)
    assert np.abs(rows[:, 1] - zenith).max() < 1e-9
    assert np.abs((rows[:, 2] - azimuth + 180) % 360 - 180).max() < 1e-9


def test_apply_turns_spots_into_directions(fitted, workdir):
    _, data, cal, _ = fitted
    output = workdir / "applied.csv"
    result = invoke("apply", cal, data, "-o", output)
    assert result.exit_code == 0, result.output
    assert "250 directions written" in flat(result.stdout) and "camera model of CAM-0001" in flat(result.stdout)
    with output.open() as fh:
        rows = list(csv.DictReader(row for row in fh if not row.startswith("#")))
    assert list(rows[0])[:2] == ["input_zenith_deg", "input_azimuth_deg"] and list(rows[0])[-2:] == [
        "zenith_deg", "azimuth_deg"]
    column = lambda name: [float(r[name]) for r in rows]  # noqa: E731
    given = direction_vector(column("input_zenith_deg"), column("input_azimuth_deg"))
    found = direction_vector(column("zenith_deg"), column("azimuth_deg"))
    error = np.degrees(np.arccos(np.clip(np.sum(given * found, axis=1), -1, 1)))
    assert error.max() < 0.02  # the fit's residual at the nodes


def test_header_command_writes_the_same_header(fitted, workdir):
    _, _, cal, header = fitted
    again = workdir / "again.h"
    result = invoke("header", cal, "-o", again)
    assert result.exit_code == 0, result.output
    assert again.read_text() == header.read_text()


# --- bad input -----------------------------------------------------------------------------------------------

def _edited(fitted, tmp_path, row: int, column: str, value: str) -> Path:
    """The exported CSV with one cell changed (`row` is the data row, 1-based)."""
    _, data, _, _ = fitted
    lines = data.read_text().splitlines()
    header = lines[2].split(",")
    cells = lines[2 + row].split(",")
    cells[header.index(column)] = value
    lines[2 + row] = ",".join(cells)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("cell, words", BAD_CELLS[:3])
def test_a_bad_cell_is_named_by_row_line_and_column(fitted, tmp_path, cell, words):
    path = _edited(fitted, tmp_path, 4, "y_px", cell)
    assert_user_error(invoke("fit", "camera", path), str(path), "row 4 (line 7)", "column 'y_px'", words)


@pytest.mark.parametrize("column, value, words", [
    ("zenith_deg", "95", ["zenith 95° must lie in [0, 90)"]),
    ("x_px", "700", ["700 px is outside the frame's 640 columns", "--width-px"]),
    ("repeat", "1.5", ["'1.5' is not a whole number"]),
    ("exposure_ms", "-2", ["exposure -2 ms must be positive"]),
])
def test_a_value_out_of_range_is_named(fitted, tmp_path, column, value, words):
    path = _edited(fitted, tmp_path, 10, column, value)
    assert_user_error(invoke("fit", "camera", path), "row 10 (line 13)", f"column '{column}'", *words)


def test_files_of_other_shapes_are_refused_saying_what_they_are(tmp_path):
    cases = {
        "missing.csv": ("zenith_deg,azimuth_deg,x_px\n1,2,3\n", ["missing column(s) y_px"]),
        "qd.csv": ("zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,i4_a,temperature_c\n1,2,0,0,0,0,25\n",
                   ["QD sensor's CSV", "sunbench fit qd"]),
        "stage.csv": ("stage_zenith_deg,stage_azimuth_deg,x_px,y_px\n1,2,3,4\n", ["stage angles"]),
        "header.csv": ("# pixel_pitch_mm: 0.003\nzenith_deg,azimuth_deg,x_px,y_px\n1,2,3,4\n",
                       ["unknown header comment 'pixel_pitch_mm'", "line 1"]),
        "two.csv": ("zenith_deg,azimuth_deg,x_px,y_px,sensor_id\n1,2,3,4,A\n1,2,3,4,B\n", ["2 sensors", "--sensor"]),
        "empty.csv": ("zenith_deg,azimuth_deg,x_px,y_px\n", ["no data rows"]),
        "frame.csv": ("# width_px: 10.5\nzenith_deg,azimuth_deg,x_px,y_px\n1,2,3,4\n", ["width_px 10.5"]),
    }
    for name, (text, words) in cases.items():
        path = tmp_path / name
        path.write_text(text)
        assert_user_error(invoke("fit", "camera", path), str(path), *words)
    assert_user_error(invoke("fit", "camera", tmp_path / "absent.csv"), "no such file")


def test_too_few_spots_is_a_user_error_not_a_traceback(tmp_path):
    path = tmp_path / "few.csv"
    path.write_text("zenith_deg,azimuth_deg,x_px,y_px\n0,0,320,240\n0,0,320.1,240\n")
    assert_user_error(invoke("fit", "camera", path), str(path))


def test_a_broken_camera_calibration_is_refused_naming_the_field(fitted, tmp_path):
    _, data, cal, _ = fitted
    document = json.loads(cal.read_text())
    for change, words in ((lambda d: d["model"].pop("k1"), "missing field `k1`"),
                          (lambda d: d.update(version=2), "version 2"),
                          (lambda d: d["model"].update(fx_px="800"), "fx_px"),
                          (lambda d: d.pop("model"), "missing field `model`")):
        broken = json.loads(json.dumps(document))
        change(broken)
        path = tmp_path / "broken.json"
        path.write_text(json.dumps(broken))
        assert_user_error(invoke("apply", path, data, "-o", tmp_path / "out.csv"), str(path), words)
        assert_user_error(invoke("header", path, "-o", tmp_path / "out.h"), words)


# --- the same camera outdoors -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def day(fitted, workdir):
    """`field simulate` of the camera of the bench file (its serial, its lens) on seed 001's day, one reading a
    minute for two hours, clear at first and clouds after (the default sky), the truth beside it."""
    args = [a for item in FIELD.items() for a in item]
    result = invoke("field", "simulate", "--bench", ROOT / "examples/bench-sim-camera.yaml", "-o", workdir / "day.csv",
                    "--truth", workdir / "t.json", "--hours", 2, "--interval", 60, *args)
    assert result.exit_code == 0, result.output
    assert "tilted roll 20°, pitch 40° (an inclinometer)" in flat(result.output)
    return workdir / "day.csv", workdir / "t.json", fitted[2]


def test_the_simulated_camera_day_is_a_field_csv_with_the_cameras_own_cloud_flag(day):
    path, truth_path, _ = day
    data = read_field_csv(path)
    truth = json.loads(truth_path.read_text())
    assert truth["sensor"] == {"family": "camera", "serial": "CAM-0001"}
    assert len(data) == 121 and data.ok.mean() > 0.9  # the bracket keeps the Sun in the frame
    assert data.metadata["roll_deg"] == 20.0 and data.metadata["pitch_deg"] == 40.0  # the inclinometer's 0.1°
    assert data.spot_cloud is not None
    clouds = np.array(truth["clouds"])
    covered = (clouds[:, 0] >= 0.1) & data.ok
    clear = (clouds[:, 0] == 0) & (clouds[:, 1] > 0.99) & data.ok
    print(f"\nthe camera's shape flag: {int(data.spot_cloud[covered].sum())} of {int(covered.sum())} readings with a "
          f"cloud over ≥ 10 % of the disc, {int(data.spot_cloud[clear].sum())} of {int(clear.sum())} clear ones")
    assert data.spot_cloud[clear].mean() <= 0.05


def test_compare_gives_a_small_clear_sky_error_and_locate_covers_the_truth(day):
    """The camera's calibration frame is its housing's (the bench camera sat square on its fixture), so with the
    heading fitted and the level as the inclinometer gave it (to 0.1°), the clear-sky error is that reading's
    rounding; with the level fitted too, what the bench calibration left. `locate` with the level known to 0.05°
    puts the site within its stated uncertainty of the truth."""
    path, truth_path, cal = day
    truth = json.loads(truth_path.read_text())
    heading = invoke("field", "compare", path, "--cal", cal, "--heading-fit")
    assert heading.exit_code == 0, heading.output
    n, zenith_rms, azimuth_rms, vector_rms = _row(heading.output, "clear")[:4]
    print(f"\nheading fitted: clear zenith {zenith_rms:.4f}°, azimuth {azimuth_rms:.4f}°, vector {vector_rms:.4f}° "
          f"over {n:.0f} readings")
    assert vector_rms < 0.1
    level = invoke("field", "compare", path, "--cal", cal, "--heading-fit", "--level-fit")
    assert level.exit_code == 0, level.output
    n, zenith_rms, azimuth_rms, vector_rms = _row(level.output, "clear")[:4]
    fitted = re.search(r"heading ([\d.]+)° \(fitted\), roll (-?[\d.]+)°, pitch (-?[\d.]+)°", level.output)
    print(f"heading and level fitted ({fitted[1]}°, roll {fitted[2]}°, pitch {fitted[3]}°; true "
          f"{truth['mount']['heading_deg']}°, {truth['mount']['roll_deg']}°, {truth['mount']['pitch_deg']}°): clear "
          f"zenith {zenith_rms:.4f}°, azimuth {azimuth_rms:.4f}°, vector {vector_rms:.4f}° over {n:.0f} readings")
    assert n >= 50 and vector_rms < 0.01
    assert abs(float(fitted[1]) - truth["mount"]["heading_deg"]) < 0.05
    assert abs(float(fitted[2]) - truth["mount"]["roll_deg"]) < 0.02
    assert abs(float(fitted[3]) - truth["mount"]["pitch_deg"]) < 0.02
    assert "flagged as cloud by the sensor itself" in flat(level.output)

    located = invoke("field", "locate", path, "--cal", cal, "--level-sd", 0.05, "--json", path.with_suffix(".json"))
    assert located.exit_code == 0, located.output
    location = json.loads(path.with_suffix(".json").read_text())["location"]
    site = truth["site"]
    error = float(distance_km(site["latitude_deg"], site["longitude_deg"], location["latitude_deg"],
                              location["longitude_deg"]))
    sigma = max(location["sd_latitude_km"], location["sd_longitude_km"])
    print(f"located {location['latitude_deg']:.4f}, {location['longitude_deg']:.4f}: {error:.2f} km from the truth, "
          f"1σ {location['sd_latitude_km']:.2f} × {location['sd_longitude_km']:.2f} km, heading "
          f"{location['heading_deg']:.3f}° (true {truth['mount']['heading_deg']}°)")
    assert error < 3 * sigma
    assert abs(location["heading_deg"] - truth["mount"]["heading_deg"]) < 3 * max(location["sd_heading_deg"], 0.01)


def test_the_camera_field_file_with_the_bench_data_reader(fitted):
    """The exported bench data read back as the fit reads them: one sensor, its frame size from the header."""
    _, data, _, _ = fitted
    frames = read_camera_frames(data)
    assert len(frames.data) == 250 and frames.data.sensor_id == "CAM-0001"
    assert (frames.data.width_px, frames.data.height_px) == (640, 480) and frames.rows[0] == 1 and frames.lines[0] == 4
    assert np.all(frames.exposure_ms > 0)
