// Results of a run: spot map, zenith vs radius, the metrics of every method, residuals.
// The radius and the fitted directions come from GET /api/runs/{id}/fit (computed by the calibration code).
/* global Plotly */
import { $, api, download, el, fmt, initTokenForm, matrixLayout, PLOT_CONFIG, query, report } from "./common.js";

const runParam = query("run");

// Table 4.1: held-out figures (points not used in the fit) decide; the fitted RMS is shown for comparison
const COLUMNS = [
  ["heldout", "n_points", "n held out", 0],
  ["heldout", "rms_zenith_deg", "RMS zenith [°]", 3],
  ["heldout", "rms_azimuth_deg", "RMS azimuth [°]", 3],
  ["heldout", "rms_vector_deg", "RMS vector [°]", 3],
  ["heldout", "rms_vector_below40_deg", "RMS vector θ<40° [°]", 3],
  ["heldout", "p95_vector_deg", "p95 vector [°]", 3],
  ["heldout", "max_vector_deg", "max vector [°]", 3],
  ["heldout", "bound95_deg", "95 % bound [°]", 3],
  ["fitted", "rms_vector_deg", "fitted RMS vector [°]", 3],
];

async function listRuns() {
  $("#run-picker").hidden = false;
  const runs = (await api("/api/runs")).data.slice().reverse();
  $("#runs-table tbody").replaceChildren(...runs.map((r) => el("tr", {},
    el("td", {}, el("a", { href: `/results?run=${r.id}` }, `run ${r.id}`)), el("td", {}, r.sensor_id),
    el("td", {}, r.campaign_id ? el("a", { href: `/fleet?campaign=${r.campaign_id}` }, String(r.campaign_id)) : "–"),
    el("td", {}, r.status), el("td", {}, `${r.n_points_recorded} / ${r.n_points_planned ?? "–"}`), el("td", {}, r.ended_utc ?? "–"))));
  if (!runs.length) $("#runs-table tbody").append(el("tr", {}, el("td", { colspan: 6 }, "no run recorded yet")));
}

function metricsTable(calibrations) {
  $("#metrics-section").hidden = false;
  $("#metrics thead").replaceChildren(el("tr", {}, el("th", {}, "method"), ...COLUMNS.map((c) => el("th", {}, c[2]))));
  $("#metrics tbody").replaceChildren(...calibrations.map((c) => {
    const m = c.metrics || {};
    const cells = m.error
      ? [el("td", { colspan: COLUMNS.length }, `fit failed: ${m.error}`)]
      : COLUMNS.map(([set, key, , digits]) => el("td", {}, fmt(m[set]?.[key], digits)));
    return el("tr", { class: c.chosen ? "chosen" : "" }, el("td", {}, c.method + (c.chosen ? " ✓ chosen" : "")), ...cells);
  }));
}

function spotMap(points, fit) {
  $("#spot-section").hidden = false;
  const good = points.filter((p) => p.x_px !== null);
  const traces = [{
    type: "scatter", mode: "markers", name: "mean spot per point",
    x: good.map((p) => p.x_px), y: good.map((p) => p.y_px), text: good.map((p) => p.key),
    marker: { size: 6, color: good.map((p) => p.zenith_deg), colorscale: "Viridis", colorbar: { title: { text: "zenith [°]" } } },
    hovertemplate: "(%{x:.2f}, %{y:.2f}) px<br>%{text}<extra></extra>",
  }];
  if (fit) {
    traces.push({ type: "scatter", mode: "markers", name: `centre (${fit.method})`, x: [fit.x0_px], y: [fit.y0_px],
      marker: { symbol: "x", size: 12, color: "red" } });
  }
  Plotly.react("spot-plot", traces, { ...matrixLayout("spot centres on the detector"), legend: { orientation: "h" } }, PLOT_CONFIG);
}

function radiusPlot(fit) {
  $("#radius-section").hidden = false;
  const byRadius = fit.data.slice().sort((a, b) => a.radius_px - b.radius_px);
  Plotly.react("radius-plot", [
    { type: "scatter", mode: "markers", name: "bench (true zenith)", x: fit.data.map((p) => p.radius_px),
      y: fit.data.map((p) => p.zenith_deg), marker: { size: 6 } },
    { type: "scatter", mode: "lines", name: `${fit.method} at the measured spots`, x: byRadius.map((p) => p.radius_px),
      y: byRadius.map((p) => p.zenith_fit_deg), line: { width: 1.5 } },
  ], {
    title: { text: `zenith vs radius from the ${fit.method} centre (${fmt(fit.x0_px, 2)}, ${fmt(fit.y0_px, 2)}) px` },
    xaxis: { title: { text: "radius r [px]" } }, yaxis: { title: { text: "zenith θ [°]" } },
    margin: { t: 40, r: 10, b: 50, l: 60 }, legend: { orientation: "h" },
  }, PLOT_CONFIG);
}

function residualPlot(fit) {
  $("#residual-section").hidden = false;
  const x = fit.data.map((p) => p.zenith_deg);
  const text = fit.data.map((p) => `azimuth ${fmt(p.azimuth_deg, 1)}°`);
  Plotly.react("residual-plot", [
    { type: "scatter", mode: "markers", name: "angular error", x, y: fit.data.map((p) => p.error_deg), text },
    { type: "scatter", mode: "markers", name: "zenith residual", x, y: fit.data.map((p) => p.zenith_residual_deg), text },
  ], {
    title: { text: `residuals of ${fit.method} at the run's points (fitted and held-out together)` },
    xaxis: { title: { text: "true zenith [°]" } }, yaxis: { title: { text: "residual [°]" } },
    margin: { t: 40, r: 10, b: 50, l: 60 }, legend: { orientation: "h" },
  }, PLOT_CONFIG);
}

function downloads(runId, method) {
  const button = (label, path, filename) => el("button", { onclick: () => download(path, filename).catch(report) }, label);
  $("#downloads").replaceChildren(
    button("bench data CSV", `/api/runs/${runId}/data.csv`, `run-${runId}-data.csv`),
    ...(method ? [button(`${method} JSON`, `/api/calibrations/${runId}/${method}.json`, `run-${runId}-${method}.json`),
      button(`${method} C header`, `/api/calibrations/${runId}/${method}.h`, `run-${runId}-${method}.h`)] : []));
}

async function showMethod(runId, points, method) {
  downloads(runId, method);
  let fit = null;
  if (method) {
    try { fit = await api(`/api/runs/${runId}/fit?method=${encodeURIComponent(method)}`); } catch (err) { report(err); }
  }
  spotMap(points, fit);
  if (fit) { radiusPlot(fit); residualPlot(fit); }
}

async function showRun(runId) {
  $("#run-summary").hidden = false;
  const [run, points, calibrations] = await Promise.all([
    api(`/api/runs/${runId}`), api(`/api/runs/${runId}/points`), api(`/api/runs/${runId}/calibrations`)]);
  $("#run-heading").textContent = `Run ${run.id} · sensor ${run.sensor_id}`;
  $("#run-info").textContent = `${run.plan_name}, ${run.status}${run.exit_reason ? ` (${run.exit_reason})` : ""}, `
    + `${run.n_points_recorded} / ${run.n_points_planned ?? "–"} points, ${run.started_utc ?? "–"} → ${run.ended_utc ?? "–"}`;
  const usable = calibrations.data.filter((c) => !c.metrics?.error);
  const chosen = usable.find((c) => c.chosen) || usable[0];
  const select = $("#method");
  select.replaceChildren(...usable.map((c) => el("option", { value: c.method, selected: c === chosen }, c.method + (c.chosen ? " (chosen)" : ""))));
  select.onchange = () => showMethod(runId, points.data, select.value);
  if (calibrations.data.length) metricsTable(calibrations.data);
  await showMethod(runId, points.data, chosen?.method);
}

async function init() {
  try {
    if (runParam && /^\d+$/.test(runParam)) await showRun(Number(runParam));
    else await listRuns();
  } catch (err) {
    report(err);
  }
}

initTokenForm(init);
init();
