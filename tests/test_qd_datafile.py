"""bench.qd_datafile: the QD bench data CSV a lab engineer hands to `sunbench fit qd`, and its writer."""

from __future__ import annotations

import numpy as np
import pytest
from clitools import BAD_CELLS

import bench.datafile as datafile
import bench.qd_datafile as qd_datafile
from bench.datafile import DataFileError
from bench.qd_datafile import read_qd_csv, read_qd_frames, read_qd_readings, write_qd_csv
from calibration.qd.data import QdBenchData
from calibration.qd.design import DEFAULT_QD

HEADER = "zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,i4_a,temperature_c"
LIGHT = "10,45,1e-7,2e-7,1.5e-7,1.2e-7,25"
DARK = ",,1e-10,1.1e-10,0.9e-10,1e-10,15"


def _write(tmp_path, text: str, name: str = "qd.csv", encoding: str = "utf-8"):
    path = tmp_path / name
    path.write_text(text, encoding=encoding)
    return path


def _error(path, **kwargs) -> DataFileError:
    with pytest.raises(DataFileError) as info:
        read_qd_frames(path, **kwargs)
    exc = info.value
    assert str(path) in str(exc), "the message must name the file"
    assert exc.path == str(path)
    return exc


def _synthetic(sensor_id: str | None = "QD-0042", seed: int = 4) -> QdBenchData:
    rng = np.random.default_rng(seed)
    n_dark, n_light = 6, 30
    n = n_dark + n_light
    zenith = np.concatenate([np.full(n_dark, np.nan), rng.uniform(0, 60, n_light)])
    azimuth = np.concatenate([np.full(n_dark, np.nan), rng.uniform(0, 360, n_light)])
    currents = rng.uniform(1e-10, 2e-6, (n, 4)) * np.pi  # irrational digits: repr must be exact
    temperature = rng.uniform(10, 40, n).round(2)
    dark = np.arange(n) < n_dark
    check = ~dark & (np.arange(n) % 5 == 0)
    return QdBenchData(zenith, azimuth, currents, temperature, repeat=np.arange(n) % 3, sensor_id=sensor_id,
                       dark=dark, check=check)


def _assert_same(a: QdBenchData, b: QdBenchData) -> None:
    light = ~a.dark
    for name in ("zenith_deg", "azimuth_deg"):
        assert getattr(a, name)[light].tobytes() == getattr(b, name)[light].tobytes(), name
    assert np.isnan(b.zenith_deg[a.dark]).all() and np.isnan(b.azimuth_deg[a.dark]).all()
    assert a.currents_a.tobytes() == b.currents_a.tobytes()  # bit-identical, not just close
    assert a.temperature_c.tobytes() == b.temperature_c.tobytes()
    for name in ("repeat", "dark", "check"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.sensor_id == b.sensor_id


# --- round trip -------------------------------------------------------------------------------------------

def test_round_trip_is_exact(tmp_path):
    data = _synthetic()
    path = tmp_path / "sub" / "qd.csv"
    write_qd_csv(path, data)
    lines = path.read_text().splitlines()
    assert lines[0] == HEADER + ",repeat,dark,check,sensor_id"
    assert lines[1].startswith(",,")  # a dark row has no direction
    back = read_qd_csv(path)
    _assert_same(data, back)
    np.testing.assert_array_equal(back.row_id, np.arange(1, len(data) + 1))  # the file's data rows


def test_round_trip_without_sensor(tmp_path):
    data = _synthetic(sensor_id=None)
    path = tmp_path / "qd.csv"
    write_qd_csv(path, data)
    assert "sensor_id" not in path.read_text().splitlines()[0]
    back = read_qd_csv(path)
    _assert_same(data, back)
    assert back.sensor_id is None


def test_minimal_file_and_defaults(tmp_path):
    data = read_qd_csv(_write(tmp_path, f"{HEADER}\n{LIGHT}\n"))
    assert len(data) == 1
    np.testing.assert_array_equal(data.currents_a, [[1e-7, 2e-7, 1.5e-7, 1.2e-7]])
    assert (data.zenith_deg[0], data.azimuth_deg[0], data.temperature_c[0]) == (10.0, 45.0, 25.0)
    assert data.repeat.tolist() == [0] and not data.dark.any() and not data.check.any() and data.sensor_id is None


def test_quadrant_columns_are_quadrants_1_to_4_in_order(tmp_path):
    """i1_a … i4_a are eq. 2.1's Q1 … Q4 whatever order the columns come in."""
    text = "i4_a,temperature_c,i2_a,zenith_deg,i1_a,azimuth_deg,i3_a\n4e-7,20,2e-7,5,1e-7,90,3e-7\n"
    data = read_qd_csv(_write(tmp_path, text))
    np.testing.assert_array_equal(data.currents_a, [[1e-7, 2e-7, 3e-7, 4e-7]])


def test_comments_blank_lines_bom_and_design_comments(tmp_path):
    text = ("# diaphragm_diameter_m: 8e-5\n"
            "# pinhole_height_m = 2.5e-5\n"
            "# a comment that is not a key\n"
            "\n"
            f"{HEADER},dark\n"
            "# dark sweep\n"
            f"{DARK},1\n"
            "   \n"
            f"{LIGHT},0\n")
    frames = read_qd_frames(_write(tmp_path, text, encoding="utf-8-sig"))
    assert (tmp_path / "qd.csv").read_bytes().startswith(b"\xef\xbb\xbf")
    assert frames.data.dark.tolist() == [True, False]
    assert frames.design.diaphragm_diameter_m == 8e-5 and frames.design.pinhole_height_m == 2.5e-5
    assert frames.design.gap_m == DEFAULT_QD.gap_m
    assert frames.given == {"diaphragm_diameter_m": 8e-5, "pinhole_height_m": 2.5e-5}
    assert frames.where(2) == "row 2 (line 9)"


def test_bom_before_the_header(tmp_path):
    data = read_qd_csv(_write(tmp_path, "\ufeff" + f"{HEADER}\n{LIGHT}\n"))
    assert data.zenith_deg[0] == 10.0  # the first column is zenith_deg, not '\ufeffzenith_deg'


def test_an_unknown_header_comment_names_its_line(tmp_path):
    exc = _error(_write(tmp_path, f"# pixel_pitch_mm: 0.0099\n{HEADER}\n{LIGHT}\n"))
    assert exc.line == 1 and "unknown header comment 'pixel_pitch_mm'" in str(exc)
    assert "diaphragm_diameter_m" in str(exc)


@pytest.mark.parametrize("value, words", [("abc", "is not a number"), ("inf", "not a finite number"),
                                          ("-1e-4", "must be positive")])
def test_a_bad_design_comment(tmp_path, value, words):
    exc = _error(_write(tmp_path, f"# pinhole_height_m: {value}\n{HEADER}\n{LIGHT}\n"))
    assert words in str(exc)


def test_dark_rows_may_leave_the_direction_empty(tmp_path):
    text = (f"{HEADER},dark,check\n{DARK},1,0\n,,1e-10,1e-10,1e-10,1e-10,35,1,0\n{LIGHT},0,1\n"
            "95,0,1e-10,1e-10,1e-10,1e-10,25,1,0\n")
    data = read_qd_csv(_write(tmp_path, text))
    assert data.dark.tolist() == [True, True, False, True] and data.check.tolist() == [False, False, True, False]
    assert np.isnan(data.zenith_deg[:2]).all()
    assert np.isnan(data.alpha_deg[3])  # a dark row's direction (here 95°) is never used


def test_multi_sensor_file(tmp_path):
    text = f"{HEADER},dark,sensor_id\n{LIGHT},0,QD-A\n{LIGHT},0,QD-B\n{DARK},1,QD-B\n"
    path = _write(tmp_path, text)
    exc = _error(path)
    assert exc.column == "sensor_id" and "2 sensors" in str(exc) and "--sensor" in str(exc)
    b = read_qd_csv(path, sensor_id="QD-B")
    assert len(b) == 2 and b.sensor_id == "QD-B"
    np.testing.assert_array_equal(b.row_id, [2, 3])  # rows keep their names in the file
    exc = _error(path, sensor_id="QD-C")
    assert "QD-C" in str(exc) and "QD-A" in str(exc)


def test_sensor_selection_without_sensor_column(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER}\n{LIGHT}\n"), sensor_id="QD-A")
    assert "sensor_id" in str(exc) and "QD-A" in str(exc)


# --- errors -----------------------------------------------------------------------------------------------

def test_missing_column(tmp_path):
    exc = _error(_write(tmp_path, "zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,temperature_c\n0,0,1,1,1,20\n"))
    assert "missing column(s) i4_a" in str(exc) and exc.row is None


def test_missing_temperature(tmp_path):
    exc = _error(_write(tmp_path, "zenith_deg,azimuth_deg,i1_a,i2_a,i3_a,i4_a\n0,0,1e-7,1e-7,1e-7,1e-7\n"))
    assert "temperature_c" in str(exc)


def test_a_cmos_file_is_named_as_such(tmp_path):
    exc = _error(_write(tmp_path, "zenith_deg,azimuth_deg,x_px,y_px\n0,0,320,240\n"))
    assert "CMOS" in str(exc) and "sunbench fit cmos" in str(exc)


@pytest.mark.parametrize("cell, words", BAD_CELLS)  # the CMOS file's, "  " included: one reader
def test_bad_current_names_row_line_and_column(tmp_path, cell, words):
    path = _write(tmp_path, f"# comment\n{HEADER}\n{LIGHT}\n# mid\n{LIGHT}\n10,0,1e-7,{cell},1e-7,1e-7,25\n")
    exc = _error(path)
    assert (exc.row, exc.line, exc.column) == (3, 6, "i2_a")
    assert words in str(exc) and "row 3 (line 6)" in str(exc) and "column 'i2_a'" in str(exc)


@pytest.mark.parametrize("column", ["zenith_deg", "azimuth_deg", "temperature_c", "i4_a"])
@pytest.mark.parametrize("cell", ["x", "nan", "inf"])
def test_bad_cell_in_every_numeric_column(tmp_path, column, cell):
    values = dict(zip(HEADER.split(","), LIGHT.split(",")))
    values[column] = cell
    exc = _error(_write(tmp_path, f"{HEADER}\n{LIGHT}\n{','.join(values.values())}\n"))
    assert (exc.row, exc.line, exc.column) == (2, 3, column)


def test_a_light_row_needs_its_direction(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},dark\n{DARK},1\n,,1e-7,1e-7,1e-7,1e-7,20,0\n"))
    assert (exc.row, exc.line, exc.column) == (2, 3, "zenith_deg") and "empty cell" in str(exc)


def test_a_dark_row_with_a_bad_direction_cell(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},dark\nabc,,1e-10,1e-10,1e-10,1e-10,20,1\n"))
    assert (exc.row, exc.column) == (1, "zenith_deg") and "'abc' is not a number" in str(exc)


@pytest.mark.parametrize("zenith", ["90", "95.5", "-0.5"])
def test_zenith_out_of_range_on_a_light_row(tmp_path, zenith):
    path = _write(tmp_path, f"{HEADER}\n{LIGHT}\n\n{LIGHT}\n{zenith},0,1e-7,1e-7,1e-7,1e-7,25\n{LIGHT}\n")
    exc = _error(path)
    assert (exc.row, exc.line, exc.column) == (3, 5, "zenith_deg")
    assert "[0, 90)" in str(exc)


@pytest.mark.parametrize("column, cell", [("dark", "2"), ("dark", "0.5"), ("dark", "yes"), ("check", "-1"),
                                          ("check", "")])
def test_flags_are_0_or_1(tmp_path, column, cell):
    exc = _error(_write(tmp_path, f"{HEADER},{column}\n{LIGHT},0\n{LIGHT},{cell}\n"))
    assert (exc.row, exc.line, exc.column) == (2, 3, column)


def test_a_row_both_dark_and_check(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},dark,check\n{LIGHT},0,1\n{DARK},1,1\n"))
    assert (exc.row, exc.column) == (2, "check") and "dark" in str(exc)


def test_currents_in_microamperes_are_refused(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER}\n{LIGHT}\n10,45,0.1,0.2,0.15,0.12,25\n"))
    assert (exc.row, exc.column) == (2, "i1_a") and "amperes" in str(exc)


def test_temperature_in_kelvin_is_refused(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER}\n10,45,1e-7,2e-7,1.5e-7,1.2e-7,298.15\n"))
    assert (exc.row, exc.column) == (1, "temperature_c") and "Celsius" in str(exc)


def test_non_integer_repeat(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},repeat\n{LIGHT},0\n{LIGHT},1.5\n"))
    assert (exc.row, exc.line, exc.column) == (2, 3, "repeat") and "'1.5' is not a whole number" in str(exc)


def test_ragged_row(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER}\n{LIGHT}\n10,0,1e-7\n"))
    assert (exc.row, exc.line, exc.column) == (2, 3, None) and "3 cells, the header has 7" in str(exc)


def test_duplicate_column(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER},i2_a\n{LIGHT},1e-7\n"))
    assert "duplicate" in str(exc) and "i2_a" in str(exc) and exc.line == 1


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n", "\ufeff"])
def test_empty_file(tmp_path, text):
    assert "empty file" in str(_error(_write(tmp_path, text)))


def test_header_only(tmp_path):
    assert "no data rows" in str(_error(_write(tmp_path, f"{HEADER},dark\n# nothing measured\n")))


def test_missing_file(tmp_path):
    assert "no such file" in str(_error(tmp_path / "absent.csv"))


def test_not_utf8(tmp_path):
    path = tmp_path / "qd.csv"
    path.write_bytes(f"{HEADER}\n10,0,\xff\xfe,1,1,1,20\n".encode("latin-1"))
    assert "UTF-8" in str(_error(path))


def test_a_huge_file_is_refused_before_it_is_read(tmp_path, monkeypatch):
    path = _write(tmp_path, f"{HEADER}\n" + f"{LIGHT}\n" * 200)
    monkeypatch.setattr(qd_datafile, "MAX_FILE_BYTES", 1024)
    monkeypatch.setattr(datafile, "read_csv_table", lambda p: pytest.fail("read a file over the cap"))
    exc = _error(path)
    assert "too large" in str(exc)


def test_the_size_cap_is_far_above_a_real_grid(tmp_path):
    """±40° at 1° with check points, 3 repeats: (81² + 80²) × 3 = 38 883 rows, each as long as the writer makes it
    (full-precision floats and a sensor id: ~135 bytes; about 5 MB in all)."""
    path = tmp_path / "qd.csv"
    write_qd_csv(path, _synthetic())
    row_bytes = max(len(line) + 1 for line in path.read_bytes().splitlines()[1:])
    assert 100 < row_bytes < 200
    assert qd_datafile.MAX_FILE_BYTES > 10 * (81**2 + 80**2) * 3 * row_bytes


# --- readings to apply a calibration to ---------------------------------------------------------------------

def test_readings_without_the_truth(tmp_path):
    readings = read_qd_readings(_write(tmp_path, "i1_a,i2_a,i3_a,i4_a,temperature_c,note\n1e-7,2e-7,1e-7,1e-7,20,a\n"))
    assert not readings.has_truth and readings.table.header[-1] == "note"
    np.testing.assert_array_equal(readings.currents_a, [[1e-7, 2e-7, 1e-7, 1e-7]])


def test_readings_with_some_truth(tmp_path):
    readings = read_qd_readings(_write(tmp_path, f"{HEADER}\n{LIGHT}\n,,1e-7,1e-7,1e-7,1e-7,20\n"))
    assert readings.has_truth and readings.zenith_deg[0] == 10.0 and np.isnan(readings.zenith_deg[1])


def test_readings_with_half_a_direction(tmp_path):
    with pytest.raises(DataFileError) as info:
        read_qd_readings(_write(tmp_path, f"{HEADER}\n10,,1e-7,1e-7,1e-7,1e-7,20\n"))
    assert (info.value.row, info.value.column) == (1, "azimuth_deg")
