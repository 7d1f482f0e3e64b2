"""The camera family's pages (seed 001's camera sun sensor) in a real browser, as tests/web/test_browser.py drives the
others: Debian's headless chromium against `sunbench serve` on the simulated camera bench
(examples/bench-sim-camera.yaml, time scale 0). The engineer pastes the token, finds the launcher offering the camera
grid only, dry-runs and starts a small one, and reads its results view: the figures (the fit, rings and azimuths held
out, the worse marked), the warnings in words, the camera model ± 1σ, the spots in the frame coloured by their
angular residual with their residual vectors, and the residual against the field angle. Screenshots in
``test-artifacts/browser/camera-*.png``."""

import re
import time
from pathlib import Path

import pytest
import test_browser
from playwright.sync_api import expect
from serving import ROOT, serving
from test_browser import ARTIFACTS, TIMEOUT_MS, Shots, _api, _plot_traces, _wait_idle, paste_token, watch_errors

# the browser of test_browser.py (its fixture, here for this module)
browser = test_browser.browser

CAMERA_BENCH = ROOT / "examples" / "bench-sim-camera.yaml"
#: the launcher's camera grid, kept small: 3 rings × 4 azimuths and the frame's corners reach 19 directions
RINGS, AZIMUTHS, POINTS = 3, 4, 19
#: the bench file's camera (simulation.camera.serial): on this small grid its held-out error raises a warning
SENSOR = "CAM-0001"
CMOS_SECTIONS = ("#metrics-section", "#spot-section", "#fit-plots", "#uncertainty-section", "#parameters-section",
                 "#quality-section", "#qd-view")


def test_a_camera_campaign_from_the_launcher_to_its_results_view(browser, tmp_path):
    with serving(tmp_path, None, "--bench", str(CAMERA_BENCH), "--time-scale", "0") as served:
        server = (served.base, served.token)
        context = browser.new_context(base_url=served.base, viewport={"width": 1280, "height": 900})
        context.set_default_timeout(TIMEOUT_MS)
        page = context.new_page()
        errors = watch_errors(page, [])
        shots = Shots(page, "camera")
        try:
            # the launcher on a camera bench: its one plan, with its procedure's fields
            page.goto("/launch")
            paste_token(page, served.token)
            options = page.eval_on_selector_all("select[name=plan] option", "os => os.map(o => o.value)")
            assert options == ["camera-grid"]  # the bench's family's plans only
            fieldset = page.locator("fieldset[data-plan='camera-grid']")
            expect(fieldset).to_be_visible()
            expect(fieldset.locator("legend")).to_contain_text("Camera grid procedure")
            expect(page.locator("label[data-frames]")).to_be_visible()  # a camera keeps frames
            names = fieldset.locator("input").evaluate_all("inputs => inputs.map(i => i.name)")
            assert names == ["horizontal_fov_deg", "width_px", "height_px", "rings", "azimuths", "margin_radii",
                             "repeats"]
            page.fill("input[name=sensors]", SENSOR)
            page.fill("fieldset[data-plan='camera-grid'] input[name=rings]", str(RINGS))
            page.fill("fieldset[data-plan='camera-grid'] input[name=azimuths]", str(AZIMUTHS))
            page.click("#dry-run")
            expect(page.locator("#message")).to_have_text("dry run ok: nothing moved")
            expect(page.locator("#d-points")).to_have_text(str(POINTS))
            expect(page.locator("#d-frames-label")).to_have_text("Frames per sensor")
            shots("launcher")
            # a field out of the model's limits is named by the refusal
            page.fill("fieldset[data-plan='camera-grid'] input[name=rings]", "2")
            page.click("#dry-run")
            expect(page.locator("#message")).to_contain_text("invalid campaign: camera_grid.rings")
            expect(page.locator("fieldset[data-plan='camera-grid'] input[name=rings]")).to_have_class(
                re.compile("invalid"))
            page.fill("fieldset[data-plan='camera-grid'] input[name=rings]", str(RINGS))
            page.click("#start")
            expect(page.locator("#started")).to_contain_text("queued")

            def fitted():
                runs = _api(server, "/api/runs")["data"]
                return runs and _api(server, f"/api/runs/{runs[-1]['id']}/calibrations")["count"] and runs[-1]
            deadline = time.monotonic() + 120
            while not fitted():
                assert time.monotonic() < deadline, "the camera campaign did not finish"
                time.sleep(0.2)
            _wait_idle(server)
            run = _api(server, f"/api/runs/{fitted()['id']}")
            assert (run["status"], run["results_view"], run["n_points_recorded"]) == ("completed", "camera", POINTS)
            fit = _api(server, f"/api/runs/{run['id']}/camera/fit")

            # the results: the runs list says the family, the run's page shows the camera view
            page.goto("/results")
            expect(page.locator("#runs-table tbody tr").first).to_contain_text("camera")
            page.click(f"#runs-table a[href='/results?run={run['id']}']")
            expect(page.locator("#run-heading")).to_have_text(f"Run {run['id']} · sensor {SENSOR} (camera)")
            expect(page.locator("#camera-view")).to_be_visible()
            for section in CMOS_SECTIONS:
                expect(page.locator(section)).to_be_hidden()
            # the figures: the fit, rings out, azimuths out; the worse scheme marked and the calibration judged by it
            rows = page.locator("#camera-metrics tbody tr")
            expect(rows).to_have_count(3)
            assert [rows.nth(i).locator("td").first.inner_text() for i in range(3)] == [
                "fit (every frame it used)", "rings left out", "azimuths left out"]
            worse = page.locator("#camera-metrics tbody tr.worse")
            expect(worse).to_have_count(1)
            expect(worse).to_contain_text(f"{fit['figures']['worse_scheme']} left out")
            expect(worse).to_contain_text("the worse scheme: the calibration is judged by it")
            shown_rms = float(worse.locator("td").nth(3).inner_text())
            assert shown_rms == pytest.approx(fit["figures"]["heldout_rms_deg"], abs=6e-5)
            fit_rms = float(rows.first.locator("td").nth(3).inner_text())
            assert fit_rms == pytest.approx(fit["figures"]["fit"]["rms_deg"], abs=6e-5)
            # the warnings in words (this small grid's rings are far apart: its held-out error says so)
            assert any("held-out error" in w for w in fit["warnings"]), fit["warnings"]
            expect(page.locator("#camera-warnings")).to_be_visible()
            assert page.locator("#camera-warnings li").all_inner_texts() == fit["warnings"]
            expect(page.locator("#camera-ok")).to_be_hidden()
            expect(page.locator("#camera-figures")).to_contain_text("χ²/dof")
            # the camera model: 12 parameters, each ± 1σ
            params = page.locator("#camera-parameters tbody tr")
            expect(params).to_have_count(12)
            labels = [params.nth(i).locator("td").first.inner_text() for i in range(12)]
            assert labels[0] == "fx, focal length along x [px]" and labels[4] == "k1, radial"
            assert labels[9:] == ["rotation x (tilt) [°]", "rotation y (tilt) [°]",
                                  "rotation z (about the boresight) [°]"]
            assert all(t.startswith("± ") for t in params.locator("td:nth-child(3)").all_inner_texts())
            fx = float(params.first.locator("td").nth(1).inner_text())
            assert fx == pytest.approx(fit["parameters"][0]["value"], rel=1e-6)
            expect(page.locator("#camera-parameters-note")).to_contain_text("nearly degenerate")
            # the spots in the frame, coloured by their angular residual, their residual vectors drawn to scale
            for plot in ("camera-spot-plot", "camera-error-plot"):
                expect(page.locator(f"#{plot} .main-svg").first).to_be_visible()
            spots = {t["name"]: t for t in _plot_traces(page, "camera-spot-plot")}
            assert spots["mean spot of each point"]["n"] == POINTS
            arrows = next(t for name, t in spots.items() if name.startswith("residual × "))
            assert arrows["n"] == 3 * POINTS  # a segment and a gap per point
            expect(page.locator("#camera-spot-plot .colorbar")).to_contain_text("angular residual [°]")
            expect(page.locator("#camera-spot-plot")).to_contain_text("detector 640 × 480 px")
            colours = page.evaluate("""() => document.getElementById("camera-spot-plot").data
                .find(t => t.name === "mean spot of each point").marker.color""")
            assert colours == pytest.approx([p["error_deg"] for p in fit["data"]])
            # the residual against the field angle, with the fit's and the held-out RMS as lines
            error = {t["name"]: t for t in _plot_traces(page, "camera-error-plot")}
            assert error["mean spot of each point"]["n"] == POINTS
            assert any(name.startswith("fit RMS ") for name in error)
            assert any(name.startswith("held-out RMS ") for name in error)
            expect(page.locator("#camera-error-plot .xtitle")).to_contain_text("field angle")
            expect(page.locator("#camera-error-info")).to_contain_text("over every frame the fit used")
            assert page.locator("#downloads button").all_inner_texts() == ["bench data CSV", "opencv JSON",
                                                                          "opencv C header"]
            shots("results")
            page.locator("#camera-spot-section").screenshot(path=ARTIFACTS / "camera-spot-plot.png")
            with page.expect_download() as download:
                page.click("#downloads button:has-text('opencv C header')")
            assert "sunbench_sun_direction" in Path(download.value.path()).read_text()
        finally:
            shots("last")
            context.close()
        assert not errors, errors
