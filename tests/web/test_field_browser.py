"""The field data page (/field, issue 13) in a real browser, as tests/web/test_browser.py drives the others: Debian's
headless chromium against `sunbench serve` on the simulated bench. The engineer pastes the token, picks a field CSV
and a calibration JSON, analyses them and reads the statistics, the figures 5.1–5.5 and the located site; a file
the analysis cannot use is said in the message line. Screenshots in ``test-artifacts/browser/field-*.png``.

The demo's calibration is of another sensor than the simulated field's: the errors are large, and these tests
check what the page shows, not how accurate it is."""

import re

import pytest
import test_browser
from playwright.sync_api import Page, expect
from test_browser import ARTIFACTS, TIMEOUT_MS, Shots, paste_token, plot_points, watch_errors
from test_field import make_field_files

# the browser and the server of test_browser.py (its fixtures, here for this module)
browser = test_browser.browser
server = test_browser.server

COMPARISON_PLOTS = ("zenith-plot", "zenith-error-plot", "azimuth-plot", "azimuth-error-plot", "vector-error-plot")
GROUP_NAMES = {"clear sky, Sun in the field of view", "cloudy", "out of the field of view",
               "other samples (not counted as clear)"}


#: test → the prefix of its screenshots in ARTIFACTS (field-analyse-01-form.png …)
SHOT_NAMES = {"test_field_page_analyses_a_file_and_shows_its_errors_and_the_located_site": "field-analyse",
              "test_field_page_with_a_fitted_heading_and_no_location": "field-fitted-heading",
              "test_field_page_says_what_is_wrong_with_a_file": "field-refused"}


@pytest.fixture(scope="module")
def field_files(tmp_path_factory):
    return make_field_files(tmp_path_factory.mktemp("field-browser"))


def _field_page(browser, server, shots_name: str):
    base, _ = server
    context = browser.new_context(base_url=base, viewport={"width": 1280, "height": 900})
    context.set_default_timeout(TIMEOUT_MS)
    page = context.new_page()
    page.shots = Shots(page, shots_name)
    return context, page


@pytest.fixture
def field_page(browser, server, request):
    """A fresh browser profile on /field with the token pasted; any uncaught script error fails the test, and a
    last screenshot is taken whatever happened. Screenshots: field-<what>-NN-<step>.png (SHOT_NAMES)."""
    name = SHOT_NAMES.get(request.node.name, request.node.name)
    context, page = _field_page(browser, server, name)
    errors = watch_errors(page, [])
    page.goto("/field")
    paste_token(page, server[1])
    yield page
    page.shots("last")
    context.close()
    # a refused request logs "Failed to load resource" (not counted); nothing else may go wrong
    assert not errors, errors


def _analyse(page: Page, csv, calibration=None, *, heading="file", level="file", locate=True) -> None:
    page.set_input_files("#field-csv", csv)
    if calibration is not None:
        page.set_input_files("#field-calibration", calibration)
    page.select_option("#field-form select[name=heading]", heading)
    page.select_option("#field-form select[name=level]", level)
    page.set_checked("#field-form input[name=locate]", locate)
    page.click("#analyse")


def _trace_names(page: Page, plot_id: str) -> list[str]:
    return page.evaluate("id => document.getElementById(id).data.map(t => t.name)", plot_id)


def test_field_page_analyses_a_file_and_shows_its_errors_and_the_located_site(field_page, field_files):
    page = field_page
    csv_path, calibration_path = field_files
    expect(page.locator("header nav a.here")).to_have_text("Field")
    expect(page.locator("#summary-section")).to_be_hidden()
    page.shots("form")

    _analyse(page, csv_path, calibration_path)
    expect(page.locator("#message")).to_have_text(re.compile(r"^field\.csv: 61 rows analysed"))
    expect(page.locator("#message")).not_to_have_class(re.compile("error"))

    # the statistics: clear samples and all of them
    expect(page.locator("#summary-section")).to_be_visible()
    expect(page.locator("#summary-heading")).to_have_text("field.csv: comparison with SPA")
    expect(page.locator("#summary-info")).to_contain_text(
        "61 rows; the file states the site 54.84370°, 83.09300°, 160 m")
    rows = page.locator("#stats tbody tr")
    expect(rows).to_have_count(2)
    expect(rows.nth(0).locator("td").first).to_have_text("clear sky, Sun in the field of view")
    expect(rows.nth(1).locator("td").first).to_have_text("all with the Sun in the field of view, cloudy too")
    for row in (0, 1):  # n, then five figures in degrees
        cells = rows.nth(row).locator("td").all_inner_texts()[1:]
        assert len(cells) == 6 and re.fullmatch(r"\d+", cells[0]), cells
    all_rms = rows.nth(1).locator("td").nth(4).inner_text()
    assert re.fullmatch(r"\d+\.\d{4}", all_rms), all_rms
    expect(page.locator("#heading-info")).to_have_text(re.compile(
        r"^Heading 15\.000° east of north, from the file\. Level: roll 0\.000°, pitch 0\.000°, from the file\.$"))

    # figs. 5.1–5.5: every plot drawn, the samples in their groups (the clear ones apart)
    expect(page.locator("#comparison-plots")).to_be_visible()
    for plot in COMPARISON_PLOTS:
        expect(page.locator(f"#{plot} .main-svg").first).to_be_visible()
        assert plot_points(page, plot) > 0, plot
        names = _trace_names(page, plot)
        groups = [n for n in names if n in GROUP_NAMES]
        assert groups and set(names) - set(groups) <= {"SPA apparent zenith", "SPA azimuth"}, (plot, names)
    clear_n = int(rows.nth(0).locator("td").nth(1).inner_text())
    drawn_clear = page.evaluate("""() => document.getElementById("vector-error-plot").data
        .filter(t => t.name === "clear sky, Sun in the field of view").reduce((n, t) => n + t.x.length, 0)""")
    assert drawn_clear == clear_n
    assert len(_trace_names(page, "zenith-plot")) >= 2  # SPA's line and the measured samples
    page.shots("comparison")

    # the located site: its figures beside the plot of its ellipse and the site the file states
    expect(page.locator("#location-section")).to_be_visible()
    expect(page.locator("#location-none")).to_be_hidden()
    figures = page.locator("#location-figures")
    expect(figures).to_contain_text("Latitude (located)")
    names = figures.locator("dt").all_inner_texts()
    values = dict(zip(names, figures.locator("dd").all_inner_texts()))
    assert re.fullmatch(r"-?\d+\.\d{5}°( ± \d+\.\d{2} km)?", values["Latitude (located)"]), values
    assert re.fullmatch(r"-?\d+\.\d{5}°( ± \d+\.\d{2} km)?", values["Longitude (located)"]), values
    assert re.fullmatch(r"-?\d+\.\d{3}°( ± \d+\.\d{3}°)?", values["Heading (located)"]), values
    assert re.fullmatch(r"\d+\.\d{2} km", values["Distance from it"]), values
    assert re.fullmatch(r"\d+\.\d{2} × \d+\.\d{2} km", values["Ellipse semi-axes (1σ)"]), values
    assert values["Site the file states"] == "54.84370°, 83.09300°, 160 m"
    expect(page.locator("#location-plot .main-svg").first).to_be_visible()
    assert _trace_names(page, "location-plot")[-2:] == ["located site", "site the file states"]
    assert any("ellipse" in n for n in _trace_names(page, "location-plot"))
    # plain axes, longitude across, a kilometre as long either way
    axes = page.evaluate("""() => { const l = document.getElementById("location-plot").layout;
        return [l.xaxis.title.text, l.yaxis.title.text, l.yaxis.scaleanchor, l.yaxis.scaleratio]; }""")
    assert axes[:3] == ["longitude, east [°]", "latitude, north [°]", "x"] and axes[3] > 1
    page.locator("#location-section").scroll_into_view_if_needed()
    page.shots("location")
    page.locator("#location-section").screenshot(path=ARTIFACTS / "field-analyse-location-section.png")


def test_field_page_with_a_fitted_heading_and_no_location(field_page, field_files):
    page = field_page
    _analyse(page, field_files[0], field_files[1], heading="fit", locate=False)
    expect(page.locator("#message")).to_have_text(re.compile(r"^field\.csv: 61 rows analysed"))
    expect(page.locator("#heading-info")).to_contain_text("fitted to the track: the azimuth errors are relative")
    expect(page.locator("#azimuth-error-heading")).to_contain_text("relative to the fitted heading")
    expect(page.locator("#location-section")).to_be_hidden()
    expect(page.locator("#location-none")).to_be_hidden()  # not asked for
    assert plot_points(page, "azimuth-error-plot") > 0
    page.shots("fitted-heading")


def test_field_page_says_what_is_wrong_with_a_file(field_page, field_files):
    page = field_page
    lines = field_files[0].read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("time_utc")) + 1
    cells = lines[first + 2].split(",")
    cells[lines[first - 1].split(",").index("x_px")] = "abc"
    lines[first + 2] = ",".join(cells)
    bad_csv = {"name": "bad.csv", "mimeType": "text/csv", "buffer": ("\n".join(lines) + "\n").encode()}
    _analyse(page, bad_csv, field_files[1])
    message = page.locator("#message")
    expect(message).to_have_class(re.compile(r"\berror\b"))
    expect(message).to_contain_text("422")
    expect(message).to_contain_text("bad.csv")
    expect(message).to_contain_text("row 3")
    expect(message).to_contain_text("x_px")
    expect(page.locator("#summary-section")).to_be_hidden()
    page.shots("malformed-csv")

    not_json = {"name": "notes.json", "mimeType": "application/json", "buffer": b"this is not JSON"}
    _analyse(page, field_files[0], not_json)
    expect(message).to_contain_text("notes.json is not a calibration JSON file")
    expect(message).to_have_class(re.compile(r"\berror\b"))
    page.shots("bad-calibration")
