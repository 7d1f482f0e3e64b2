"""The dashboard in a real browser: Playwright drives Debian's headless chromium against `sunbench serve` on
the simulated bench, as an engineer would use it (the token pasted into the form, campaigns started from
the launcher, followed live, read on the results page).

chromium comes from scripts/setup-browser.sh (``apt-get install chromium``; ``SUNBENCH_CHROMIUM`` names
another binary). Playwright never downloads a browser here. Screenshots of every step are saved in
``test-artifacts/browser/`` (``SUNBENCH_ARTIFACTS`` moves the folder).
"""

import json
import os
import re
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect, sync_playwright
from serving import ROOT, serving

from calibration.models import METHODS, calibration_from_dict
from calibration.uncertainty import uncertainty_document

ARTIFACTS = Path(os.environ.get("SUNBENCH_ARTIFACTS", ROOT / "test-artifacts")) / "browser"
CHROMIUM = os.environ.get("SUNBENCH_CHROMIUM", "/usr/bin/chromium")
# as root in a container chromium needs --no-sandbox; without the networking flags it keeps trying to
# reach Google's hosts, which this machine's closed network refuses
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
# simulated time runs 100× faster: the launcher's default campaign (about 17 min on the bench) lasts ~10 s,
# long enough to watch it, pause it and abort it
TIME_SCALE = 100
TIMEOUT_MS = 60_000
expect.set_options(timeout=20_000)  # a busy CI machine; a passing expect returns as soon as it holds


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """`sunbench serve` on the simulated bench; (base URL, token)."""
    with serving(tmp_path_factory.mktemp("serve"), None, "--time-scale", str(TIME_SCALE)) as served:
        yield served.base, served.token
    # printed once, at first start; the pages' event streams send it as ?token=, which the access log masks
    assert served.output().count(served.token) == 1


@pytest.fixture(scope="module")
def browser():
    if not os.access(CHROMIUM, os.X_OK):
        pytest.fail(f"no chromium at {CHROMIUM}: run scripts/setup-browser.sh (or bash scripts/test.sh, which "
                    "runs it), or set SUNBENCH_CHROMIUM")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


class Shots:
    """Numbered screenshots of one test, in ARTIFACTS."""

    def __init__(self, page: Page, test_name: str):
        self.page, self.prefix, self.n = page, re.sub(r"\W+", "-", test_name).strip("-"), 0
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        for old in ARTIFACTS.glob(f"{self.prefix}-*.png"):
            old.unlink()

    def __call__(self, name: str) -> Path:
        self.n += 1
        path = ARTIFACTS / f"{self.prefix}-{self.n:02d}-{name}.png"
        self.page.screenshot(path=path, full_page=True)
        return path


@pytest.fixture
def page(browser, server, request):
    """A fresh browser profile (no token yet) on the bench's idle dashboard. Any uncaught script error
    fails the test; a last screenshot is taken whatever happened."""
    base, _ = server
    _wait_idle(server)
    context = browser.new_context(base_url=base, viewport={"width": 1280, "height": 900})
    context.set_default_timeout(TIMEOUT_MS)
    page = context.new_page()
    errors = watch_errors(page, [])
    page.shots = Shots(page, request.node.name)
    yield page
    page.shots("last")
    context.close()
    assert not errors, errors


def watch_errors(page: Page, errors: list, where: str = "") -> list:
    """Collect into `errors` (returned) every uncaught script error of `page` and every error it logs to the
    console; a 404 for a frame before the shutter has opened is the API's answer, not a page error."""
    page.on("pageerror", lambda exc: errors.append(f"uncaught{where}: {exc}"))
    page.on("console", lambda m: m.type == "error" and "Failed to load resource" not in m.text
            and errors.append(f"console{where}: {m.text}"))
    return errors


def _wait_idle(server, timeout_s=60.0):
    base, token = server
    request = urllib.request.Request(base + "/api/status", headers={"Authorization": f"Bearer {token}"})
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        status = urllib.request.urlopen(request, timeout=5).read().decode()
        if '"state":"idle"' in status:
            return
        time.sleep(0.2)
    raise AssertionError("the bench did not come back to idle")


def paste_token(page: Page, token: str, state: str = "token set") -> None:
    """What an engineer does first: open the token box and paste the token `sunbench serve` printed."""
    box = page.locator("#token-box")
    if box.get_attribute("open") is None:
        page.click("#token-box summary")
    page.fill("#token-form input[name=token]", token)
    page.click("#token-form button[type=submit]")
    expect(page.locator("#token-state")).to_have_text(state)


def jog_to(page: Page, azimuth_deg: float, zenith_deg: float) -> None:
    """Move the table with the bench page's form and wait until the status shows it there."""
    page.fill("#jog-form input[name=azimuth_deg]", str(azimuth_deg))
    page.fill("#jog-form input[name=zenith_deg]", str(zenith_deg))
    page.click("#jog-form button[type=submit]")
    expect(page.locator("#message")).to_have_text(f"table at azimuth {azimuth_deg:.3f}°, zenith {zenith_deg:.3f}°")
    expect(page.locator("#s-az")).to_have_text(f"{azimuth_deg:.3f}°")
    expect(page.locator("#s-zen")).to_have_text(f"{zenith_deg:.3f}°")


def plot_points(page: Page, plot_id: str) -> int:
    """How many markers plotly drew in the plot `plot_id`."""
    return page.locator(f"#{plot_id} .scatterlayer .point").count()


FIT_PLOTS = ("spot-plot", "radius-plot", "zenith-residual-plot", "azimuth-plot", "error-plot")
LEFT_OUT = "left out of the fit"


def _left_out_traces(page: Page, plot_id: str) -> list[dict]:
    """The traces of a plot named as the points the fit left out: their points and hover texts."""
    return page.evaluate("""id => document.getElementById(id).data
        .filter(t => t.name === "left out of the fit").map(t => ({n: t.x.length, text: t.text}))""", plot_id)


def _expect_left_out(page: Page, left: list[dict]) -> None:
    """Every result plot draws the points the fit left out in their own trace, with their own marker, named
    "left out of the fit" in the legend, and each one's hover text says why."""
    for plot in FIT_PLOTS:
        shown = [p for p in left if plot != "zenith-residual-plot" or p["zenith_deg"] > 0.5]
        if plot == "azimuth-plot":
            shown = [p for p in shown if p["zenith_deg"] >= 5 and p["azimuth_fit_deg"] is not None]
        traces = _left_out_traces(page, plot)
        assert [t["n"] for t in traces] == ([len(shown)] if shown else []), plot
        for trace in traces:
            texts = sorted(trace["text"])
            assert texts == sorted(f"{p['key']}<br>left out of the fit: {p['excluded']}" for p in shown), plot
        if shown:
            expect(page.locator(f"#{plot} .legendtext", has_text=LEFT_OUT)).to_be_visible()
            symbol = page.evaluate("""id => document.getElementById(id).data
                .find(t => t.name === "left out of the fit").marker.symbol""", plot)
            assert symbol == "x-thin-open", plot


def _expect_titles_inside(page: Page) -> None:
    """No plot's title runs off its card: each title line lies within its plot's drawing."""
    for plot in (*FIT_PLOTS, "uncertainty-plot"):
        box = page.evaluate("""id => {
            const root = document.getElementById(id), svg = root.querySelector(".main-svg").getBoundingClientRect();
            const title = root.querySelector(".gtitle").getBoundingClientRect();
            return [title.left - svg.left, title.top - svg.top, svg.right - title.right, svg.bottom - title.bottom];
        }""", plot)
        assert min(box) >= 0, (plot, box)


# -- the whole way: launcher → live run → results → fleet ---------------------------------------------------
def test_a_campaign_from_the_launcher_to_its_results(page, server):
    _, token = server
    page.goto("/launch")
    expect(page.locator("#token-state")).to_have_text("no token")
    paste_token(page, token)

    page.click("#dry-run")
    expect(page.locator("#message")).to_have_text("dry run ok: nothing moved")
    expect(page.locator("#d-nviol")).to_have_text("none")
    points = int(page.locator("#d-points").inner_text())
    assert points == 80  # seed 003: 8 azimuths × 7 zenith stages + centre and tilt points
    assert re.fullmatch(r"\d+ min \d+ s", page.locator("#d-duration").inner_text())
    # the lamp's warm-up apart, for every plan; seed 003's figures are what the run will do, not bounds
    assert re.fullmatch(r"\d+ min \d+ s", page.locator("#d-warmup").inner_text())
    expect(page.locator("#d-summary")).to_have_text(re.compile(
        r"^80 points, \d+ frames, \d+ moves per sensor × 1 sensor\(s\); about [\d.]+ min of bench time in all "
        r"\(of which [\d.]+ min lamp warm-up\), about [\d.]+ min of wall time$"))
    expect(page.locator("#d-bound")).to_have_text("")
    # per sensor and in all, in bench time and on the wall clock: a simulated bench's run takes 1/100 of it
    expect(page.locator("#d-sensors")).to_have_text("1")
    expect(page.locator("#d-duration-sensor")).to_have_text(page.locator("#d-duration").inner_text())
    expect(page.locator("#d-wall")).to_have_text(re.compile(
        r"^(\d+ min )?\d+ s on this simulated bench \(bench time / time scale 100\)$"))
    page.shots("dry-run")

    page.click("#start")
    expect(page.locator("#started")).to_contain_text("queued")
    page.shots("queued")
    page.click("#started a[href='/run']")
    expect(page).to_have_url(re.compile(r"/run$"))
    expect(page.locator("#stream-state")).to_have_text("connected")
    expect(page.locator("#run-title")).to_contain_text("plan seed003")
    expect(page.locator("#bound-note")).to_be_hidden()  # seed 003's total is what it will measure

    # progress while it runs: the bar moves and spots arrive on the matrix before the end
    seen_between = False
    deadline = time.monotonic() + TIMEOUT_MS / 1000
    while time.monotonic() < deadline:
        value, maximum = page.eval_on_selector("#progress", "p => [p.value, p.max]")
        if 0 < value < maximum and maximum == points:
            if not seen_between:
                page.shots("running")
            seen_between = True
            assert plot_points(page, "spot-plot") > 0
        if page.locator("#result-link a").count():
            break
        time.sleep(0.1)
    assert seen_between, "the live run page never showed the run in progress"
    expect(page.locator("#progress-text")).to_have_text(f"{points} / {points}")
    assert page.eval_on_selector("#progress", "p => p.value / p.max") == 1.0
    expect(page.locator("#log")).to_contain_text("finished: completed")
    assert plot_points(page, "spot-plot") >= points  # every frame's spot, as it arrived
    page.shots("finished")

    page.click("#result-link a")
    expect(page).to_have_url(re.compile(r"/results\?run=\d+$"))
    rows = page.locator("#metrics tbody tr")
    expect(rows).to_have_count(len(METHODS))  # seed003, -tilt, -sector and the physical models side by side
    expect(page.locator("#metrics tbody tr.chosen")).to_have_count(1)
    chosen = page.locator("#metrics tbody tr.chosen td").first.inner_text()
    assert chosen.startswith("physical")  # the physical model predicts held-out directions best
    held_out_rms = float(page.locator("#metrics tbody tr.chosen td").nth(4).inner_text())
    assert 0 < held_out_rms < 0.05  # degrees, on the default simulated sensor
    for plot in ("spot-plot", "radius-plot", "zenith-residual-plot", "azimuth-plot", "error-plot"):
        expect(page.locator(f"#{plot} .main-svg").first).to_be_visible()
        assert plot_points(page, plot) > 10, plot
    # the chosen physical model's 1σ pointing uncertainty over the field, and the fit's quality in words
    expect(page.locator("#uncertainty-plot .main-svg").first).to_be_visible()
    expect(page.locator("#quality-section")).to_be_visible()
    # fig. 4.7 draws one line per bench azimuth, and the points the fit left out apart
    run_id = int(page.url.rsplit("=", 1)[1])
    fit = _api(server, f"/api/runs/{run_id}/fit")
    left = [p for p in fit["data"] if p["excluded"]]
    assert left and all(p["excluded"] == "spot clipped at the detector's edge" for p in left)
    off_axis_left = [p for p in left if p["zenith_deg"] > 0.5]
    assert page.locator("#zenith-residual-plot .scatterlayer .trace").count() == 8 + bool(off_axis_left)
    _expect_left_out(page, left)
    _expect_titles_inside(page)
    # where the figures come from, and the fitted parameters with their 1σ
    provenance = page.locator("#provenance")
    for words in ("Bench configuration hash", "simulated (no real device measured this run)", "Software", "Operator",
                  "Device: sensor", "SB-CMOS-PINHOLE, serial SIM-0001"):
        expect(provenance).to_contain_text(words)
    expect(page.locator("#parameters-heading")).to_have_text(f"Fitted parameters of {chosen.split()[0]}")
    x0 = page.locator("#parameters tbody tr", has_text="x0_px").locator("td")
    expect(x0.nth(2)).to_have_text(re.compile(r"^± \d"))
    assert 0 < float(x0.nth(1).inner_text()) < 640
    page.shots("results")

    with page.expect_download() as download:
        page.click("#downloads button:has-text('bench data CSV')")
    csv_text = Path(download.value.path()).read_text()
    assert csv_text.splitlines()[0].startswith("#") or "," in csv_text.splitlines()[0]
    assert len(csv_text.splitlines()) > points

    page.select_option("#method", "seed003")
    expect(page.locator("#radius-plot .gtitle")).to_contain_text("seed003")
    page.shots("results-seed003")

    page.click("nav a[href='/fleet']")
    page.click("#campaigns-table a")
    expect(page.locator("#fleet-heading")).to_contain_text("1 / 1 sensors done")
    expect(page.locator("#fleet tbody tr")).to_have_count(1)
    expect(page.locator("#fleet tbody tr td").nth(5)).to_have_text("physical")
    page.shots("fleet")


# -- the physical plan: launcher → live run → results -------------------------------------------------------
def test_a_physical_campaign_from_the_launcher_to_its_results(page, server):
    _, token = server
    page.goto("/launch")
    paste_token(page, token)
    page.select_option("#campaign-form select[name=plan]", "physical")
    physical = page.locator("fieldset[data-plan=physical]")
    expect(physical).to_be_visible()
    expect(page.locator("fieldset[data-plan=seed003]")).to_be_hidden()
    expect(physical.locator("input[name=first_batch]")).to_have_value("16")
    page.shots("physical-form")

    # a field beyond the model's limit: refused, the field named and marked
    physical.locator("input[name=first_batch]").fill("5")
    page.click("#dry-run")
    expect(page.locator("#message")).to_have_text("invalid campaign: physical.first_batch: Input should be greater "
                                                  "than or equal to 10")
    expect(physical.locator("input[name=first_batch]")).to_have_class(re.compile(r"\binvalid\b"))
    physical.locator("input[name=first_batch]").fill("16")
    physical.locator("summary", has_text="in its own unit").click()
    physical.locator("input[name='parameter_targets.x0_px']").fill("0.05")

    page.click("#dry-run")
    expect(page.locator("#message")).to_have_text("dry run ok: nothing moved")
    expect(physical.locator("input[name=first_batch]")).not_to_have_class(re.compile(r"\binvalid\b"))
    expect(page.locator("#d-points")).to_have_text(re.compile(r"^at most \d+$"))
    cap = int(page.locator("#d-points").inner_text().removeprefix("at most "))
    assert cap == 16 + 2 * 8 + 8  # the procedure's defaults: every batch and the check directions
    expect(page.locator("#d-duration")).to_have_text(re.compile(r"^at most \d+ min \d+ s$"))
    expect(page.locator("#d-summary")).to_have_text(re.compile(
        rf"^at most {cap} points, at most \d+ frames, at most \d+ moves per sensor × 1 sensor\(s\); "
        r"at most [\d.]+ min of bench time in all \(of which [\d.]+ min lamp warm-up\), at most [\d.]+ min of "
        r"wall time$"))
    expect(page.locator("#d-bound")).to_contain_text("Upper bounds, every point counted")
    page.shots("physical-dry-run")

    page.click("#start")
    expect(page.locator("#started")).to_contain_text("queued")
    page.click("#started a[href='/run']")
    expect(page.locator("#stream-state")).to_have_text("connected")
    expect(page.locator("#result-link a")).to_be_visible(timeout=TIMEOUT_MS)
    expect(page.locator("#log")).to_contain_text("finished: completed")
    expect(page.locator("#run-title")).to_contain_text("plan physical")
    # its total is its cap: an upper bound, and a run that stopped before it is complete all the same; the count is
    # the catalogue's once the run has ended (a page that joined midway may have missed points on the stream)
    run_id = int(page.locator("#result-link a").get_attribute("href").rsplit("=", 1)[1])
    recorded = _api(server, f"/api/runs/{run_id}")["n_points_recorded"]
    assert 16 + 8 <= recorded <= cap  # the first batch and the check directions, at least
    expect(page.locator("#progress-text")).to_have_text(f"{recorded} / at most {cap}")
    expect(page.locator("#bound-note")).to_be_visible()
    assert page.eval_on_selector("#progress", "p => p.value / p.max") == 1.0
    expect(page.locator("#log")).to_contain_text("batch 1/3")  # the stopping rule's verdict after each batch
    page.shots("physical-finished")

    page.click("#result-link a")
    expect(page).to_have_url(re.compile(r"/results\?run=\d+$"))
    expect(page.locator("#run-info")).to_contain_text(f"physical, completed, {recorded} / at most {cap} points")
    expect(page.locator("#metrics tbody tr.chosen")).to_have_count(1)
    # the stopping rule's records: one row per batch measured, the final decision, 1σ against the targets
    expect(page.locator("#stopping-section")).to_be_visible()
    batches = page.locator("#batches tbody tr")
    expect(batches.first).to_be_visible()
    expect(page.locator("#stopping-verdict")).to_contain_text(f"Stopped after batch {batches.count()} of 3")
    expect(page.locator("#sigmas tbody tr")).to_have_count(9)
    expect(page.locator("#sigmas tbody tr", has_text="x0_px").locator("td").nth(1)).to_have_text("0.0500")
    # the directions are scattered: fig. 4.7's line per azimuth gives way to points against zenith
    expect(page.locator("#zenith-residual-heading")).to_contain_text("against zenith")
    for plot in ("spot-plot", "radius-plot", "zenith-residual-plot", "azimuth-plot", "error-plot"):
        expect(page.locator(f"#{plot} .main-svg").first).to_be_visible()
        assert plot_points(page, plot) >= 10, plot
    assert page.url.endswith(f"?run={run_id}")
    left = [p for p in _api(server, f"/api/runs/{run_id}/fit")["data"] if p["excluded"] and p["zenith_deg"] > 0.5]
    assert page.locator("#zenith-residual-plot .scatterlayer .trace").count() == 1 + bool(left)
    page.shots("physical-results")

    page.goto("/results")
    physical_row = page.locator("#runs-table tbody tr", has_text="physical").first
    expect(physical_row).to_contain_text(f"{recorded} / at most {cap}")
    campaign_id = _api(server, f"/api/runs/{run_id}")["campaign_id"]
    page.goto(f"/fleet?campaign={campaign_id}")  # its point total is a cap there too
    expect(page.locator("#fleet tbody tr td").nth(4)).to_have_text(f"{recorded} / at most {cap}")


# -- a calibration's quality and uncertainty ----------------------------------------------------------------
SMALL = {"name": "small", "frames": "none",
         "seed003": {"azimuth_step_deg": 90.0, "repeats": 1, "centre_repeats": 1, "tilt_stage": False}}


def _api(server, path, body=None):
    base, token = server
    request = urllib.request.Request(base + path, data=None if body is None else json.dumps(body).encode(),
                                     headers={"Authorization": f"Bearer {token}", "Content-Type": "application/json"})
    return json.loads(urllib.request.urlopen(request, timeout=10).read())


def _fitted_run(server, timeout_s=60.0) -> int:
    """A completed run with its calibrations: one an earlier test left, else a small campaign run now."""
    def fitted():
        return [r["id"] for r in _api(server, "/api/runs")["data"]
                if r["status"] == "completed" and _api(server, f"/api/runs/{r['id']}/calibrations")["count"]]
    if not fitted():
        _api(server, "/api/campaigns", SMALL)
    deadline = time.monotonic() + timeout_s
    while not fitted():
        assert time.monotonic() < deadline, "the small campaign did not finish"
        time.sleep(0.2)
    return fitted()[-1]


def test_the_results_page_shows_the_quality_the_rejected_frames_and_the_uncertainty_map(page, server):
    """The page draws what the calibration documents carry; the quality and the rejected frames are put into
    the API's answer here (the fit that writes them is tested in tests/calibration), and so is the uncertainty
    map while the run's document lacks it."""
    run_id = _fitted_run(server)
    calibrations = _api(server, f"/api/runs/{run_id}/calibrations")["data"]
    chosen = next(c for c in calibrations if c["chosen"])
    assert chosen["method"].startswith("physical")
    other = next(c["method"] for c in calibrations if not c["chosen"] and not c["metrics"].get("error"))
    document = _api(server, f"/api/calibrations/{run_id}/{chosen['method']}.json")
    umap = uncertainty_document(calibration_from_dict(document))
    warning = "χ²/dof is 3.4: the model misses the data by more than the repeat scatter"
    quality = {"chi2_dof": 3.4, "repeat_scatter_px": 0.021, "residual_rms_px": 0.038, "warnings": [warning]}
    rejected = [{"row": 17, "zenith_deg": 30.0, "azimuth_deg": 45.0, "x_px": 301.2, "y_px": 250.9, "offset_px": 6.3,
                 "reason": "6.3 px from the model"}]

    def with_quality(route):
        response = route.fetch()
        if not response.ok:  # before the token is pasted: the API's refusal, as it is
            route.fulfill(response=response)
            return
        body = response.json()
        for c in body["data"]:
            if c["method"] == chosen["method"]:
                c.update(quality=quality, rejected=rejected, uncertainty_map=c["uncertainty_map"] or umap)
            elif c["method"] == other:  # as a document written before these fields
                c.update(quality=None, rejected=None, uncertainty_map=None)
        route.fulfill(response=response, json=body)
    page.route(re.compile(r"/api/runs/\d+/calibrations$"), with_quality)
    # a point the calibration rejected (the fit route says so from the document's `rejected`: tested in
    # tests/web/test_excluded_points.py), drawn apart with the calibration's reason
    fits = []

    def with_rejected(route):
        response = route.fetch()
        if not response.ok:
            route.fulfill(response=response)
            return
        body = response.json()
        target = next(p for p in body["data"] if not p["excluded"] and p["zenith_deg"] > 20)
        target["excluded"] = rejected[0]["reason"]
        fits.append(body)
        route.fulfill(response=response, json=body)
    page.route(re.compile(r"/api/runs/\d+/fit\?method=.*$"), with_rejected)

    page.goto("/results")
    paste_token(page, server[1])
    page.goto(f"/results?run={run_id}")
    expect(page.locator("#quality-warnings")).to_be_visible()
    expect(page.locator("#quality-warnings li")).to_have_text([warning])
    expect(page.locator("#quality-figures")).to_contain_text("3.40")
    expect(page.locator("#rejected tbody tr")).to_have_count(1)
    expect(page.locator("#rejected tbody tr td").last).to_have_text("6.3 px from the model")
    expect(page.locator("#uncertainty-plot .main-svg").first).to_be_visible()
    cells = len(umap["zenith_deg"]) * len(umap["azimuth_deg"])
    assert page.locator("#uncertainty-plot .barlayer .point").count() == cells
    expect(page.locator("#uncertainty-plot .colorbar")).to_contain_text("1σ pointing uncertainty [°]")
    left = [p for p in fits[-1]["data"] if p["excluded"]]
    assert {p["excluded"] for p in left} >= {"6.3 px from the model"}
    _expect_left_out(page, left)
    page.shots("quality-and-uncertainty")

    # a document without them (an older one, or a polynomial fit's map): no box, no table, no map
    page.select_option("#method", other)
    expect(page.locator("#radius-plot .gtitle")).to_contain_text(other)
    expect(page.locator("#quality-section")).to_be_hidden()
    expect(page.locator("#uncertainty-section")).to_be_hidden()


# -- the bench page -----------------------------------------------------------------------------------------
def test_the_bench_page_lights_the_lamp_opens_the_shutter_and_jogs(page, server):
    _, token = server
    page.goto("/")
    paste_token(page, token)
    expect(page.locator("#s-engine")).to_have_text(re.compile(r"^idle"))

    page.click("#lamp-on")
    expect(page.locator("#message")).to_have_text("lamp on")  # the command's answer, not an earlier state
    expect(page.locator("#s-lamp")).to_contain_text("on")
    page.click("#shutter-open")
    expect(page.locator("#message")).to_have_text("shutter open")
    expect(page.locator("#s-shutter")).to_have_text("open")
    jog_to(page, 45, 20)
    page.fill("#jog-step", "10")
    page.click("[data-jog='zen:1']")
    expect(page.locator("#s-zen")).to_have_text("30.000°")
    zenith = 30.0
    # the frame with its spot marked (refreshed every 2 s)
    expect(page.locator("#spot-text")).to_contain_text("spot at (", timeout=15_000)
    page.shots("lamp-on-shutter-open")

    # beyond the soft limits: refused before anything moves
    page.fill("#jog-form input[name=zenith_deg]", "95")
    page.click("#jog-form button[type=submit]")
    expect(page.locator("#message")).to_contain_text("Refused: 422")
    expect(page.locator("#s-zen")).to_have_text(f"{zenith:.3f}°")
    page.shots("refused-jog")

    page.click("#shutter-close")
    expect(page.locator("#s-shutter")).to_have_text("closed")
    page.click("#shutter-open")
    expect(page.locator("#s-shutter")).to_have_text("open")
    page.click("#lamp-off")  # standby: the shutter closes; the simulated bench's arc lamp keeps burning
    expect(page.locator("#message")).to_have_text("lamp to standby")
    expect(page.locator("#s-shutter")).to_have_text("closed")
    expect(page.locator("#s-lamp")).to_have_text("on")
    jog_to(page, 0, 0)


def test_the_bench_page_follows_a_run_and_its_emergency_stop_latches(page, server):
    """During a run the bench page shows what the engine does (the lamp lit, the shutter open, "updated" moving
    on), its manual buttons disabled; after EMERGENCY STOP the latch shows, moves and lights stay disabled until
    "Acknowledge e-stop"."""
    _, token = server
    page.goto("/")
    paste_token(page, token)
    expect(page.locator("#s-engine")).to_have_text(re.compile(r"^idle"))
    manual = ("#lamp-on", "#shutter-open", "#jog-form button[type=submit]", "[data-jog='az:1']")
    try:
        _api(server, "/api/campaigns", {"name": "e-stop", "frames": "none"})  # seed 003: ~10 s at 100×
        expect(page.locator("#s-engine")).to_have_text(re.compile(r"^running"))
        expect(page.locator("#s-shutter")).to_have_text("open")  # the engine opened it (it used to stay "closed")
        expect(page.locator("#s-lamp")).to_contain_text("on")
        updated, azimuth = page.locator("#s-updated").inner_text(), page.locator("#s-az").inner_text()
        page.wait_for_function("([u, a]) => document.querySelector('#s-updated').textContent !== u "
                               "&& document.querySelector('#s-az').textContent !== a", arg=[updated, azimuth])
        for button in (*manual, "#lamp-off", "#shutter-close"):
            expect(page.locator(button)).to_be_disabled()  # a run owns the bench
        expect(page.locator("#stop")).to_be_enabled()
        expect(page.locator("#estop-box")).to_be_hidden()
        expect(page.locator("#estop-ack")).to_be_disabled()
        page.shots("running")

        page.click("#stop")
        expect(page.locator("#message")).to_contain_text("emergency stop latched: table stopped, shutter closed")
        expect(page.locator("#estop-box")).to_be_visible()
        expect(page.locator("#s-engine")).to_have_text(re.compile(r"^estop"))
        expect(page.locator("#s-shutter")).to_have_text("closed")
        expect(page.locator("#estop-ack")).to_be_enabled()
        for button in manual:
            expect(page.locator(button)).to_be_disabled()
        for button in ("#lamp-off", "#shutter-close"):  # they make the bench safer
            expect(page.locator(button)).to_be_enabled()
        page.shots("latched")

        page.click("#estop-ack")
        expect(page.locator("#message")).to_have_text("emergency stop acknowledged: the bench may move and light again")
        expect(page.locator("#estop-box")).to_be_hidden()
        expect(page.locator("#s-engine")).to_have_text(re.compile(r"^idle"))
        for button in manual:
            expect(page.locator(button)).to_be_enabled()
        jog_to(page, 0, 0)  # the bench moves again
    finally:  # the next tests need a bench that is not latched
        try:
            _api(server, "/api/stop/acknowledge", {})
        except urllib.error.HTTPError:
            pass  # nothing latched


# -- refusals -----------------------------------------------------------------------------------------------
def test_without_the_token_the_launcher_asks_for_it_and_refuses_bad_campaigns(page, server):
    _, token = server
    page.goto("/launch")
    page.click("#dry-run")
    expect(page.locator("#message")).to_contain_text("no token: paste the token")
    expect(page.locator("#token-box")).to_have_attribute("open", "")
    page.shots("no-token")

    paste_token(page, token)
    page.fill("#campaign-form input[name=zenith_stage_deg]", "0, 10, 20, 30, 40, 50, 95")
    page.click("#dry-run")
    expect(page.locator("#message")).to_have_text("the campaign would be refused")
    violations = page.locator("#violations li")
    assert violations.count() >= 1 and "95" in violations.first.inner_text()
    page.click("#start")
    expect(page.locator("#message")).to_have_text("preflight refused the campaign: see the violations")
    page.fill("#campaign-form input[name=zenith_stage_deg]", "0, 10, 20")
    page.click("#dry-run")
    expect(page.locator("#message")).to_have_text("invalid campaign: seed003.zenith_stage_deg: Value error, "
                                                  "a 6th-order θ(r) needs at least 7 zenith angles")
    page.shots("refused")
    expect(page.locator("#started")).to_have_text("")  # nothing was queued


# -- run control --------------------------------------------------------------------------------------------
def test_pause_resume_and_abort_from_the_live_run_page(page, server):
    _, token = server
    page.goto("/launch")
    paste_token(page, token)
    page.click("#start")
    expect(page.locator("#started")).to_contain_text("queued")
    page.goto("/run")
    expect(page.locator("#stream-state")).to_have_text("connected")
    expect(page.locator("#engine-state")).to_have_text("running")
    # Pause only while running, Resume only while paused
    expect(page.locator("#pause")).to_be_enabled()
    expect(page.locator("#resume")).to_be_disabled()
    expect(page.locator("#abort")).to_be_enabled()
    # each point as it lands: its stage, angles, exposure, spots; the latest frame; a log line per point and
    # per stage result
    expect(page.locator("#n-table")).to_have_text(re.compile(r"^azimuth -?\d+\.\d{3}°, zenith stage -?\d+\.\d{3}°$"))
    expect(page.locator("#n-exposure")).to_have_text(re.compile(r"^\d+\.\d{3} ms$"))
    expect(page.locator("#n-stage")).not_to_have_text("–")
    expect(page.locator("#n-spots")).to_contain_text(" px")
    expect(page.locator("#frame-text")).to_contain_text("spot at (")
    expect(page.locator("#log li.point").first).to_contain_text("→ (")
    expect(page.locator("#log li.result", has_text="centre (normal incidence) at (")).to_have_count(1, timeout=30_000)

    page.click("#pause")
    expect(page.locator("#engine-state")).to_have_text("paused")
    expect(page.locator("#pause")).to_be_disabled()
    expect(page.locator("#resume")).to_be_enabled()
    index = page.eval_on_selector("#progress", "p => p.value")
    time.sleep(1.0)  # 100 s of bench time: a running campaign would have recorded points meanwhile
    assert page.eval_on_selector("#progress", "p => p.value") == index
    page.shots("paused")

    page.click("#resume")
    expect(page.locator("#engine-state")).to_have_text("running")
    # a function, not an expression: Playwright evaluates an expression with eval, which the pages' CSP forbids
    page.wait_for_function(f"() => document.querySelector('#progress').value > {index}")

    page.once("dialog", lambda dialog: dialog.accept())  # "Abort the run? Its recorded points stay."
    page.click("#abort")
    expect(page.locator("#log")).to_contain_text("finished: aborted")
    expect(page.locator("#engine-state")).to_have_text("idle")
    for button in ("#pause", "#resume", "#abort"):
        expect(page.locator(button)).to_be_disabled()
    page.shots("aborted")
    page.click("#result-link a")
    expect(page.locator("#run-info")).to_contain_text("aborted")


# -- read-only views without the token ----------------------------------------------------------------------
def test_with_public_read_the_pages_show_without_the_token_and_commands_still_ask_for_it(browser, tmp_path):
    with serving(tmp_path, None, "--time-scale", str(TIME_SCALE), "--public-read") as served:
        base = served.base
        context = browser.new_context(base_url=base, viewport={"width": 1280, "height": 900})
        page = context.new_page()
        shots = Shots(page, "public-read")
        try:
            page.goto("/")
            expect(page.locator("#token-state")).to_have_text("no token")
            expect(page.locator("#s-engine")).to_have_text(re.compile(r"^idle"))  # the status, read freely
            expect(page.locator("#s-az")).to_have_text(re.compile(r"^-?\d+\.\d{3}°$"))
            expect(page.locator("#bench-banner")).to_contain_text("Simulated bench")
            page.click("#lamp-on")
            expect(page.locator("#message")).to_contain_text("no token: paste the token")
            expect(page.locator("#s-lamp")).to_have_text("off")  # nothing was lit
            shots("bench-refused")

            page.goto("/run")
            expect(page.locator("#stream-state")).to_have_text("connected")  # events without the token
            page.goto("/launch")
            page.click("#dry-run")
            expect(page.locator("#d-nviol")).to_have_text("none")  # a dry run reads, it moves nothing
            page.click("#start")
            expect(page.locator("#message")).to_contain_text("no token: paste the token")
            expect(page.locator("#started")).to_have_text("")
            shots("launch-refused")
        finally:
            context.close()


# -- a fleet's next sensor, and a stopped run resumed (issue 10) ------------------------------------------------
def _campaign_status(server, campaign_id):
    return next(c["status"] for c in _api(server, "/api/campaigns")["data"] if c["id"] == campaign_id)


def test_the_live_run_page_asks_for_each_next_sensor_of_a_fleet_and_confirms_it(page, server):
    _, token = server
    page.goto("/run")
    paste_token(page, token)
    expect(page.locator("#stream-state")).to_have_text("connected")
    campaign_id = _api(server, "/api/campaigns", {**SMALL, "name": "fleet", "sensors": ["SIM-0001", "FM-102"]})[
        "campaign_id"]
    prompt = page.locator("#mount-prompt")
    expect(prompt).to_be_visible(timeout=TIMEOUT_MS)  # once the first sensor is measured
    text = f"Mount sensor FM-102 on the bench (sensor 2 of 2 of campaign {campaign_id})"
    expect(page.locator("#mount-text")).to_have_text(text)
    expect(page.locator("#engine-state")).to_have_text("idle")  # the bench waits for the operator
    page.shots("mount-prompt")
    page.reload()  # a page opened meanwhile asks too: the status says what the bench waits for
    expect(page.locator("#mount-text")).to_have_text(text)
    assert _campaign_status(server, campaign_id) == "running"

    page.click("#mount-confirm")
    expect(page.locator("#message")).to_have_text("sensor FM-102 confirmed mounted")
    expect(prompt).to_be_hidden()
    expect(page.locator("#run-title")).to_contain_text("sensor FM-102")
    expect(page.locator("#log")).to_contain_text(f"campaign-finished: campaign {campaign_id}: completed")
    page.shots("fleet-done")
    page.goto(f"/fleet?campaign={campaign_id}")
    expect(page.locator("#fleet-heading")).to_contain_text("2 / 2 sensors done")
    expect(page.locator("#campaign-stopped")).to_be_hidden()


def test_a_stopped_run_resumes_from_the_live_run_page(page, server):
    _, token = server
    # 64 points: long enough at 100× to be stopped midway
    longer = {**SMALL, "name": "to-resume", "seed003": {**SMALL["seed003"], "azimuth_step_deg": 45.0}}
    campaign_id = _api(server, "/api/campaigns", longer)["campaign_id"]
    deadline = time.monotonic() + TIMEOUT_MS / 1000
    while not any(r["campaign_id"] == campaign_id and r["n_points_recorded"] >= 3
                  for r in _api(server, "/api/runs")["data"]):
        assert time.monotonic() < deadline, "the run recorded no points"
        time.sleep(0.02)
    _api(server, "/api/run/abort", {})
    _wait_idle(server)
    (run,) = [r for r in _api(server, "/api/runs")["data"] if r["campaign_id"] == campaign_id]
    assert run["status"] == "aborted" and _campaign_status(server, campaign_id) == "aborted"

    page.goto(f"/results?run={run['id']}")
    paste_token(page, token)
    # the results page offers it too, and leads to the live run page of that run
    expect(page.locator("#resume-box")).to_be_visible()
    expect(page.locator("#resume-text")).to_contain_text("This run aborted (aborted by the operator)")
    expect(page.locator("#resume-link")).to_have_attribute("href", f"/run?run={run['id']}")
    page.goto(f"/fleet?campaign={campaign_id}")
    expect(page.locator("#campaign-stopped")).to_be_visible()  # the fleet page offers the campaign's rest too
    expect(page.locator("#campaign-stopped-text")).to_contain_text("This campaign aborted; 1 sensor(s) not done.")
    page.goto("/run")
    box = page.locator("#resume-box")
    expect(box).to_be_visible()
    expect(page.locator("#resume-text")).to_contain_text(f"Run {run['id']} (sensor SIM-0001) aborted: aborted by "
                                                         "the operator")
    page.shots("resume-offered")
    page.click("#resume-run")
    expect(page.locator("#message")).to_have_text(f"run {run['id']} queued to resume")
    expect(page.locator("#log")).to_contain_text(f"campaign-finished: campaign {campaign_id}: completed")
    page.shots("resumed")
    runs = [r for r in _api(server, "/api/runs")["data"] if r["campaign_id"] == campaign_id]
    assert [(r["parent_run_id"], r["status"]) for r in runs] == [(None, "aborted"), (run["id"], "completed")]
    assert runs[1]["n_points_recorded"] == 64 - runs[0]["n_points_recorded"]  # only what the first missed
    expect(box).to_be_hidden()  # nothing left to resume


# -- telling the truth: the token, the simulated bench, the docs, Start, an unsafe end, a restart (issue 10) -----
def test_a_wrong_token_is_said_refused_and_clears_once_the_right_one_is_pasted(page, server):
    _, token = server
    run_id = _fitted_run(server)
    page.goto(f"/results?run={run_id}")
    expect(page.locator("#message")).to_contain_text("no token: paste the token")
    paste_token(page, "wrong-token-0123456789abcdef", state="token refused")
    expect(page.locator("#message")).to_contain_text("token refused: the server does not know the token pasted")
    page.shots("wrong-token")
    paste_token(page, token)
    expect(page.locator("#metrics tbody tr.chosen")).to_have_count(1)
    expect(page.locator("#message")).to_have_text("")  # the old refusal is gone with the token it was about
    expect(page.locator("#token-state")).to_have_text("token set")
    page.shots("right-token")


def test_every_page_says_the_bench_is_simulated_and_at_what_time_scale(page, server):
    for path in ("/", "/launch", "/run", "/results", "/fleet", "/results?run=1"):
        page.goto(path)
        banner = page.locator("#bench-banner")
        expect(banner).to_be_visible()
        expect(banner).to_contain_text("Simulated bench: nothing real moves, lights or measures; time scale 100: "
                                       "its time runs 100× as fast as the wall clock (a bench hour takes 36 s of "
                                       "wall time)")
    page.shots("banner")


def test_the_api_docs_work_offline(page, server):
    base, _ = server
    requested = []
    page.on("request", lambda request: requested.append(request.url))
    page.goto("/docs")
    expect(page.locator(".opblock").first).to_be_visible()
    assert page.locator(".opblock").count() >= 25  # every route, from /openapi.json
    expect(page.locator(".information-container")).to_contain_text("sunbench")
    page.shots("docs")
    elsewhere = [url for url in requested if not url.startswith(base)]
    assert requested and not elsewhere, elsewhere


def test_a_double_clicked_start_queues_one_campaign(page, server):
    _, token = server
    page.goto("/launch")
    paste_token(page, token)
    page.fill("#campaign-form input[name=azimuth_step_deg]", "90")
    page.fill("#campaign-form input[name=repeats]", "1")
    page.fill("#campaign-form input[name=centre_repeats]", "1")
    page.uncheck("#campaign-form input[name=tilt_stage]")
    before = _api(server, "/api/campaigns")["count"]
    page.dblclick("#start")
    expect(page.locator("#message")).to_have_text(re.compile(r"^campaign \d+ queued$"))
    campaign_id = int(page.locator("#message").inner_text().split()[1])
    page.click("#start")  # again, the form unchanged: the same key, nothing more queued
    expect(page.locator("#message")).to_have_text(f"campaign {campaign_id} was queued already by this Start: nothing "
                                                  "more was queued (change the form to queue another)")
    page.shots("double-start")
    assert _api(server, "/api/campaigns")["count"] == before + 1
    _wait_idle(server)


def test_a_run_that_ended_unsafe_is_said_first_on_the_run_and_results_pages(page, server):
    _, token = server
    run_id = _fitted_run(server)
    unsafe = ("ended unsafe: the shutter did not close (no answer from the shutter controller); the lamp was "
              "switched off instead")

    def status(route):  # as the service says it once the engine's "unsafe" event came (tests/web/test_api.py)
        response = route.fetch()
        body = response.json()
        if response.ok:
            body["engine"].update(state="idle", run_id=run_id, ended_unsafe=unsafe)
        route.fulfill(response=response, json=body)

    def run(route):
        response = route.fetch()
        body = response.json()
        if response.ok:
            body["exit_reason"] = unsafe
        route.fulfill(response=response, json=body)
    page.route(re.compile(r"/api/status$"), status)
    page.route(re.compile(rf"/api/runs/{run_id}$"), run)
    said = (f"RUN {run_id} ENDED UNSAFE: the shutter did not close (no answer from the shutter controller); the lamp "
            "was switched off instead. See to the bench (shutter, lamp, table) before the next run.")
    page.goto("/run")
    paste_token(page, token)
    expect(page.locator("#unsafe-box")).to_have_text(said)
    page.shots("run-unsafe")
    page.goto(f"/results?run={run_id}")
    expect(page.locator("#unsafe-box")).to_have_text(said)
    page.shots("results-unsafe")


def test_after_a_restart_the_run_page_links_the_last_run(browser, tmp_path):
    with serving(tmp_path, None, "--time-scale", str(TIME_SCALE)) as served:
        server = (served.base, served.token)
        _fitted_run(server)
    with serving(tmp_path, None, "--time-scale", str(TIME_SCALE)) as served:  # the same catalogue
        server = (served.base, served.token)
        (run,) = _api(server, "/api/runs")["data"]
        context = browser.new_context(base_url=served.base, viewport={"width": 1280, "height": 900})
        page = context.new_page()
        errors = watch_errors(page, [])
        shots = Shots(page, "restart")
        try:
            page.goto("/run")
            paste_token(page, served.token)
            expect(page.locator("#run-title")).to_have_text(f"none running · last run {run['id']} · sensor SIM-0001 "
                                                            "(cmos) · plan seed003 · completed")
            expect(page.locator("#result-link a")).to_have_attribute("href", f"/results?run={run['id']}")
            shots("last-run")
        finally:
            context.close()
        assert not errors, errors


# -- a QD bench (seed 002's quadrant photodiode): launcher → live run → its family's results view ------------------
QD_BENCH = ROOT / "examples" / "bench-sim-qd.yaml"


def _plot_traces(page: Page, plot_id: str) -> list[dict]:
    """The traces plotly holds for a plot: their type, name and number of points."""
    return page.evaluate("""id => (document.getElementById(id).data || []).map(t => ({type: t.type || "scatter",
        name: t.name, n: t.type === "heatmap" ? t.z.flat().filter(v => v !== null).length : (t.x || []).length}))""",
                         plot_id)


def test_a_qd_campaign_from_the_launcher_to_its_results_view(browser, tmp_path):
    """On a QD bench the launcher offers the QD plans only; the live run page shows currents, no frame and no spot
    map; the results page shows the QD view: every method's figures, the error map over the field, the dark
    current with its model, the quadrant currents."""
    with serving(tmp_path, None, "--bench", str(QD_BENCH), "--time-scale", "0") as served:
        server = (served.base, served.token)
        context = browser.new_context(base_url=served.base, viewport={"width": 1280, "height": 900})
        context.set_default_timeout(TIMEOUT_MS)
        page = context.new_page()
        errors = watch_errors(page, [])
        shots = Shots(page, "qd")
        try:
            page.goto("/")
            paste_token(page, served.token)
            # the bench page: the module's currents in the status, no frame to show
            expect(page.locator("#s-sensor")).to_contain_text(re.compile(r"^qd: [\d.]+ °C, currents [\d.]+ [pnµ]A, "))
            expect(page.locator("#frame-section")).to_be_hidden()
            page.goto("/launch")
            options = page.eval_on_selector_all("select[name=plan] option", "os => os.map(o => o.value)")
            assert options == ["qd-grid", "qd-physical", "qd-dark"]  # the bench's family's plans only
            expect(page.locator("fieldset[data-plan='qd-grid']")).to_be_visible()
            expect(page.locator("label[data-frames]")).to_be_hidden()  # a photodiode keeps no frame
            page.fill("fieldset[data-plan='qd-grid'] input[name=step_deg]", "10")
            page.fill("fieldset[data-plan='qd-grid'] input[name=repeats]", "2")
            page.click("#dry-run")
            expect(page.locator("#message")).to_have_text("dry run ok: nothing moved")
            expect(page.locator("#d-points")).to_have_text(str(81 + 64 + 4))  # 9 × 9 nodes, 8 × 8 checks, 4 dark
            expect(page.locator("#d-frames-label")).to_have_text("Readings per sensor")
            shots("launcher")
            # a second tab follows the run live, from its events (the token is the context's, in localStorage)
            live = context.new_page()
            watch_errors(live, errors, " (live)")
            live.goto("/run")
            expect(live.locator("#stream-state")).to_have_text("connected")
            page.click("#start")
            expect(page.locator("#started")).to_contain_text("queued")

            def fitted():
                runs = _api(server, "/api/runs")["data"]
                return runs and _api(server, f"/api/runs/{runs[-1]['id']}/calibrations")["count"] and runs[-1]
            deadline = time.monotonic() + 120
            while not fitted():
                assert time.monotonic() < deadline, "the QD campaign did not finish"
                time.sleep(0.2)
            run = fitted()
            _wait_idle(server)
            expect(live.locator("#log")).to_contain_text("finished: completed")
            expect(live.locator("#currents-section")).to_be_visible()
            expect(live.locator("#spot-section")).to_be_hidden()
            assert [t["n"] for t in _plot_traces(live, "currents-plot")] == [run["n_points_recorded"]] * 5
            expect(live.locator("#n-currents")).to_contain_text(re.compile(r"^Q1 [\d.]+ [nµ]A, Q2 .*; sum "))
            expect(live.locator("#n-stage")).to_have_text("grid")
            recorded = run["n_points_recorded"]
            expect(live.locator("#progress-text")).to_have_text(f"{recorded} / {recorded}")
            live.screenshot(path=ARTIFACTS / "qd-live-run-events.png", full_page=True)
            live.close()

            # the live run page, joined after the end: the run's currents, no frame, no spot map
            page.goto("/run")
            expect(page.locator("#run-title")).to_contain_text("(qd) · plan qd-grid")
            expect(page.locator("#currents-section")).to_be_visible()
            expect(page.locator("#spot-section")).to_be_hidden()
            expect(page.locator("#frame-part")).to_be_hidden()
            # the page draws on an animation frame after its catch-up's fetches: wait for the plot, then read it
            page.wait_for_function("""([id, n]) => {
                const data = document.getElementById(id).data || [];
                return data.length === 5 && data.every(t => (t.x || []).length === n); }""",
                                   arg=["currents-plot", run["n_points_recorded"]], timeout=TIMEOUT_MS)
            traces = _plot_traces(page, "currents-plot")
            assert [t["name"] for t in traces] == ["Q1", "Q2", "Q3", "Q4", "sum"]
            assert all(t["n"] == run["n_points_recorded"] for t in traces)
            expect(page.locator("#log")).to_contain_text("Q1 ")
            expect(page.locator("#n-currents")).to_contain_text(re.compile(r"^Q1 [\d.]+ [nµ]A, Q2 .*; sum [\d.]+ µA$"))
            expect(page.locator("#n-point")).to_contain_text(f"({run['n_points_recorded']} / ")
            shots("live-run")

            # the results: the runs list says the family, the run's page shows the QD view
            page.goto("/results")
            expect(page.locator("#runs-table tbody tr").first).to_contain_text("qd")
            page.click(f"#runs-table a[href='/results?run={run['id']}']")
            expect(page.locator("#run-heading")).to_have_text(f"Run {run['id']} · sensor SIM-0001 (qd)")
            expect(page.locator("#qd-view")).to_be_visible()
            for cmos in ("#metrics-section", "#spot-section", "#fit-plots", "#uncertainty-section"):
                expect(page.locator(cmos)).to_be_hidden()
            rows = page.locator("#qd-metrics tbody tr")
            expect(rows).to_have_count(3)  # physical, polynomial, geometric
            expect(page.locator("#qd-metrics tbody tr.chosen")).to_have_count(1)
            chosen = page.locator("#qd-metrics tbody tr.chosen td").first.inner_text().split()[0]
            metrics = _api(server, f"/api/runs/{run['id']}/qd/metrics")
            stored = next(m for m in metrics["data"] if m["chosen"])
            assert chosen == stored["method"]
            held_max = float(page.locator("#qd-metrics tbody tr.chosen td").nth(1).inner_text())
            assert held_max == pytest.approx(stored["heldout"]["max_deg"], abs=6e-5)
            for plot in ("qd-error-plot", "qd-dark-plot", "qd-currents-plot", "qd-sum-plot"):
                expect(page.locator(f"#{plot} .main-svg").first).to_be_visible()
            # the error map: the nodes as a heat map, the check points held out between them
            error = {t["name"]: t for t in _plot_traces(page, "qd-error-plot")}
            assert error["at the nodes (fitted)"]["type"] == "heatmap"
            assert error["at the nodes (fitted)"]["n"] >= 81 - 2  # all but a direction the fit left out whole
            assert error["held out (check points)"]["n"] >= 64 - 2
            expect(page.locator("#qd-error-plot .colorbar")).to_contain_text("angular error [°]")
            expect(page.locator("#qd-error-info")).to_contain_text("held out at the check points")
            # the dark current: each quadrant's readings and its model's line
            dark = _plot_traces(page, "qd-dark-plot")
            lines = [t for t in dark if t["name"].startswith("Q") and "readings" not in t["name"]]
            assert len([t for t in dark if t["name"].endswith("readings")]) == 4 and len(lines) == 4
            assert sum(t["n"] for t in dark if t["name"] == "Q1 readings") >= 4 * 8 - 2
            assert [t["name"] for t in _plot_traces(page, "qd-currents-plot")] == ["Q1", "Q2", "Q3", "Q4", "sum"]
            assert page.locator("#downloads button").all_inner_texts() == ["bench data CSV", f"{chosen} JSON",
                                                                          f"{chosen} C header"]
            shots("results")

            # another method: its map and its name
            other = next(m["method"] for m in metrics["data"] if not m["chosen"])
            page.select_option("#method", other)
            expect(page.locator("#qd-error-heading")).to_have_text(f"Angular error of {other} over the field")
            expect(page.locator("#qd-error-plot .gtitle")).to_contain_text(other)
            page.select_option("#qd-error-kind", "check")
            names = [t["name"] for t in _plot_traces(page, "qd-error-plot")]
            assert "held out (check points)" in names and "at the nodes (fitted)" not in names
            shots("results-other")
            with page.expect_download() as download:
                page.click(f"#downloads button:has-text('{other} C header')")
            assert "sunbench_qd_sun_direction" in Path(download.value.path()).read_text()

            # a dark sweep alone: no calibration, its dark current with the model fitted to its readings
            _api(server, "/api/campaigns", {"name": "dark", "plan": "qd-dark", "qd_dark": {"temperatures_c": [15, 35],
                                                                                           "repeats": 3}})
            deadline = time.monotonic() + 60
            while (len(runs := _api(server, "/api/runs")["data"]) < 2 or runs[-1]["status"] != "completed"
                   or _api(server, "/api/status")["engine"]["state"] != "idle"):
                assert time.monotonic() < deadline, "the dark sweep did not finish"
                time.sleep(0.2)
            _wait_idle(server)
            dark_run = _api(server, "/api/runs")["data"][-1]
            page.goto(f"/results?run={dark_run['id']}")
            expect(page.locator("#qd-metrics-none")).to_have_text(
                "No calibration: a dark sweep calibrates no direction (a grid run's fit uses it).")
            expect(page.locator("#qd-error-section")).to_be_hidden()
            expect(page.locator("#qd-dark-plot .gtitle")).to_contain_text("model fitted to these readings")
            assert sum(t["n"] for t in _plot_traces(page, "qd-dark-plot") if t["name"].endswith("readings")) == 4 * 6
            assert page.locator("#downloads button").all_inner_texts() == ["bench data CSV"]
            shots("results-dark-sweep")
        finally:
            shots("last")
            context.close()
        assert not errors, errors
