"""The horizon family in a real browser, as tests/web/test_browser.py drives the others: Debian's headless chromium
against `sunbench serve` on the simulated horizon bench (examples/bench-sim-horizon.yaml, time scale 0). The engineer
pastes the token, fills the launcher's horizon-grid form (a small grid: two disc radii, 36 points), dry-runs it,
starts it and watches it on the live run page in a second tab (each cone's phases and Earth chord per point), then
reads its results view — the sensor's own errors ± 1σ against the nominal design, the warnings, the held-out roll and
pitch against the nominal sensor's, each edge's phase residual per cone, the error maps over the grid, the pulse of a
reading with its threshold and edges — checked against the API, without a script error. Screenshots in
``test-artifacts/browser/horizon-*.png``."""

import re
import time

import pytest
import test_browser
from playwright.sync_api import expect
from serving import ROOT, serving
from test_browser import ARTIFACTS, TIMEOUT_MS, Shots, _api, _plot_traces, _wait_idle, paste_token, watch_errors

# the browser of test_browser.py (its fixture, here for this module)
browser = test_browser.browser

HORIZON_BENCH = ROOT / "examples" / "bench-sim-horizon.yaml"
OTHER_VIEWS = ("#metrics-section", "#spot-section", "#fit-plots", "#uncertainty-section", "#parameters-section",
               "#quality-section", "#qd-view", "#camera-view", "#css-view")
FORM = "fieldset[data-plan='horizon-grid']"


def _fill_small_grid(page) -> None:
    """Two disc radii (400 and 700 km), roll every 16.5°, pitch every 17°, two scans a pose, three check points."""
    page.fill("#campaign-form input[name=sensors]", "HZ-0001")
    page.fill(f"{FORM} input[name=altitudes_km]", "400, 700")
    page.fill(f"{FORM} input[name=roll_step_deg]", "16.5")
    page.fill(f"{FORM} input[name=pitch_step_deg]", "17")
    page.fill(f"{FORM} input[name=repeats]", "2")
    page.fill(f"{FORM} input[name=check_points]", "3")


def test_a_horizon_campaign_from_the_launcher_to_its_results_view(browser, tmp_path):
    with serving(tmp_path, None, "--bench", str(HORIZON_BENCH), "--time-scale", "0") as served:
        server = (served.base, served.token)
        context = browser.new_context(base_url=served.base, viewport={"width": 1400, "height": 1000})
        context.set_default_timeout(TIMEOUT_MS)
        page = context.new_page()
        errors = watch_errors(page, [])
        shots = Shots(page, "horizon")
        try:
            # the launcher: the bench's family's plan only, its every field with the model's default
            page.goto("/launch")
            paste_token(page, served.token)
            options = page.eval_on_selector_all("select[name=plan] option", "os => os.map(o => o.value)")
            assert options == ["horizon-grid"]
            expect(page.locator(FORM)).to_be_visible()
            expect(page.locator("label[data-frames]")).to_be_hidden()
            assert page.input_value(f"{FORM} input[name=altitudes_km]") == "400, 500, 700"
            assert page.input_value(f"{FORM} input[name=disc_radii_deg]") == ""  # blank: the altitudes decide
            expect(page.locator(f"{FORM} input[name=roll_range_deg]")).to_have_value("33")
            expect(page.locator(f"{FORM} input[name=pitch_range_deg]")).to_have_value("17")
            # a step that does not divide the range is refused, the field named
            _fill_small_grid(page)
            page.fill(f"{FORM} input[name=roll_step_deg]", "10")
            page.click("#dry-run")
            expect(page.locator("#message")).to_contain_text("the roll step must divide the roll span")
            page.fill(f"{FORM} input[name=roll_step_deg]", "16.5")
            page.click("#dry-run")
            expect(page.locator("#message")).to_have_text("dry run ok: nothing moved")
            expect(page.locator("#d-points")).to_have_text(str(2 * (5 * 3 + 3)))
            expect(page.locator("#d-frames")).to_have_text(str(2 * 2 * (5 * 3 + 3)))
            expect(page.locator("#d-frames-label")).to_have_text("Readings per sensor")
            shots("launcher")

            # a second tab follows the run live, from its events
            live = context.new_page()
            watch_errors(live, errors, " (live)")
            live.goto("/run")
            expect(live.locator("#stream-state")).to_have_text("connected")
            page.click("#start")
            expect(page.locator("#started")).to_contain_text("queued")

            def fitted():
                runs = _api(server, "/api/runs")["data"]
                return runs and _api(server, f"/api/runs/{runs[-1]['id']}/calibrations")["count"] and runs[-1]
            deadline = time.monotonic() + 60
            while not fitted():
                assert time.monotonic() < deadline, "the horizon campaign did not finish"
                time.sleep(0.2)
            run = fitted()
            _wait_idle(server)
            n = run["n_points_recorded"]
            assert n == 36 and run["sensor_id"] == "HZ-0001"
            expect(live.locator("#log")).to_contain_text("finished: completed")
            expect(live.locator("#currents-section")).to_be_visible()
            expect(live.locator("#spot-section")).to_be_hidden()
            expect(live.locator("#currents-section h2")).to_have_text("Each cone's Earth chord at each point")
            expect(live.locator("#n-currents")).to_contain_text(re.compile(
                r"^cone 1 in [\d.]+° out [\d.]+° chord [\d.]+°; cone 2 in .*; disc 6\d\.\d{3}°$"))
            expect(live.locator("#log")).to_contain_text("chord")
            live.wait_for_function("""([id, n]) => {
                const data = document.getElementById(id).data || [];
                return data.length === 2 && data.every(t => (t.x || []).length === n); }""",
                                   arg=["currents-plot", n], timeout=TIMEOUT_MS)
            assert [t["name"] for t in _plot_traces(live, "currents-plot")] == ["cone 1", "cone 2"]
            live.screenshot(path=ARTIFACTS / "horizon-live-run.png", full_page=True)
            live.close()

            # the results: the runs list says the family, the run's page shows the horizon view
            metrics = _api(server, f"/api/runs/{run['id']}/horizon/metrics")
            edges = _api(server, f"/api/runs/{run['id']}/horizon/edges")
            attitude = _api(server, f"/api/runs/{run['id']}/horizon/attitude")
            page.goto("/results")
            expect(page.locator("#runs-table tbody tr").first).to_contain_text("horizon")
            page.click(f"#runs-table a[href='/results?run={run['id']}']")
            expect(page.locator("#run-heading")).to_have_text(f"Run {run['id']} · sensor HZ-0001 (horizon)")
            expect(page.locator("#horizon-view")).to_be_visible()
            for section in OTHER_VIEWS:
                expect(page.locator(section)).to_be_hidden()
            assert page.locator("#downloads button").all_inner_texts() == [
                "bench data CSV", "crossings JSON", "crossings C header"]

            # the parameters ± 1σ against the nominal design, as the API gives them
            rows = page.locator("#horizon-parameters tbody tr")
            expect(rows).to_have_count(8)
            for k, p in enumerate(metrics["parameters"]):
                cells = rows.nth(k).locator("td")
                expect(cells.first).to_have_text(f"{p['symbol']} ({p['name']})")
                value = float(cells.nth(3).inner_text().split()[0])
                assert value == pytest.approx(p["value"], abs=6e-5)
                assert float(cells.nth(2).inner_text()) == pytest.approx(p["nominal"])
            expect(rows.nth(7)).to_have_class("muted")  # the mount's pitch: folded into the offsets, never fitted
            expect(page.locator("#horizon-figures")).to_contain_text(f"{metrics['fit']['chi2_dof']:.2f}")
            if metrics["warnings"]:
                assert page.locator("#horizon-warnings li").all_inner_texts() == metrics["warnings"]
            else:
                expect(page.locator("#horizon-ok")).to_be_visible()
            expect(page.locator("#horizon-rejected-summary")).to_contain_text(
                f"{len(metrics['rejected'])} edge(s) rejected" if metrics["rejected"] else "No edge was rejected")
            fitted_names = [p for p in metrics["parameters"] if p["fitted"]]
            assert [t["n"] for t in _plot_traces(page, "horizon-deviation-plot")] == [len(fitted_names)]
            assert _plot_traces(page, "horizon-correlation-plot")[0]["n"] == len(fitted_names) ** 2
            shots("results")
            for section in ("calibration", "deviation", "correlation"):
                page.locator(f"#horizon-{section}-section").screenshot(path=ARTIFACTS / f"horizon-{section}.png")

            # held out: the check points' roll and pitch, calibrated and nominal
            check = page.locator("#horizon-heldout tbody tr").first
            expect(check.locator("td").first).to_have_text("check points (never fitted)")
            shown = [float(check.locator("td").nth(i).inner_text()) for i in (3, 5)]
            expected = metrics["heldout"]["check"]["calibrated"]
            assert shown == pytest.approx([expected["roll_rms_deg"], expected["pitch_rms_deg"]], rel=5e-3)  # 3 digits
            expect(page.locator("#horizon-heldout tbody tr")).to_have_count(4 + len(metrics["heldout"]["radius_out"]))
            assert len(_plot_traces(page, "horizon-heldout-plot")) == 4
            expect(page.locator("#horizon-heldout-info")).to_contain_text("check scans (never fitted)")
            page.locator("#horizon-heldout-section").screenshot(path=ARTIFACTS / "horizon-heldout.png")

            # every edge's residual, a plot per cone, against roll, then the disc radius; the nominal sensor's
            assert sum(t["n"] for t in _plot_traces(page, "horizon-residuals-plot")) == edges["count"]
            expect(page.locator("#horizon-residuals-info")).to_contain_text(f"{edges['count']} edges")
            page.locator("#horizon-residuals-section").screenshot(path=ARTIFACTS / "horizon-residuals.png")
            page.select_option("#horizon-residuals-x", "radius")
            expect(page.locator("#horizon-residuals-heading")).to_contain_text("against the disc radius")
            page.select_option("#horizon-residuals-model", "nominal")
            expect(page.locator("#horizon-residuals-heading")).to_contain_text("of the nominal sensor")
            assert sum(t["n"] for t in _plot_traces(page, "horizon-residuals-plot")) == edges["count"]
            page.locator("#horizon-residuals-section").screenshot(path=ARTIFACTS / "horizon-residuals-nominal.png")

            # the error maps: 5 rolls × 3 pitches a radius, the check points on the same colours
            maps = {t["name"]: t for t in _plot_traces(page, "horizon-maps-plot")}
            assert maps["roll error at the grid's nodes"]["type"] == "heatmap"
            assert maps["roll error at the grid's nodes"]["n"] == maps["pitch error at the grid's nodes"]["n"] == 15
            assert maps["check points (never fitted)"]["n"] == 3 * 2  # each scan of the radius's 3 check points
            expect(page.locator("#horizon-maps-radius option")).to_have_count(len(attitude["maps"]))
            page.locator("#horizon-maps-section").screenshot(path=ARTIFACTS / "horizon-maps.png")
            page.select_option("#horizon-maps-model", "nominal")
            expect(page.locator("#horizon-maps-heading")).to_contain_text("of the nominal sensor")
            page.select_option("#horizon-maps-radius", "1")
            expect(page.locator("#horizon-maps-heading")).to_contain_text(f"{attitude['maps'][1]['disc_radius_deg']:.3f}°")
            page.locator("#horizon-maps-section").screenshot(path=ARTIFACTS / "horizon-maps-nominal.png")

            # the pulse of the latest scan: both cones, the threshold, the edges; then one asked for, zoomed
            latest = _api(server, f"/api/runs/{run['id']}/horizon/pulse")
            expect(page.locator("#horizon-pulse-heading")).to_have_text(
                f"The pulse of reading {latest['reading']['id']} ({latest['reading']['key']})")
            expect(page.locator("#horizon-pulse-edges tbody tr")).to_have_count(4)
            first = page.locator("#horizon-pulse-edges tbody tr").first.locator("td")
            detected = latest["cones"][0]["detected_deg"]["out"]
            assert float(first.nth(2).inner_text()) == pytest.approx(detected, abs=6e-5)
            names = [t["name"] for t in _plot_traces(page, "horizon-pulse-plot")]
            assert names.count("pulse (drawn from the calibration)") == 2 and "detected by the module" in names
            page.locator("#horizon-pulse-section").screenshot(path=ARTIFACTS / "horizon-pulse.png")
            grid = next(k for k, key in zip(attitude["reading_id"], attitude["key"]) if "roll+033" in key)
            page.fill("#horizon-reading", str(grid))
            page.select_option("#horizon-pulse-zoom", "out")
            page.click("#horizon-reading-show")
            expect(page.locator("#horizon-pulse-heading")).to_contain_text(f"reading {grid} ")
            expect(page.locator("#horizon-pulse-reading")).to_contain_text("roll 33.000°")
            span = page.evaluate("() => document.getElementById('horizon-pulse-plot').layout.xaxis.range")
            assert span[1] - span[0] == pytest.approx(6)
            page.locator("#horizon-pulse-section").screenshot(path=ARTIFACTS / "horizon-pulse-zoom.png")
            shots("results-end")
        finally:
            shots("last")
            context.close()
        assert not errors, errors
