"""Issue 10, items 8 and 11: every limit explicit. Bad or abusive input is refused at once with a message that
names the field or the limit (exit 2 on the command line), never a traceback, a hang or a C header with `nan`."""

import json
import math
from pathlib import Path

import pytest
from clitools import assert_user_error_text, invoke
from pydantic import ValidationError

from bench.campaign import MAX_POINTS_PER_SENSOR, Campaign
from calibration.errors import CalibrationError
from calibration.export import c_header
from calibration.models.seed003 import Seed003Calibration

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def problems(**fields) -> str:
    with pytest.raises(ValidationError) as info:
        Campaign(name="x", **fields)
    return str(info.value)


def test_a_plan_too_large_is_refused_before_it_is_expanded():
    message = problems(seed003={"azimuth_step_deg": 0.00001})
    assert "azimuth_step_deg" in message and "0.5" in message
    message = problems(plan="grid", grid={"azimuths_deg": list(range(0, 360, 2)), "zenith_stage_deg": list(range(60))})
    assert f"the limit is {MAX_POINTS_PER_SENSOR}" in message
    assert "at most 100 items" in problems(sensors=[f"FM-{i}" for i in range(101)])


def test_infinity_nan_and_true_are_not_numbers():
    assert "finite number" in problems(seed003={"auto_exposure": {"start_ms": math.inf}})
    assert "finite number" in problems(seed003={"tilt_probe_deg": math.nan})
    assert "not true/false" in problems(grid={"repeats": True})
    assert "not true/false" in problems(plan="grid", grid={"azimuths_deg": [0.0, True]})


def test_the_seed003_campaign_is_well_inside_the_caps():
    assert Campaign(name="x").planned_points() == 80


@pytest.mark.parametrize("name, value, words", [
    ("gap_mm", float("nan"), "must be a finite number"),
    ("gap_mm", -1.0, "must be positive"),
    ("gap_mm", "abc", "must be a number, got a string"),
    ("gap_mm", None, "must be a number, got null"),
    ("gap_mm", [1, 2], "must be a number, got a list"),
    ("x0_px", 1e308, "out of range"),
    ("mirrored", 3, "must be true or false"),
    ("uncertainties", {"gap_mm": "x"}, "entry 'gap_mm' must be a number"),
])
def test_a_calibration_file_with_a_bad_parameter_is_refused_naming_it(tmp_path, name, value, words):
    demo = tmp_path / "demo"
    assert invoke("demo", "--out", demo).exit_code == 0
    document = json.loads((demo / "calibration.json").read_text())
    document["parameters"][name] = value
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(document))
    for command in (("header", bad, "-o", tmp_path / "out.h"), ("apply", bad, demo / "bench-data.csv", "-o",
                                                                  tmp_path / "out.csv")):
        result = invoke(*command)
        assert_user_error_text(result.stderr, result.exit_code, "bad.json", name, words)
    assert not (tmp_path / "out.h").exists()


def test_deeply_nested_json_and_huge_spot_coordinates_are_refused(tmp_path):
    nested = tmp_path / "nested.json"
    nested.write_text("[" * 100_000 + "]" * 100_000)
    result = invoke("header", nested, "-o", tmp_path / "out.h")
    assert_user_error_text(result.stderr, result.exit_code, "nested.json", "nested too deeply")
    demo = tmp_path / "demo"
    invoke("demo", "--out", demo)
    spots = tmp_path / "spots.csv"
    spots.write_text("x_px,y_px\n320,240\n1e308,5\n")
    result = invoke("apply", demo / "calibration.json", spots, "-o", tmp_path / "out.csv")
    assert_user_error_text(result.stderr, result.exit_code, "spots.csv", "row 2", "x_px", "out of range")


def test_no_c_header_holds_a_non_finite_coefficient():
    cal = Seed003Calibration(320.0, 240.0, (0.0, 1.0, 0.0, 0.0, float("nan"), 0.0, 0.0), 240.0, 1.0, 0.0)
    with pytest.raises(CalibrationError, match="non-finite"):
        c_header(cal)


def test_an_infinite_time_scale_and_an_id_beyond_sqlite_are_refused(tmp_path):
    result = invoke("run", EXAMPLES / "seed003.yaml", "--time-scale", "inf", "--dry-run")
    assert result.exit_code == 2 and "Traceback" not in result.output and "--time-scale" in result.output
    result = invoke("show", str(2**63), "--catalogue", tmp_path / "c.sqlite")
    assert result.exit_code == 2 and "Traceback" not in result.output
