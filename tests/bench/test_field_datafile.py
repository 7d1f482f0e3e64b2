"""The field data CSV (bench/field_datafile.py, README "Field data CSV"): what it reads, and how it refuses bad
files naming the row and the column."""

from __future__ import annotations

import numpy as np
import pytest

from bench.datafile import DataFileError
from bench.field_datafile import read_field_csv, write_field_csv


def _write(tmp_path, text: str):
    path = tmp_path / "field.csv"
    path.write_text(text)
    return path


def test_a_written_file_reads_back(tmp_path):
    path = tmp_path / "out.csv"
    t0 = 1569729497.0
    write_field_csv(path, {"time_utc": [t0, t0 + 30, t0 + 60], "x_px": [1.5, 2.5, np.nan],
                           "y_px": [3.25, 4.0, np.nan], "peak_dn": [500, 510, np.nan],
                           "exposure_ms": [2.0, 2.0, 2.0], "status": ["ok", "ok", "NoSpotError"]},
                    metadata={"latitude_deg": 54.8437, "longitude_deg": 83.093, "heading_deg": None})
    data = read_field_csv(path)
    assert data.time_utc[0] == "2019-09-29T03:58:17.000Z"
    np.testing.assert_allclose(data.t_s, [t0, t0 + 30, t0 + 60])
    assert data.ok.tolist() == [True, True, False]
    assert data.x_px[1] == 2.5 and np.isnan(data.x_px[2])
    assert data.metadata == {"latitude_deg": 54.8437, "longitude_deg": 83.093}
    assert data.has_spots and data.zenith_deg is None


def test_directions_zones_and_optional_columns(tmp_path):
    path = _write(tmp_path, "# latitude_deg: 49.3052028\n# longitude_deg: 14.1633511\n"
                            "time_utc,zenith_deg,azimuth_deg,pressure_hpa,cloud,sensor_id\n"
                            "2013-04-18T10:00:00+02:00,40.0,10.0,980,,A1\n"
                            "2013-04-18T08:01:00,41.0,11.0,,1,A1\n")
    data = read_field_csv(path)
    assert data.t_s[1] - data.t_s[0] == 60.0  # +02:00 converted; no zone is UTC
    assert data.cloud.tolist() == [False, True]
    assert data.sensor_id == "A1" and np.isnan(data.numbers["pressure_hpa"][1])


@pytest.mark.parametrize("text, fragments", [
    ("x_px,y_px\n1,2\n", ["missing column time_utc"]),
    ("time_utc,peak_dn\n2019-09-29T03:58:17,1\n", ["x_px, y_px", "zenith_deg, azimuth_deg"]),
    ("time_utc,x_px,y_px\n", ["no data rows"]),
    ("time_utc,x_px,y_px\nyesterday,1,2\n", ["row 1", "time_utc", "ISO 8601"]),
    ("time_utc,x_px,y_px\n2019-09-29T04:00:00,1,2\n2019-09-29T03:00:00,1,2\n", ["row 2", "backwards"]),
    ("time_utc,x_px,y_px\n2019-09-29T04:00:00,1,abc\n", ["row 1", "y_px", "not a number"]),
    ("time_utc,zenith_deg,azimuth_deg\n2019-09-29T04:00:00,190,2\n", ["row 1", "zenith_deg", "outside"]),
    ("# latitude: 5\ntime_utc,x_px,y_px\n2019-09-29T04:00:00,1,2\n", ["unknown header comment"]),
    ("time_utc,x_px,y_px,sensor_id\n2019-09-29T04:00:00,1,2,A\n2019-09-29T04:00:01,1,2,B\n", ["2 sensors"]),
    ("time_utc,x_px,y_px\n2019-09-29T04:00:00,1\n", ["row 1", "cells"]),
])
def test_bad_files_are_refused_naming_the_problem(tmp_path, text, fragments):
    with pytest.raises(DataFileError) as caught:
        read_field_csv(_write(tmp_path, text))
    for fragment in fragments:
        assert fragment in str(caught.value)


def test_a_failed_reading_may_leave_its_cells_empty(tmp_path):
    data = read_field_csv(_write(tmp_path, "time_utc,x_px,y_px,status\n2019-09-29T04:00:00,,,NoSpotError\n"
                                           "2019-09-29T04:00:30,5,6,ok\n"))
    assert data.ok.tolist() == [False, True]


def test_the_sensors_own_cloud_flag_is_read_apart_from_the_operators_and_counts_as_cloud(tmp_path):
    """`spot_cloud` is the sensor's flag (the camera's, from its spot's shape), `cloud` the operator's mark; the
    analysis leaves a reading either flags out of the clear statistics, and says how many the sensor flagged."""
    from bench.field_analysis import analyse_field

    data = read_field_csv(_write(tmp_path, "time_utc,zenith_deg,azimuth_deg,cloud,spot_cloud,status\n"
                                           "2013-04-18T08:00:00,20,10,0,0,ok\n"
                                           "2013-04-18T08:01:00,20,11,1,,ok\n"
                                           "2013-04-18T08:02:00,20,12,,1,ok\n"
                                           "2013-04-18T08:03:00,,,,1,NoSpotError\n"))
    assert data.cloud.tolist() == [False, True, False, False]
    assert data.spot_cloud.tolist() == [False, False, True, True]
    analysis = analyse_field(data, None, do_compare=False)
    assert analysis.cloudy.tolist() == [False, True, True, False]  # a reading without a spot is no cloud's
    assert any("1 readings flagged as cloud by the sensor itself" in note for note in analysis.notes)
    assert read_field_csv(_write(tmp_path, "time_utc,x_px,y_px\n2019-09-29T04:00:00,1,2\n")).spot_cloud is None
    with pytest.raises(DataFileError, match=r"row 1.*spot_cloud.*whole number"):
        read_field_csv(_write(tmp_path, "time_utc,x_px,y_px,spot_cloud\n2019-09-29T04:00:00,1,2,0.5\n"))
