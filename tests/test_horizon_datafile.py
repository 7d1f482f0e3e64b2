"""The Horizon bench data CSV (bench.horizon_datafile): written and read back bit for bit, edge times and phases alike,
the cones of a scan paired without a `scan` column, and every malformed file refused with a DataFileError naming the
row, its line and the column."""

from __future__ import annotations

import numpy as np
import pytest
from horizontools import synthetic

from bench.datafile import DataFileError
from bench.horizon_datafile import read_horizon_csv, read_horizon_frames, write_horizon_csv


@pytest.fixture(scope="module")
def data():
    small = synthetic(rolls=np.array([-20.0, 0.0, 20.0]), pitches=np.array([-10.0, 10.0]), repeats=2,
                      check=[(5.0, 3.0, 68.0)])
    phases = small.phase_in_deg.copy()
    phases[3] = np.nan  # an edge the module did not find
    return type(small)(small.roll_deg, small.pitch_deg, small.cone, small.phase_out_deg, phases, small.disc_radius_deg,
                       scan=small.scan, repeat=small.repeat, check=small.check, sensor_id="HZ-7")


def test_written_data_read_back_bit_for_bit(tmp_path, data):
    path = tmp_path / "hz.csv"
    temperature = np.linspace(20, 21, len(data))
    write_horizon_csv(path, data, temperature_c=temperature)
    frames = read_horizon_frames(path)
    back = frames.data
    for name in ("roll_deg", "pitch_deg", "disc_radius_deg", "phase_out_deg"):
        assert getattr(back, name).tobytes() == getattr(data, name).tobytes(), name
    assert np.isnan(back.phase_in_deg[3]) and np.nan_to_num(back.phase_in_deg).tobytes() == \
        np.nan_to_num(data.phase_in_deg).tobytes()
    for name in ("cone", "scan", "repeat", "check"):
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name), err_msg=name)
    assert back.sensor_id == "HZ-7" and frames.temperature_c.tobytes() == temperature.tobytes()
    assert back.row_id.tolist() == list(range(1, len(data) + 1)) and frames.where(2) == "row 2 (line 3)"


def _times_csv(data, path, *, scan=False, period=1.002):
    """The same scans as edge times after the index mark with a period, the way a module reports them."""
    lines = ["roll_deg,pitch_deg,cone,t_out_s,t_in_s,period_s,disc_radius_deg,repeat,check"
             + (",scan" if scan else "")]
    for i in range(len(data)):
        t = [("" if not np.isfinite(p) else repr(float(p) / 360.0 * period)) for p in (data.phase_out_deg[i],
                                                                                     data.phase_in_deg[i])]
        lines.append(f"{float(data.roll_deg[i])!r},{float(data.pitch_deg[i])!r},{data.cone[i]},{t[0]},{t[1]},"
                     f"{period!r},{float(data.disc_radius_deg[i])!r},{data.repeat[i]},{int(data.check[i])}"
                     + (f",{data.scan[i]}" if scan else ""))
    path.write_text("# the horizon sensor HZ-7\n" + "\n".join(lines) + "\n")
    return path


def test_times_and_periods_are_phases_and_the_cones_of_a_scan_are_paired(tmp_path, data):
    back = read_horizon_csv(_times_csv(data, tmp_path / "t.csv"))
    assert np.allclose(back.phase_out_deg, data.phase_out_deg, atol=1e-9, rtol=0)
    assert np.isnan(back.phase_in_deg[3])
    # without a scan column the k-th cone-1 and cone-2 rows at one pose and repeat share a scan, as the file's did
    same = back.scan[:, None] == back.scan[None, :]
    assert np.array_equal(same, data.scan[:, None] == data.scan[None, :])
    assert np.unique(back.scan).size == len(data) // 2


TIMES = "roll_deg,pitch_deg,cone,t_out_s,t_in_s,period_s,disc_radius_deg,temperature_c"


@pytest.mark.parametrize("header, row, words, column", [
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "0,0,3,66,294,68", "a cone is 1 or 2",
     "cone"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "0,0,1.5,66,294,68", "not a whole number",
     "cone"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "95,0,1,66,294,68", "|roll| < 90°",
     "roll_deg"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "0,0,1,66,294,95", "0 < ρ < 90°",
     "disc_radius_deg"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "0,0,1,366,294,68", "not in [0, 360)",
     "phase_out_deg"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "0,0,1,abc,294,68", "not a number",
     "phase_out_deg"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg", "0,nan,1,66,294,68", "not a finite",
     "pitch_deg"),
    (TIMES, "0,0,1,184.5,815.5,1000,68,20", "0 < T ≤ 60 s", "period_s"),
    (TIMES, "0,0,1,1.2,0.8,1.0,68,20", "not within the revolution", "t_out_s"),
    (TIMES, "0,0,1,0.2,0.8,1.0,68,300", "not kelvin", "temperature_c"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg,check", "0,0,1,66,294,68,2",
     "not 0 or 1", "check"),
])
def test_a_bad_cell_is_named_by_row_line_and_column(tmp_path, header, row, words, column):
    path = tmp_path / "bad.csv"
    good = "0,0,2,0.2,0.8,1.0,68,20" if header == TIMES else "0,0,2,66,294,68" + ",0" * (header.count(",") - 5)
    path.write_text(f"{header}\n{good}\n{row}\n")
    with pytest.raises(DataFileError) as info:
        read_horizon_csv(path)
    assert words in str(info.value) and info.value.column == column
    assert (info.value.row, info.value.line) == (2, 3)


@pytest.mark.parametrize("text, words", [
    ("roll_deg,pitch_deg,cone,disc_radius_deg\n0,0,1,68\n", "no edge columns"),
    ("roll_deg,pitch_deg,cone,t_out_s,t_in_s,disc_radius_deg\n0,0,1,0.2,0.8,68\n", "missing column(s) period_s"),
    ("roll_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg\n0,1,66,294,68\n", "missing column(s) pitch_deg"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,t_out_s,t_in_s,period_s,disc_radius_deg\n"
     "0,0,1,66,294,0.2,0.8,1,68\n", "give one or the other"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg\n", "no data rows"),
    ("zenith_deg,azimuth_deg,x_px,y_px\n1,2,3,4\n", "a CMOS or camera sensor's CSV"),
    ("zenith_deg,azimuth_deg,pz_vis_a,temperature_c\n1,2,1e-6,20\n", "a CSS head's CSV"),
    ("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg,sensor_id\n0,0,1,66,294,68,A\n"
     "0,0,1,66,294,68,B\n", "holds 2 sensors"),
])
def test_a_file_that_is_no_horizon_data_says_why(tmp_path, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataFileError, match=None) as info:
        read_horizon_csv(path)
    assert words in str(info.value)


def test_two_rows_of_one_cone_in_one_scan_are_refused(tmp_path):
    path = tmp_path / "dup.csv"
    path.write_text("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg,scan\n"
                    "0,0,1,66,294,68,4\n0,0,2,66,294,68,4\n1,0,1,66,294,68,4\n")
    with pytest.raises(DataFileError) as info:
        read_horizon_csv(path)
    assert "scan 4 has two rows of cone 1" in str(info.value) and (info.value.row, info.value.line) == (3, 4)


def test_the_ifov_half_angle_travels_in_a_header_comment(tmp_path, data):
    """The design's IFOV half-angle α (whose limb-curvature bias the fit models) is written as ``# ifov_half_angle_deg:
    …`` and read back; without it the data carries none (the fit then takes the design's 2°); an unknown comment or an α
    out of range is refused, naming the line or the value."""
    from dataclasses import replace

    path = tmp_path / "hz.csv"
    write_horizon_csv(path, replace(data, ifov_half_angle_deg=1.5))
    assert path.read_text().startswith("# ifov_half_angle_deg: 1.5\n")
    assert read_horizon_csv(path).ifov_half_angle_deg == 1.5
    write_horizon_csv(path, data)
    assert read_horizon_csv(path).ifov_half_angle_deg is None
    body = path.read_text()
    path.write_text("# ifov_deg: 2\n" + body)
    with pytest.raises(DataFileError, match="unknown header comment 'ifov_deg'.*ifov_half_angle_deg"):
        read_horizon_csv(path)
    path.write_text("# ifov_half_angle_deg: 45\n" + body)
    with pytest.raises(DataFileError, match="IFOV half-angle"):
        read_horizon_csv(path)


# --- a file of several sensors ---------------------------------------------------------------------------------------

def _two_sensors(data, *, scan: bool, swap_cones: bool = False) -> str:
    """Sensors A and B measured at the same poses, their rows interleaved (A's scan, then B's), each numbering its own
    scans from 0; B's phases 1° on from A's. `swap_cones`: B's rows of a scan in the order cone 2, cone 1 (a scan's
    rows of A then stand round B's: A cone 1, B cone 2, B cone 1, A cone 2)."""
    header = "roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg,repeat,check,sensor_id" \
        + (",scan" if scan else "")

    def row(i, sensor, shift):
        cells = [repr(float(data.roll_deg[i])), repr(float(data.pitch_deg[i])), str(data.cone[i])]
        cells += ["" if not np.isfinite(p) else repr(float(np.mod(p + shift, 360.0)))
                  for p in (data.phase_out_deg[i], data.phase_in_deg[i])]
        cells += [repr(float(data.disc_radius_deg[i])), str(data.repeat[i]), str(int(data.check[i])), sensor]
        return ",".join(cells + ([str(data.scan[i])] if scan else []))

    lines = [header]
    for s in np.unique(data.scan):
        one, two = np.flatnonzero(data.scan == s)
        if swap_cones:
            lines += [row(one, "A", 0.0), row(two, "B", 1.0), row(one, "B", 1.0), row(two, "A", 0.0)]
        else:
            lines += [row(one, "A", 0.0), row(two, "A", 0.0), row(one, "B", 1.0), row(two, "B", 1.0)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("scan", [True, False])
def test_each_sensor_of_a_batch_is_read_with_its_own_scans(tmp_path, data, scan):
    """Two sensors in one file, each numbering its scans from 0: the chosen sensor's rows are taken before its scans
    are paired and checked, so neither refuses as "scan 0 has two rows of cone 1", and each keeps its own phases,
    its cones of a scan together and its rows named by the file's row."""
    path = tmp_path / "two.csv"
    path.write_text(_two_sensors(data, scan=scan))
    for sensor, shift, first in (("A", 0.0, 1), ("B", 1.0, 3)):
        back = read_horizon_csv(path, sensor_id=sensor)
        assert back.sensor_id == sensor and len(back) == len(data)
        assert np.allclose(back.phase_out_deg, np.mod(data.phase_out_deg + shift, 360.0), atol=1e-12)
        assert np.array_equal(back.scan[:, None] == back.scan[None, :], data.scan[:, None] == data.scan[None, :])
        assert back.row_id[:2].tolist() == [first, first + 1] and back.row_id[2] == first + 4
    with pytest.raises(DataFileError, match="holds 2 sensors"):
        read_horizon_csv(path)


def test_without_a_scan_column_the_cones_are_paired_within_one_sensor(tmp_path, data):
    """Rows of two sensors at the same pose and repeat, in the order A cone 1, B cone 2, B cone 1, A cone 2: each
    sensor's cone 1 and cone 2 make one scan, never A's cone 1 with B's cone 2."""
    from bench.horizon_datafile import _pair_scans

    path = tmp_path / "two.csv"
    path.write_text(_two_sensors(data, scan=False, swap_cones=True))
    for sensor in ("A", "B"):
        back = read_horizon_csv(path, sensor_id=sensor)
        assert np.array_equal(back.scan[:, None] == back.scan[None, :], data.scan[:, None] == data.scan[None, :])
        assert np.unique(back.scan).size == len(data) // 2
    # the pairing itself keys on the sensor: the same four rows (cones 1, 2, 1, 2) taken as one sensor's, they pair
    # in order; as A, B, B, A, each sensor's two rows pair
    pose = [np.zeros(4)] * 3 + [np.zeros(4, int), np.zeros(4, bool), np.array([1, 2, 1, 2])]
    assert _pair_scans(*pose).tolist() == [0, 0, 1, 1]
    assert _pair_scans(*pose, ["A", "B", "B", "A"]).tolist() == [0, 1, 1, 0]


def test_a_duplicate_scan_of_the_chosen_sensor_names_its_row_in_the_file(tmp_path):
    path = tmp_path / "dup.csv"
    path.write_text("roll_deg,pitch_deg,cone,phase_out_deg,phase_in_deg,disc_radius_deg,scan,sensor_id\n"
                    "0,0,1,66,294,68,0,A\n0,0,1,66,294,68,0,B\n0,0,2,66,294,68,0,B\n1,0,1,66,294,68,0,B\n"
                    "0,0,2,66,294,68,0,A\n")
    assert len(read_horizon_csv(path, sensor_id="A")) == 2
    with pytest.raises(DataFileError) as info:
        read_horizon_csv(path, sensor_id="B")
    assert "scan 0 has two rows of cone 1" in str(info.value) and (info.value.row, info.value.line) == (4, 5)
