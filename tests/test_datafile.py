"""bench.datafile: the bench data CSV, spot CSVs and calibration JSON a lab engineer hands to sunbench."""

from __future__ import annotations

import json

import numpy as np
import pytest
from clitools import BAD_CELLS

from bench.datafile import (
    DataFileError,
    calibration_document,
    read_bench_csv,
    read_calibration,
    read_spots_csv,
    write_bench_csv,
    write_calibration,
)
from calibration.data import BenchData
from calibration.design import BenchGeometry
from calibration.geometry import incidence_from_stage_angle
from calibration.models import METHODS, fit_calibration
from calibration.synthetic import synthetic_bench_data

HEADER = "zenith_deg,azimuth_deg,x_px,y_px"


@pytest.fixture(scope="module")
def synthetic() -> BenchData:
    return synthetic_bench_data(seed=3)


def _write(tmp_path, text: str, name: str = "bench.csv", encoding: str = "utf-8"):
    path = tmp_path / name
    path.write_text(text, encoding=encoding)
    return path


def _error(path, **kwargs) -> DataFileError:
    with pytest.raises(DataFileError) as info:
        read_bench_csv(path, **kwargs)
    exc = info.value
    assert str(path) in str(exc), "the message must name the file"
    assert exc.path == str(path)
    return exc


def _assert_same(a: BenchData, b: BenchData) -> None:
    for name in ("zenith_deg", "azimuth_deg", "x_px", "y_px"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.sensor_id == b.sensor_id
    if a.repeat is None:
        assert b.repeat is None
    else:
        np.testing.assert_array_equal(a.repeat, b.repeat)


# --- round trip -------------------------------------------------------------------------------------------

def test_round_trip_is_exact(tmp_path, synthetic):
    path = tmp_path / "sub" / "bench.csv"
    write_bench_csv(path, synthetic)
    back = read_bench_csv(path)
    assert len(back) == len(synthetic) == 264
    _assert_same(synthetic, back)
    assert back.sensor_id == "SIM-0001"
    assert back.repeat is not None and back.repeat.max() == 4
    assert back.exposure_ms is None
    # repr floats: bit-identical, not just close
    assert back.x_px.tobytes() == synthetic.x_px.tobytes()
    assert back.y_px.tobytes() == synthetic.y_px.tobytes()


def test_round_trip_with_exposure_and_without_sensor(tmp_path, synthetic):
    exposure = np.linspace(0.1, 3.0, len(synthetic)) / 3.0
    data = BenchData(synthetic.zenith_deg, synthetic.azimuth_deg, synthetic.x_px, synthetic.y_px,
                     repeat=synthetic.repeat, exposure_ms=exposure)
    path = tmp_path / "bench.csv"
    write_bench_csv(path, data)
    assert path.read_text().splitlines()[0] == "zenith_deg,azimuth_deg,x_px,y_px,repeat,exposure_ms"
    back = read_bench_csv(path)
    _assert_same(data, back)
    assert back.sensor_id is None
    np.testing.assert_array_equal(back.exposure_ms, exposure)


def test_comments_blank_lines_and_bom_are_skipped(tmp_path):
    text = ("# bench run 2024-05-01\n"
            "\n"
            f"{HEADER},repeat\n"
            "# centre stage\n"
            "0,0,320.5,240.5,0\n"
            "   \n"
            ",,,,\n"
            "10.5,90,320.5,300.25,1\n"
            "\n")
    path = _write(tmp_path, "\ufeff" + text)
    data = read_bench_csv(path)
    np.testing.assert_array_equal(data.zenith_deg, [0.0, 10.5])
    np.testing.assert_array_equal(data.azimuth_deg, [0.0, 90.0])
    np.testing.assert_array_equal(data.x_px, [320.5, 320.5])
    np.testing.assert_array_equal(data.y_px, [240.5, 300.25])
    np.testing.assert_array_equal(data.repeat, [0, 1])


def test_bom_with_comment_first(tmp_path):
    path = _write(tmp_path, f"# comment\n{HEADER}\n5,45,1,2\n", encoding="utf-8-sig")
    assert path.read_bytes().startswith(b"\xef\xbb\xbf")
    data = read_bench_csv(path)
    assert len(data) == 1 and data.zenith_deg[0] == 5.0


# --- stage angles (seed 003 eq. 8) ------------------------------------------------------------------------

STAGE_HEADER = "stage_zenith_deg,stage_azimuth_deg,x_px,y_px"


def test_stage_angles_are_converted_with_eq8(tmp_path):
    omega = [0.0, 10.0, 20.0, 45.0, 60.0]
    rows = "".join(f"{o},{30 * i},{300 + i},{200 + i}\n" for i, o in enumerate(omega))
    path = _write(tmp_path, f"{STAGE_HEADER}\n{rows}")
    bench = BenchGeometry(lever_arm_mm=136.2, source_distance_mm=710.0)
    data = read_bench_csv(path, bench=bench)
    expected = incidence_from_stage_angle(np.array(omega), 136.2, 710.0)
    np.testing.assert_allclose(data.zenith_deg, expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(data.azimuth_deg, [0.0, 30.0, 60.0, 90.0, 120.0])
    # the zenith is not the stage angle: the lever arm matters
    assert data.zenith_deg[4] - 60.0 > 8.0


@pytest.mark.parametrize("source_mm, omega, theta", [
    (710.0, 10.0, 11.902),
    (710.0, 60.0, 68.620),
    (7100.0, 60.0, 60.943),
])
def test_stage_angles_match_seed003_digest_table(tmp_path, source_mm, omega, theta):
    path = _write(tmp_path, f"{STAGE_HEADER}\n0,0,1,1\n{omega},0,2,2\n")
    data = read_bench_csv(path, bench=BenchGeometry(lever_arm_mm=136.2, source_distance_mm=source_mm))
    assert data.zenith_deg[0] == 0.0
    assert abs(data.zenith_deg[1] - theta) < 1e-3


def test_negative_stage_zenith_turns_the_azimuth(tmp_path):
    path = _write(tmp_path, f"{STAGE_HEADER}\n-60,45,1,1\n60,45,2,2\n-10,270,3,3\n")
    data = read_bench_csv(path, bench=BenchGeometry(lever_arm_mm=136.2, source_distance_mm=710.0))
    assert data.zenith_deg[0] == pytest.approx(68.620, abs=1e-3)
    assert data.zenith_deg[0] == data.zenith_deg[1] > 0
    np.testing.assert_allclose(data.azimuth_deg, [225.0, 45.0, 90.0])  # 270 + 180 wraps to 90
    assert data.zenith_deg[2] == pytest.approx(11.902, abs=1e-3)


def test_stage_angles_need_the_bench_geometry(tmp_path):
    path = _write(tmp_path, f"{STAGE_HEADER}\n10,0,1,1\n")
    exc = _error(path)
    assert "bench geometry" in str(exc)


def test_stage_zenith_beyond_90_is_reported_on_its_row(tmp_path):
    path = _write(tmp_path, f"{STAGE_HEADER}\n10,0,1,1\n85,0,2,2\n")  # Ω = 85° → θ ≈ 95.2°
    exc = _error(path, bench=BenchGeometry(lever_arm_mm=136.2, source_distance_mm=710.0))
    assert (exc.row, exc.line, exc.column) == (2, 3, "stage_zenith_deg")


# --- errors -----------------------------------------------------------------------------------------------

def test_missing_column(tmp_path):
    path = _write(tmp_path, "zenith_deg,azimuth_deg,x_px\n0,0,1\n")
    exc = _error(path)
    assert "y_px" in str(exc) and "missing column" in str(exc)
    assert exc.row is None and exc.line is None


def test_missing_true_and_stage_columns_asks_for_stage_columns(tmp_path):
    path = _write(tmp_path, "zenith_deg,x_px,y_px\n0,1,1\n")
    exc = _error(path)
    assert "stage_zenith_deg" in str(exc) and "stage_azimuth_deg" in str(exc)


@pytest.mark.parametrize("cell, words", BAD_CELLS)
def test_bad_cell_names_row_line_and_column(tmp_path, cell, words):
    path = _write(tmp_path, f"# header comment\n{HEADER}\n0,0,1,1\n# mid comment\n10,0,2,2\n20,90,{cell},3\n")
    exc = _error(path)
    assert (exc.row, exc.line, exc.column) == (3, 6, "x_px")
    assert words in str(exc)
    assert "row 3 (line 6)" in str(exc) and "column 'x_px'" in str(exc)


def test_ragged_row(tmp_path):
    path = _write(tmp_path, f"{HEADER}\n0,0,1,1\n10,0,2\n")
    exc = _error(path)
    assert (exc.row, exc.line, exc.column) == (2, 3, None)
    assert "3 cells, the header has 4" in str(exc)


def test_too_many_cells(tmp_path):
    path = _write(tmp_path, f"{HEADER}\n0,0,1,1,9\n")
    exc = _error(path)
    assert (exc.row, exc.line) == (1, 2)
    assert "5 cells, the header has 4" in str(exc)


def test_duplicate_header_column(tmp_path):
    path = _write(tmp_path, f"# c\n{HEADER},x_px\n0,0,1,1,1\n")
    exc = _error(path)
    assert "duplicate" in str(exc) and "x_px" in str(exc)
    assert exc.line == 2 and exc.row is None


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n\n"])
def test_empty_file(tmp_path, text):
    exc = _error(_write(tmp_path, text))
    assert "empty file" in str(exc)
    assert exc.row is None


def test_header_only(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER}\n# nothing measured\n"))
    assert "no data rows" in str(exc)


@pytest.mark.parametrize("zenith", ["90", "95.5", "-0.5"])
def test_zenith_out_of_range_on_its_row(tmp_path, zenith):
    path = _write(tmp_path, f"{HEADER}\n0,0,1,1\n\n10,0,2,2\n{zenith},0,3,3\n20,0,4,4\n")
    exc = _error(path)
    assert (exc.row, exc.line, exc.column) == (3, 5, "zenith_deg")
    assert "[0, 90)" in str(exc)


def test_missing_file(tmp_path):
    exc = _error(tmp_path / "absent.csv")
    assert "no such file" in str(exc)


def test_not_utf8(tmp_path):
    path = tmp_path / "bench.csv"
    path.write_bytes(b"zenith_deg,azimuth_deg,x_px,y_px\n0,0,\xff\xfe,1\n")
    assert "UTF-8" in str(_error(path))


def _two_sensor_file(tmp_path):
    a = synthetic_bench_data(seed=1, sensor_id="SN-A")
    b = synthetic_bench_data(seed=2, sensor_id="SN-B")
    write_bench_csv(tmp_path / "a.csv", a)
    write_bench_csv(tmp_path / "b.csv", b)
    lines_a = (tmp_path / "a.csv").read_text().splitlines()
    lines_b = (tmp_path / "b.csv").read_text().splitlines()
    path = _write(tmp_path, "\n".join(lines_a + lines_b[1:]) + "\n", name="batch.csv")
    return path, a, b


def test_multi_sensor_file(tmp_path):
    path, a, b = _two_sensor_file(tmp_path)
    exc = _error(path)
    assert exc.column == "sensor_id"
    assert "2 sensors" in str(exc) and "SN-A" in str(exc) and "SN-B" in str(exc) and "--sensor" in str(exc)

    got_b = read_bench_csv(path, sensor_id="SN-B")
    assert len(got_b) == len(b)
    _assert_same(b, got_b)
    got_a = read_bench_csv(path, sensor_id="SN-A")
    _assert_same(a, got_a)

    exc = _error(path, sensor_id="SN-C")
    assert "SN-C" in str(exc) and "SN-A" in str(exc) and exc.column == "sensor_id"


def test_sensor_selection_without_sensor_column(tmp_path):
    exc = _error(_write(tmp_path, f"{HEADER}\n0,0,1,1\n"), sensor_id="SN-A")
    assert "sensor_id" in str(exc) and "SN-A" in str(exc)


def test_non_integer_repeat(tmp_path):
    path = _write(tmp_path, f"{HEADER},repeat\n0,0,1,1,0\n0,0,1,1,1.5\n")
    exc = _error(path)
    assert (exc.row, exc.line, exc.column) == (2, 3, "repeat")
    assert "'1.5' is not a whole number" in str(exc)


def test_integer_valued_repeat_is_fine(tmp_path):
    data = read_bench_csv(_write(tmp_path, f"{HEADER},repeat\n0,0,1,1,2.0\n"))
    np.testing.assert_array_equal(data.repeat, [2])


def test_spots_csv(tmp_path):
    table, x, y = read_spots_csv(_write(tmp_path, "id,x_px,y_px\nA,1.5,2.5\nB,3,4\n"))
    assert table.header == ["id", "x_px", "y_px"]
    np.testing.assert_array_equal(x, [1.5, 3.0])
    np.testing.assert_array_equal(y, [2.5, 4.0])
    with pytest.raises(DataFileError, match="missing column"):
        read_spots_csv(_write(tmp_path, "x,y\n1,2\n", name="s.csv"))


# --- calibration JSON -------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def means(synthetic):
    return synthetic.direction_means()


@pytest.fixture(scope="module")
def physical(means):
    return fit_calibration(means, "physical")


def _saved(tmp_path, calibration, **changes):
    document = calibration_document(calibration, sensor_id="SIM-0001", source="test")
    document.update(changes)
    path = tmp_path / "cal.json"
    write_calibration(path, document)
    return path


@pytest.mark.parametrize("method", list(METHODS))
def test_calibration_round_trip(tmp_path, means, method):
    original = fit_calibration(means, method)
    path = _saved(tmp_path, original)
    calibration, document = read_calibration(path)
    assert type(calibration) is type(original)
    assert calibration.method == method == document["method"]
    assert document["sensor_id"] == "SIM-0001"
    x = np.concatenate([means.x_px, [10.0, 600.0]])
    y = np.concatenate([means.y_px, [470.0, 5.0]])
    z0, a0 = original.apply(x, y)
    z1, a1 = calibration.apply(x, y)
    np.testing.assert_array_equal(z1, z0)
    np.testing.assert_array_equal(a1, a0)


def _calibration_error(path) -> DataFileError:
    with pytest.raises(DataFileError) as info:
        read_calibration(path)
    assert str(path) in str(info.value)
    return info.value


def test_calibration_of_another_version(tmp_path, physical):
    exc = _calibration_error(_saved(tmp_path, physical, version=99))
    assert "version 99" in str(exc) and "not supported" in str(exc)


def test_calibration_of_another_format(tmp_path, physical):
    exc = _calibration_error(_saved(tmp_path, physical, format="acme.calibration"))
    assert "not a sunbench calibration" in str(exc)


def test_calibration_json_that_is_a_list(tmp_path):
    path = _write(tmp_path, "[1, 2, 3]", name="cal.json")
    assert "not a sunbench calibration" in str(_calibration_error(path))


def test_calibration_not_json(tmp_path):
    path = _write(tmp_path, "zenith_deg,azimuth_deg\n1,2\n", name="cal.json")
    assert "not a JSON calibration file" in str(_calibration_error(path))


def test_calibration_missing_file(tmp_path):
    assert "no such file" in str(_calibration_error(tmp_path / "none.json"))


def test_calibration_unknown_method(tmp_path, physical):
    exc = _calibration_error(_saved(tmp_path, physical, method="magic"))
    assert "unknown calibration method 'magic'" in str(exc)


def test_calibration_missing_parameters(tmp_path, physical):
    path = _saved(tmp_path, physical)
    document = json.loads(path.read_text())
    del document["parameters"]["gap_mm"]
    path.write_text(json.dumps(document))
    exc = _calibration_error(path)
    assert "missing parameters" in str(exc) and "gap_mm" in str(exc)

    del document["parameters"]
    path.write_text(json.dumps(document))
    assert "no \"parameters\" object" in str(_calibration_error(path))
