"""bench.css_datafile: the CSS bench data CSV a lab engineer hands to `sunbench fit css`, and its writer."""

from __future__ import annotations

import numpy as np
import pytest
from clitools import BAD_CELLS

from bench.css_datafile import read_css_csv, read_css_frames, write_css_csv
from bench.datafile import DataFileError
from calibration.css.data import CssBenchData
from calibration.css.head import CHANNELS, COLUMNS

HEADER = "zenith_deg,azimuth_deg,pz_uv_a,pz_vis_a,pz_ir_v,temperature_c"
LIGHT = "30,45,4e-6,8e-4,1e-4,25"
DARK = ",,1e-10,5e-9,8e-6,15"


def _write(tmp_path, text: str, name: str = "css.csv", encoding: str = "utf-8"):
    path = tmp_path / name
    path.write_text(text, encoding=encoding)
    return path


def _error(path, **kwargs) -> DataFileError:
    with pytest.raises(DataFileError) as info:
        read_css_frames(path, **kwargs)
    exc = info.value
    assert str(path) in str(exc), "the message must name the file"
    assert exc.path == str(path)
    return exc


def _synthetic(sensor_id: str | None = "CSS-0042", seed: int = 4, channels=CHANNELS) -> CssBenchData:
    rng = np.random.default_rng(seed)
    n_dark, n_light = 6, 40
    n = n_dark + n_light
    zenith = np.concatenate([np.full(n_dark, np.nan), rng.uniform(0, 180, n_light)])
    azimuth = np.concatenate([np.full(n_dark, np.nan), rng.uniform(0, 360, n_light)])
    signals = rng.uniform(1e-10, 1e-4, (n, len(channels))) * np.pi  # irrational digits: repr must be exact
    signals[10, 2] = np.nan  # a clipped channel: no reading of it in that row
    temperature = rng.uniform(10, 40, n).round(2)
    dark = np.arange(n) < n_dark
    check = ~dark & (np.arange(n) % 7 == 0)
    return CssBenchData(zenith, azimuth, signals, temperature, channels=channels, repeat=np.arange(n) % 2,
                        sensor_id=sensor_id, dark=dark, check=check)


def _assert_same(a: CssBenchData, b: CssBenchData) -> None:
    light = ~a.dark
    for name in ("zenith_deg", "azimuth_deg"):
        assert getattr(a, name)[light].tobytes() == getattr(b, name)[light].tobytes(), name
    assert np.isnan(b.zenith_deg[a.dark]).all() and np.isnan(b.azimuth_deg[a.dark]).all()
    assert a.channels == b.channels
    np.testing.assert_array_equal(np.isnan(a.signals), np.isnan(b.signals))
    assert np.nan_to_num(a.signals).tobytes() == np.nan_to_num(b.signals).tobytes()  # bit-identical
    assert a.temperature_c.tobytes() == b.temperature_c.tobytes()
    for name in ("repeat", "dark", "check"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.sensor_id == b.sensor_id


# --- round trip -------------------------------------------------------------------------------------------

def test_round_trip_is_exact(tmp_path):
    data = _synthetic()
    path = tmp_path / "sub" / "css.csv"
    write_css_csv(path, data)
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(["zenith_deg", "azimuth_deg", *COLUMNS, "temperature_c", "repeat", "dark", "check",
                                 "sensor_id"])
    assert lines[1].startswith(",,")  # a dark row has no direction
    assert lines[11].split(",")[4] == ""  # the missing reading: an empty cell
    back = read_css_csv(path)
    _assert_same(data, back)
    np.testing.assert_array_equal(back.row_id, np.arange(1, len(data) + 1))  # the file's data rows


def test_round_trip_of_a_subset_of_detectors_without_sensor(tmp_path):
    channels = ("px_vis", "py_vis", "pz_ir", "mz_uv")
    data = _synthetic(sensor_id=None, channels=channels)
    path = tmp_path / "css.csv"
    write_css_csv(path, data)
    header = path.read_text().splitlines()[0]
    assert header == "zenith_deg,azimuth_deg,px_vis_a,py_vis_a,pz_ir_v,mz_uv_a,temperature_c,repeat,dark,check"
    back = read_css_csv(path)
    _assert_same(data, back)
    assert back.sensor_id is None and back.channels == channels


def test_minimal_file_columns_in_any_order(tmp_path):
    text = "pz_ir_v,temperature_c,px_uv_a,zenith_deg,azimuth_deg\n1e-4,20,3e-6,100,200\n"
    data = read_css_csv(_write(tmp_path, text))
    assert data.channels == ("px_uv", "pz_ir")  # the head's order, whatever the file's
    np.testing.assert_array_equal(data.signals, [[3e-6, 1e-4]])
    assert (data.zenith_deg[0], data.azimuth_deg[0], data.temperature_c[0]) == (100.0, 200.0, 20.0)
    assert data.repeat.tolist() == [0] and not data.dark.any() and not data.check.any() and data.sensor_id is None


def test_comments_blank_lines_bom_and_where(tmp_path):
    text = ("# exported from the bench\n"
            "\n"
            f"{HEADER},dark\n"
            "# dark\n"
            f"{DARK},1\n"
            "   \n"
            f"{LIGHT},0\n")
    frames = read_css_frames(_write(tmp_path, text, encoding="utf-8-sig"))
    assert frames.data.dark.tolist() == [True, False]
    assert frames.where(2) == "row 2 (line 7)"


def test_a_row_may_miss_some_detectors_but_not_all(tmp_path):
    data = read_css_csv(_write(tmp_path, f"{HEADER}\n30,45,,8e-4,1e-4,25\n"))
    assert np.isnan(data.signals[0, 0]) and data.signals[0, 1] == 8e-4
    exc = _error(_write(tmp_path, f"{HEADER}\n{LIGHT}\n30,45,,,,25\n"))
    assert (exc.row, exc.line) == (2, 3) and "at least one detector" in str(exc)


def test_zenith_beyond_90_is_a_direction_of_the_cube(tmp_path):
    data = read_css_csv(_write(tmp_path, f"{HEADER}\n180,0,1e-10,5e-9,8e-6,25\n135,270,1e-10,5e-9,8e-6,25\n"))
    assert data.zenith_deg.tolist() == [180.0, 135.0]
    exc = _error(_write(tmp_path, f"{HEADER}\n{LIGHT}\n181,0,1e-10,5e-9,8e-6,25\n"))
    assert (exc.row, exc.column) == (2, "zenith_deg") and "[0, 180]" in str(exc)


# --- malformed files ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("missing", ["zenith_deg", "azimuth_deg", "temperature_c"])
def test_a_missing_column(tmp_path, missing):
    columns = HEADER.split(",")
    keep = [i for i, c in enumerate(columns) if c != missing]
    text = ",".join(columns[i] for i in keep) + "\n" + ",".join(LIGHT.split(",")[i] for i in keep) + "\n"
    exc = _error(_write(tmp_path, text))
    assert f"missing column(s) {missing}" in str(exc) and "the header has" in str(exc)


def test_no_detector_column_at_all(tmp_path):
    exc = _error(_write(tmp_path, "zenith_deg,azimuth_deg,temperature_c\n10,0,25\n"))
    assert "no detector column" in str(exc) and "px_uv_a" in str(exc) and "<face>_ir_v" in str(exc)


@pytest.mark.parametrize("column, right", [("px_ir_a", "px_ir_v"), ("py_vis_v", "py_vis_a"), ("mz_uv", "mz_uv_a")])
def test_a_detector_column_with_the_wrong_unit(tmp_path, column, right):
    exc = _error(_write(tmp_path, f"zenith_deg,azimuth_deg,{column},temperature_c\n10,0,1e-6,25\n"))
    assert exc.column == column and f"the detector column is {right}" in str(exc)


@pytest.mark.parametrize("cell, words", BAD_CELLS)
def test_a_bad_cell_names_row_line_and_column(tmp_path, cell, words):
    if cell.strip() == "":  # an empty detector cell is a missing reading: empty is bad in a direction's cell
        text = f"{HEADER}\n{LIGHT}\n30,{cell},4e-6,8e-4,1e-4,25\n"
        column = "azimuth_deg"
    else:
        text = f"{HEADER}\n{LIGHT}\n30,45,4e-6,{cell},1e-4,25\n"
        column = "pz_vis_a"
    exc = _error(_write(tmp_path, text))
    assert (exc.row, exc.line, exc.column) == (2, 3, column)
    assert words in str(exc) and f"row 2 (line 3), column '{column}'" in str(exc)


@pytest.mark.parametrize("column, value, words", [
    ("pz_uv_a", "4.2", "out of range for a photodiode"),  # µA written as A
    ("pz_vis_a", "-0.5", "µA × 1e-6"),
    ("pz_ir_v", "120", "out of range for a thermopile"),  # mV written as V
    ("temperature_c", "298.15", "kelvin"),
    ("temperature_c", "-273", "out of range"),
])
def test_wrong_units_are_refused_as_such(tmp_path, column, value, words):
    cells = dict(zip(HEADER.split(","), LIGHT.split(",")))
    cells[column] = value
    text = f"{HEADER}\n{LIGHT}\n" + ",".join(cells.values()) + "\n"
    exc = _error(_write(tmp_path, text))
    assert (exc.row, exc.line, exc.column) == (2, 3, column) and words in str(exc)


def test_flags_and_repeat(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},dark\n{LIGHT},2\n"))
    assert exc.column == "dark" and "not 0 or 1" in str(exc)
    exc = _error(_write(tmp_path, f"{HEADER},dark,check\n{LIGHT},1,1\n"))
    assert exc.column == "check" and "both dark and a check" in str(exc)
    exc = _error(_write(tmp_path, f"{HEADER},repeat\n{LIGHT},1.5\n"))
    assert exc.column == "repeat" and "not a whole number" in str(exc)


def test_a_lit_row_needs_its_direction(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},dark\n,,4e-6,8e-4,1e-4,25,0\n"))
    assert (exc.row, exc.column) == (1, "zenith_deg") and "empty cell" in str(exc)


def test_other_families_files_are_named(tmp_path):
    exc = _error(_write(tmp_path, "zenith_deg,azimuth_deg,x_px,y_px\n0,0,320,240\n"))
    assert "CMOS or camera" in str(exc)
    exc = _error(_write(tmp_path, "zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,i4_a,temperature_c\n0,0,1,1,1,1,20\n"))
    assert "QD sensor's CSV" in str(exc)


def test_sensors_of_a_batch(tmp_path):
    text = f"{HEADER},sensor_id\n{LIGHT},A\n{LIGHT},B\n"
    exc = _error(_write(tmp_path, text))
    assert exc.column == "sensor_id" and "holds 2 sensors" in str(exc)
    data = read_css_csv(tmp_path / "css.csv", sensor_id="B")
    assert len(data) == 1 and data.sensor_id == "B"


def test_empty_files(tmp_path):
    assert "no header row" in str(_error(_write(tmp_path, "")))
    assert "no data rows" in str(_error(_write(tmp_path, HEADER + "\n")))
    assert "cells, the header has" in str(_error(_write(tmp_path, f"{HEADER}\n30,45,4e-6\n")))
