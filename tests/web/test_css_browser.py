"""The CSS family's results view (seed 000's coarse-sun-sensor head) in a real browser, as tests/web/test_browser.py
drives the others: Debian's headless chromium against `sunbench serve` on the simulated CSS bench
(examples/bench-sim-css.yaml, time scale 0). A small css-sweep campaign (both response laws) is queued through the API;
the engineer pastes the token and reads its results view: every law's figures with the chosen one marked, the warnings
in words, the face × type grid of the 18 detectors' signals against incidence with the calibration's curves (and their
residuals, and their SNR), the parameters ± 1σ, the Sun's direction from each reading, and the thesis' quantiser codes
of the latest reading and of a chosen one — without a script error. Screenshots in
``test-artifacts/browser/css-*.png``."""

import time

import pytest
import test_browser
from playwright.sync_api import expect
from serving import ROOT, serving
from test_browser import ARTIFACTS, TIMEOUT_MS, Shots, _api, _plot_traces, _wait_idle, paste_token, watch_errors
from test_css import CSS_SWEEP

# the browser of test_browser.py (its fixture, here for this module)
browser = test_browser.browser

CSS_BENCH = ROOT / "examples" / "bench-sim-css.yaml"
OTHER_VIEWS = ("#metrics-section", "#spot-section", "#fit-plots", "#uncertainty-section", "#parameters-section",
               "#quality-section", "#qd-view", "#camera-view")


def _points(page, plot_id, names) -> int:
    """How many points the traces named `names` of a plot hold."""
    return sum(t["n"] for t in _plot_traces(page, plot_id) if t["name"] in names)


def test_a_css_runs_results_view_shows_its_detectors_directions_and_codes(browser, tmp_path):
    with serving(tmp_path, None, "--bench", str(CSS_BENCH), "--time-scale", "0") as served:
        server = (served.base, served.token)
        _api(server, "/api/campaigns", CSS_SWEEP)
        deadline = time.monotonic() + 180
        while not ((runs := _api(server, "/api/runs")["data"]) and runs[-1]["status"] == "completed"
                   and _api(server, f"/api/runs/{runs[-1]['id']}/calibrations")["count"] == 2):
            assert time.monotonic() < deadline, "the CSS campaign did not finish"
            time.sleep(0.2)
        _wait_idle(server)
        run = _api(server, f"/api/runs/{runs[-1]['id']}")
        metrics = _api(server, f"/api/runs/{run['id']}/css/metrics")
        detectors = _api(server, f"/api/runs/{run['id']}/css/detectors")
        context = browser.new_context(base_url=served.base, viewport={"width": 1400, "height": 1000})
        context.set_default_timeout(TIMEOUT_MS)
        page = context.new_page()
        errors = watch_errors(page, [])
        shots = Shots(page, "css")
        try:
            page.goto("/results")
            paste_token(page, served.token)
            expect(page.locator("#runs-table tbody tr").first).to_contain_text("css")
            page.click(f"#runs-table a[href='/results?run={run['id']}']")
            expect(page.locator("#run-heading")).to_have_text(f"Run {run['id']} · sensor CSS-0001 (css)")
            expect(page.locator("#css-view")).to_be_visible()
            for section in OTHER_VIEWS:
                expect(page.locator(section)).to_be_hidden()

            # every law's figures, the chosen one marked, the held-out RMS as the API gives it
            expect(page.locator("#css-metrics tbody tr")).to_have_count(2)
            chosen = page.locator("#css-metrics tbody tr.chosen")
            expect(chosen).to_have_count(1)
            expect(chosen.locator("td").first).to_have_text(f"{metrics['chosen']} ✓ chosen")
            held = next(m for m in metrics["data"] if m["chosen"])["held_out"]
            rms = float(chosen.locator("td").nth(1).inner_text().split(" / ")[0])
            assert rms == pytest.approx(held["rms_deg"], abs=6e-4)
            # the warnings in words, the rejected readings behind their summary
            expect(page.locator("#css-warnings")).to_be_visible()
            assert page.locator("#css-warnings li").all_inner_texts() == metrics["warnings"]
            expect(page.locator("#css-rejected-summary")).to_contain_text(f"{len(metrics['rejected'])} single reading")
            assert page.locator("#downloads button").all_inner_texts() == [
                "bench data CSV", f"{metrics['chosen']} JSON", f"{metrics['chosen']} C header"]

            # the face × type grid: 18 subplots, every reading drawn, the calibration's curves through them
            expect(page.locator("#css-curves-plot .main-svg").first).to_be_visible()
            titles = page.evaluate("id => document.getElementById(id).layout.annotations.map(a => a.text)",
                                   "css-curves-plot")
            assert len(titles) == 18 and titles[0] == "face 1 px · UV (EPD-365)" and titles[-1].startswith("face 6 mz")
            temperatures = [f"{t:.1f} °C" for t in detectors["temperatures_c"]]
            main = temperatures[detectors["main_temperature"]]
            expect(page.locator("#css-curves-heading")).to_have_text(f"Each detector's signal at {main} against the "
                                                                     f"incidence on its calibrated normal "
                                                                     f"({metrics['chosen']})")
            names = ("fitted readings", "check readings (never fitted)", "left out of the fit",
                     *(f"readings at {t}" for t in temperatures))
            assert _points(page, "css-curves-plot", names) == sum(d["count"] for d in detectors["data"])
            curves = [t for t in _plot_traces(page, "css-curves-plot") if t["name"].startswith("calibration at ")]
            n_valid = sum(d["valid"] for d in detectors["data"])
            assert len(curves) == n_valid * len(temperatures) and n_valid > 0
            # the other plate temperature's readings and curve are a click on the legend away
            hidden = page.evaluate("id => document.getElementById(id).data.filter(t => t.visible === 'legendonly')"
                                   ".map(t => t.name)", "css-curves-plot")
            assert set(hidden) == {f"{what} at {t}" for t in temperatures if t != main
                                   for what in ("readings", "calibration")}
            assert page.locator("#css-curves-plot .subplot").count() == 18
            expect(page.locator("#css-curves-info")).to_contain_text(f"{detectors['n_readings']} readings")
            shots("results")
            page.locator("#css-curves-section").screenshot(path=ARTIFACTS / "css-curves.png")

            # the parameters ± 1σ, a row per detector
            rows = page.locator("#css-parameters tbody tr")
            expect(rows).to_have_count(18)
            expect(rows.first.locator("td").nth(1)).to_contain_text("±")
            expect(page.locator("#css-parameters-heading")).to_contain_text(f"{metrics['chosen']} law")

            # the Sun's direction from each reading, its figures in words
            expect(page.locator("#css-directions-plot .main-svg").first).to_be_visible()
            assert {t["name"] for t in _plot_traces(page, "css-directions-plot")} >= {
                "at the fitted directions", "at the check directions (never fitted)"}
            expect(page.locator("#css-directions-info")).to_contain_text("Held out (directions left out of the fit")
            for section in ("metrics", "parameters", "directions"):
                page.locator(f"#css-{section}-section").screenshot(path=ARTIFACTS / f"css-{section}.png")
            # against the stated 1σ: is the uncertainty honest?
            page.select_option("#css-directions-x", "sigma")
            expect(page.locator("#css-directions-plot .xtitle")).to_have_text("stated 1σ of the direction [°]")
            assert "error = 1 × stated 1σ" in {t["name"] for t in _plot_traces(page, "css-directions-plot")}
            page.locator("#css-directions-section").screenshot(path=ARTIFACTS / "css-directions-sigma.png")

            # the thesis' codes of the latest reading: EPD and BPW matrices with either set of tables; no TPS
            latest = _api(server, f"/api/runs/{run['id']}/css/quantiser")["reading"]
            expect(page.locator("#css-quantiser-heading")).to_have_text(
                f"The thesis' quantiser codes of reading {latest['id']} ({latest['key']})")
            expect(page.locator("#css-quantiser table")).to_have_count(4)
            expect(page.locator("#css-quantiser table caption").first).to_have_text("EPDsun, listing D.6's tables")
            expect(page.locator("#css-quantiser table").first.locator("td.bit")).to_have_count(30)
            expect(page.locator("#css-quantiser-sun tbody tr")).to_have_count(6)  # truth, 2 × EPD/BPW, least squares
            expect(page.locator("#css-quantiser-note")).to_contain_text("seen temperature")
            page.locator("#css-quantiser-section").screenshot(path=ARTIFACTS / "css-quantiser.png")

            # the residuals and the SNR instead of the signals
            page.select_option("#css-curves-kind", "residual")
            expect(page.locator("#css-curves-heading")).to_contain_text("Each detector's residual")
            assert any(t["name"] == "± 1σ noise of one reading" for t in _plot_traces(page, "css-curves-plot"))
            page.select_option("#css-curves-kind", "snr")
            expect(page.locator("#css-curves-heading")).to_contain_text("signal-to-noise ratio")
            assert len(_plot_traces(page, "css-curves-plot")) == n_valid
            shots("results-snr")

            # another law: its curves, its parameters and its directions
            other = next(m["method"] for m in metrics["data"] if not m["chosen"])
            page.select_option("#method", other)
            expect(page.locator("#css-parameters-heading")).to_contain_text(f"{other} law")
            expect(page.locator("#css-curves-heading")).to_contain_text(f"({other})")
            expect(page.locator("#css-directions-plot .gtitle")).to_contain_text(other)
            # the codes of a reading asked for: the Sun on the top face's normal
            top = next(r for r in _api(server, f"/api/runs/{run['id']}/css/directions")["data"]
                       if r["zenith_deg"] is not None and r["zenith_deg"] < 1e-3)
            page.fill("#css-reading", str(top["reading_id"]))
            page.click("#css-reading-show")
            expect(page.locator("#css-quantiser-heading")).to_contain_text(f"reading {top['reading_id']} ")
            expect(page.locator("#css-quantiser-reading")).to_contain_text("elevation 90.00°")
            shots("results-other")

            # the live run page joins the finished run: its points in the log with the brightest visible diodes
            page.goto("/run")
            expect(page.locator("#log")).to_contain_text("_vis")
            expect(page.locator("#log")).to_contain_text("(sweep)")
            shots("run")
        finally:
            shots("last")
            context.close()
        assert not errors, errors
