"""The field data route and page (issue 13): POST /api/field/analyse sets a field CSV against SPA's Sun and locates
the site; a file it cannot use is 422 naming the row and the column, an unknown field 422, a body over the field
limit (WebSettings.field_max_body_bytes, 4 MiB) 413 while a 2-hour track at 1 Hz passes; the /field page is served
with its script and plotly, and every page's navigation links to it.

The test data come from the CLI: ``sunbench field simulate`` (a 1-hour simulated field track, 1 reading a minute)
and ``sunbench demo`` (a CMOS calibration). The demo's calibration is of another sensor than the field's, so the
errors are large: these tests check structure and behaviour, not accuracy."""

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import httpx
import numpy as np
import pytest
from inprocess import AUTH, api_client, settings_for_tests
from test_api import SMALL_JSON, _served

from bench.benchfile import BenchFile
from bench.catalogue import Catalogue
from bench.service import BenchService
from web.app import create_app
from web.guard import FIELD_PREFIX
from web.routes.field import FieldAnalyseRequest, plain
from web.routes.pages import PAGES

SUNBENCH = Path(sys.executable).parent / "sunbench"
ANALYSE = "/api/field/analyse"
MIB = 1024 * 1024


def make_field_files(folder: Path) -> tuple[Path, Path]:
    """(field CSV, calibration JSON) made by the CLI in `folder`: a simulated hour about local noon on seed 003's
    field day (the Sun in the sensor's field of view), one reading a minute, with cloud banks (so some samples are
    not clear), and the demo's CMOS calibration."""
    csv_path = folder / "field.csv"
    subprocess.run([str(SUNBENCH), "field", "simulate", "-o", str(csv_path), "--hours", "1", "--interval", "60",
                    "--start", "2019-09-29T05:00:00Z", "--clouds", "6"], check=True, capture_output=True, timeout=300)
    subprocess.run([str(SUNBENCH), "demo", "--out", str(folder / "demo")], check=True, capture_output=True,
                   timeout=300)
    return csv_path, folder / "demo" / "calibration.json"


@pytest.fixture(scope="session")
def field_files(tmp_path_factory):
    return make_field_files(tmp_path_factory.mktemp("field"))


@pytest.fixture(scope="module")
def field_client(tmp_path_factory):
    """A client of the app around an idle simulated bench, for the whole module (the route never touches it)."""
    folder = tmp_path_factory.mktemp("field-bench")
    service = BenchService(BenchFile(), Catalogue(folder / "c.sqlite"), time_scale=0.0, status_period_s=0.05).start()
    try:
        with api_client(service) as client:
            yield client
    finally:
        service.close()
        service.catalogue.close()


def _body(field_files, **changes) -> dict:
    csv_path, calibration_path = field_files
    return {"csv": csv_path.read_text(), "calibration": json.loads(calibration_path.read_text()), "heading": "file",
            "level": "file", "locate": True, "fov_half_deg": None, "name": "field.csv", **changes}


def _analyse(client, body, status=200):
    response = client.post(ANALYSE, json=body, headers=AUTH)
    assert response.status_code == status, response.text[:2000]
    return response.json()


@pytest.fixture(scope="module")
def analysed(field_client, field_files):
    """The answer for the field file with its calibration, the heading from the file, the site located."""
    return _analyse(field_client, _body(field_files))


def _rows(field_files) -> list[str]:
    return field_files[0].read_text().splitlines()


# -- a good file --------------------------------------------------------------------------------------------------
COMPARISON_ARRAYS = ("sun_zenith_deg", "sun_azimuth_deg", "measured_zenith_deg", "measured_azimuth_deg",
                     "zenith_error_deg", "azimuth_error_deg", "vector_error_deg")
STATS_KEYS = {"n", "rms_zenith_deg", "rms_azimuth_deg", "rms_vector_deg", "std_vector_deg", "max_vector_deg"}
LOCATION_KEYS = {"latitude_deg", "longitude_deg", "heading_deg", "sd_latitude_km", "sd_longitude_km",
                 "sd_heading_deg", "ellipse", "ellipse_level", "error_km", "n", "residual_rms_deg", "warnings"}


def _finite_or_null(values):
    return all(v is None or (isinstance(v, (int, float)) and math.isfinite(v)) for v in values)


def test_a_good_file_gives_the_documented_keys(analysed, field_files):
    header = [line for line in _rows(field_files) if not line.startswith("#")]
    n = len(header) - 1  # the column names
    assert {"name", "n", "site", "comparison", "location", "notes"} <= set(analysed)
    assert analysed["name"] == "field.csv" and analysed["n"] == n == 61
    assert analysed["site"]["latitude_deg"] == pytest.approx(54.8437)
    assert analysed["site"]["longitude_deg"] == pytest.approx(83.093)
    assert analysed["site"]["altitude_m"] == pytest.approx(160)

    c = analysed["comparison"]
    assert len(c["time_utc"]) == n and all(isinstance(t, str) for t in c["time_utc"])
    for name in COMPARISON_ARRAYS:
        assert len(c[name]) == n and _finite_or_null(c[name]), name
    for name in ("clear", "in_fov", "cloud"):
        assert len(c[name]) == n and all(isinstance(v, bool) for v in c[name]), name
    assert all(0 < z < 90 for z in c["sun_zenith_deg"])  # the Sun is up over the whole hour
    assert set(c["heading"]) >= {"deg", "sd_deg", "fitted"} and c["heading"]["fitted"] is False
    assert c["heading"]["deg"] == pytest.approx(15.0)  # the compass heading the file states
    assert set(c["stats"]) >= {"clear", "all"}
    for key in ("clear", "all"):
        assert STATS_KEYS <= set(c["stats"][key]), key
    # clear: valid readings without cloud; the clear-sky figures count those with the Sun in the field of view
    assert c["stats"]["all"]["n"] >= c["stats"]["clear"]["n"] == sum(a and b for a, b in zip(c["clear"], c["in_fov"]))
    assert all(isinstance(line, str) for line in c["notes"] + c["warnings"])

    location = analysed["location"]
    assert LOCATION_KEYS <= set(location)
    assert -90 <= location["latitude_deg"] <= 90 and -180 <= location["longitude_deg"] <= 360
    ellipse = location["ellipse"]
    assert len(ellipse["latitude_deg"]) == len(ellipse["longitude_deg"]) >= 4
    assert _finite_or_null(ellipse["latitude_deg"]) and _finite_or_null(ellipse["longitude_deg"])
    # a closed polygon
    assert (ellipse["latitude_deg"][0], ellipse["longitude_deg"][0]) == pytest.approx(
        (ellipse["latitude_deg"][-1], ellipse["longitude_deg"][-1]))
    assert isinstance(location["ellipse_level"], str) and location["ellipse_level"]
    assert location["error_km"] is not None and location["error_km"] >= 0  # the file states its site
    assert all(isinstance(line, str) for line in location["warnings"])


def test_the_answer_is_plain_json_without_nan(field_client, field_files):
    response = field_client.post(ANALYSE, json=_body(field_files, locate=False), headers=AUTH)
    assert response.status_code == 200, response.text[:2000]
    assert "NaN" not in response.text and "Infinity" not in response.text
    json.loads(response.text, parse_constant=lambda name: pytest.fail(f"{name} in the answer"))


def test_without_locate_there_is_no_location_and_a_fitted_heading_says_so(field_client, field_files):
    result = _analyse(field_client, _body(field_files, locate=False, heading="fit"))
    assert result["location"] is None and result["comparison"] is not None
    heading = result["comparison"]["heading"]
    assert heading["fitted"] is True and heading["deg"] is not None


def test_a_stated_level_uncertainty_widens_the_located_site(field_client, field_files, analysed):
    """The level's 1σ enters the site's covariance (a tilt moves the site by ~111 km per degree): with 0.1° the
    1σ grows to kilometres, and the answer says why."""
    wide = _analyse(field_client, _body(field_files, level_sd_deg=0.1))["location"]
    assert wide["sd_latitude_km"] > 5 and wide["sd_latitude_km"] > 3 * analysed["location"]["sd_latitude_km"]
    assert any("level is known to ±0.1°" in w for w in wide["warnings"])
    refused = field_client.post(ANALYSE, json=_body(field_files, level_sd_deg=0), headers=AUTH)
    assert refused.status_code == 422 and "level_sd_deg" in refused.text


def test_the_name_only_names_the_upload(field_client, field_files):
    """The server reads the posted text, never a file of that name on its own disk."""
    result = _analyse(field_client, _body(field_files, locate=False, name="/etc/passwd"))
    assert result["name"] == "/etc/passwd" and result["n"] == 61


# -- files it cannot use: 422 naming the problem --------------------------------------------------------------------
def test_a_malformed_csv_is_422_naming_the_row_and_the_column(field_client, field_files):
    lines = _rows(field_files)
    first = next(i for i, line in enumerate(lines) if line.startswith("time_utc")) + 1
    columns = lines[first - 1].split(",")
    x = columns.index("x_px")
    cells = lines[first + 2].split(",")  # the third data row
    cells[x] = "abc"
    lines[first + 2] = ",".join(cells)
    detail = _analyse(field_client, _body(field_files, csv="\n".join(lines) + "\n", name="bad.csv"), 422)["detail"]
    assert isinstance(detail, str)
    assert "bad.csv" in detail and "row 3" in detail and "x_px" in detail, detail


def test_a_file_without_a_time_column_is_422_naming_it(field_client, field_files):
    text = field_files[0].read_text().replace("time_utc,", "when,", 1)
    detail = _analyse(field_client, _body(field_files, csv=text), 422)["detail"]
    assert "time_utc" in detail, detail


def test_a_file_with_no_rows_is_422(field_client, field_files):
    lines = _rows(field_files)
    header = [line for line in lines if line.startswith("#") or line.startswith("time_utc")]
    detail = _analyse(field_client, _body(field_files, csv="\n".join(header) + "\n"), 422)["detail"]
    assert isinstance(detail, str) and detail


def test_a_calibration_it_cannot_read_is_422(field_client, field_files):
    detail = _analyse(field_client, _body(field_files, calibration={"format": "something else"}), 422)["detail"]
    assert isinstance(detail, str) and detail


def test_unknown_or_mistyped_fields_are_422_naming_them(field_client, field_files):
    body = _body(field_files)
    for change, loc in (({"bogus": 1}, ["body", "bogus"]), ({"heading": "north"}, ["body", "heading"]),
                        ({"level": "flat"}, ["body", "level"]), ({"locate": 1}, ["body", "locate"]),
                        ({"fov_half_deg": True}, ["body", "fov_half_deg"]),
                        ({"fov_half_deg": -5.0}, ["body", "fov_half_deg"]), ({"csv": ""}, ["body", "csv"]),
                        ({"calibration": [1, 2]}, ["body", "calibration"])):
        detail = _analyse(field_client, {**body, **change}, 422)["detail"]
        assert [e["loc"] for e in detail] == [loc], (change, detail)
    missing = {k: v for k, v in body.items() if k != "csv"}
    assert [e["loc"] for e in _analyse(field_client, missing, 422)["detail"]] == [["body", "csv"]]


def test_the_request_model_is_strict():
    assert FieldAnalyseRequest.model_config["extra"] == "forbid" and FieldAnalyseRequest.model_config["strict"]
    assert FieldAnalyseRequest.model_validate({"csv": "x", "fov_half_deg": 30}).fov_half_deg == 30.0


def test_plain_turns_numpy_and_non_finite_numbers_into_json():
    value = {"a": np.array([1.0, np.nan, np.inf]), "b": (np.float64(2.5), np.int64(3), np.bool_(True)),
             "c": [float("-inf"), None, "x"]}
    assert plain(value) == {"a": [1.0, None, None], "b": [2.5, 3, True], "c": [None, None, "x"]}
    json.dumps(plain(value), allow_nan=False)


# -- who may ask ----------------------------------------------------------------------------------------------------
def test_it_is_a_read_the_token_or_public_read_opens(field_client, service):
    body = {"csv": "x", "bogus": 1}  # refused by the model: what matters is what comes first
    assert field_client.post(ANALYSE, json=body).status_code == 401
    assert field_client.post(ANALYSE, json=body, headers={"Authorization": "Bearer wrong-token-0123456789"}
                             ).status_code == 401
    with api_client(service, public_read=True) as public:
        assert public.post(ANALYSE, json=body).status_code == 422


def test_the_route_is_in_the_schema_under_field(field_client):
    schema = field_client.get("/openapi.json").json()
    operation = schema["paths"][ANALYSE]["post"]
    assert operation["tags"] == ["field"]
    assert operation["requestBody"]["content"]["application/json"]["schema"]["$ref"].endswith("/FieldAnalyseRequest")
    assert {"413", "422"} <= set(operation["responses"])
    assert "field" in {t["name"] for t in schema["tags"]}


# -- the body limit ---------------------------------------------------------------------------------------------
def _sized(size: int) -> bytes:
    """A JSON body of exactly `size` bytes that the request model refuses (heading "north") without analysing."""
    head, tail = b'{"heading": "north", "csv": "', b'"}'
    return head + b"x" * (size - len(head) - len(tail)) + tail


def _post_raw(client, path: str, content, **headers):
    return client.post(path, content=content, headers={**AUTH, "Content-Type": "application/json", **headers})


def test_the_field_limit_is_4_mib_by_default_and_documented():
    settings = settings_for_tests()
    assert settings.field_max_body_bytes == 4 * MIB and settings.max_body_bytes == 64 * 1024
    assert FIELD_PREFIX == "/api/field/" and ANALYSE.startswith(FIELD_PREFIX)


def test_a_body_within_the_field_limit_passes_and_one_over_it_is_413(field_client):
    limit = 4 * MIB
    within = _post_raw(field_client, ANALYSE, _sized(limit))
    assert within.status_code == 422, within.text[:300]  # parsed: refused by the model, not by its size
    assert [e["loc"] for e in within.json()["detail"]] == [["body", "heading"]]
    over = _post_raw(field_client, ANALYSE, _sized(limit + 1))
    assert over.status_code == 413 and f"{limit} bytes" in over.json()["detail"]


def test_the_field_limit_holds_only_under_api_field(field_client):
    # what the field route takes is still too much for any other
    campaign = _post_raw(field_client, "/api/campaigns/dry-run", _sized(200 * 1024))
    assert campaign.status_code == 413 and "65536 bytes" in campaign.json()["detail"]
    assert _post_raw(field_client, ANALYSE, _sized(200 * 1024)).status_code == 422


def test_a_smaller_field_limit_is_taken_from_the_settings(service):
    with api_client(service, field_max_body_bytes=100 * 1024) as client:
        assert _post_raw(client, ANALYSE, _sized(100 * 1024)).status_code == 422
        over = _post_raw(client, ANALYSE, _sized(100 * 1024 + 1))
        assert over.status_code == 413 and "102400 bytes" in over.json()["detail"]


def test_a_streamed_body_over_the_field_limit_is_413_on_a_real_server(service):
    app = create_app(service, settings=settings_for_tests(field_max_body_bytes=256 * 1024))
    with _served(app) as (_, base), httpx.Client(headers=AUTH, timeout=30) as http:
        def chunks(n):  # no Content-Length: refused once the bytes read pass the limit
            yield b'{"heading": "north", "csv": "'
            for _ in range(n):
                yield b"x" * 4096
            yield b'"}'
        over = http.post(f"{base}{ANALYSE}", content=chunks(100), headers={"Content-Type": "application/json"})
        assert over.status_code == 413 and "262144 bytes" in over.json()["detail"]
        within = http.post(f"{base}{ANALYSE}", content=chunks(40), headers={"Content-Type": "application/json"})
        assert within.status_code == 422
        assert http.post(f"{base}/api/campaigns/dry-run", json=SMALL_JSON).status_code == 200  # still answering


def _two_hours_at_1_hz(field_files) -> str:
    """The simulated hour at one reading a minute, stretched to 2 hours and resampled at 1 Hz (7200 rows, the
    spot interpolated): the size of a real 2-hour track."""
    lines = _rows(field_files)
    first = next(i for i, line in enumerate(lines) if line.startswith("time_utc"))
    comments = lines[:first]
    columns = lines[first].split(",")
    rows = [cells for line in lines[first + 1:] if line and (cells := line.split(","))[columns.index("x_px")]]
    names = ("x_px", "y_px", "peak_dn", "exposure_ms")
    t = np.arange(7200) / 7200.0 * (len(rows) - 1)
    values = [np.interp(t, np.arange(len(rows)), [float(r[columns.index(name)]) for r in rows]) for name in names]
    start = np.datetime64(rows[0][0].rstrip("Z"), "ms")
    out = [f"time_utc,{','.join(names)},status"]
    for i in range(7200):
        stamp = np.datetime_as_string(start + np.timedelta64(i * 1000, "ms"), unit="ms")
        out.append(f"{stamp}Z,{','.join(f'{v[i]:.6f}' for v in values)},ok")
    return "\n".join(comments + out) + "\n"


def test_a_two_hour_track_at_1_hz_passes_the_guard_and_is_analysed(field_client, field_files):
    text = _two_hours_at_1_hz(field_files)
    body = _body(field_files, csv=text, locate=False, name="two-hours.csv")
    size = len(json.dumps(body).encode())
    assert 8 * 64 * 1024 < size < 4 * MIB  # far over the 64 KiB of the other routes
    result = _analyse(field_client, body)
    assert result["n"] == 7200 and len(result["comparison"]["vector_error_deg"]) == 7200


# -- the page ------------------------------------------------------------------------------------------------------
def test_the_field_page_is_served_with_its_script_and_plotly(field_client):
    assert PAGES["/field"] == "field.html"
    response = field_client.get("/field")  # a page holds no data: no token
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/html")
    html = response.text
    assert '<script type="module" src="/static/field.js"></script>' in html
    assert '<script src="/static/plotly.min.js"></script>' in html
    assert "<title>sunbench · Field data</title>" in html
    assert '<a href="/field" class="here">' in html
    for needed in ('id="field-form"', 'type="file" id="field-csv"', 'type="file" id="field-calibration"',
                   'name="heading"', 'name="level"', 'name="locate"', 'id="stats"', 'id="location-plot"',
                   'id="location-figures"', 'id="message"'):
        assert needed in html, needed
    js = field_client.get("/static/field.js")
    assert js.status_code == 200 and "/api/field/analyse" in js.text
    # every element the script looks up is on the page
    ids = set(re.findall(r'\sid="([^"]+)"', html))
    looked_up = set(re.findall(r"""["'`]#([A-Za-z][\w-]*)""", js.text)) | set(
        re.findall(r"""["']([A-Za-z][\w-]*-plot)["']""", js.text))
    colours = {i for i in looked_up if re.fullmatch(r"[0-9a-fA-F]{3}(?:[0-9a-fA-F]{3})?", i)}
    assert looked_up - colours <= ids, looked_up - colours - ids


def test_every_page_links_to_the_field_page(field_client):
    for path in PAGES:
        nav = re.search(r"<nav>.*?</nav>", field_client.get(path).text, re.DOTALL).group()
        assert '<a href="/field"' in nav and ">Field</a>" in nav, path
