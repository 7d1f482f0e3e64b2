// Results of a run: the metrics of every method (table 4.1) and seed 003's figures 4.4 and 4.6–4.9.
// The radius and the fitted directions come from GET /api/runs/{id}/fit (computed by the calibration code).
/* global Plotly */
import { $, api, download, el, fmt, initTokenForm, matrixLayout, PLOT_CONFIG, plotLayout, query, report, say } from "./common.js";

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

function spotMap(points, fit, sensor) {
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
  Plotly.react("spot-plot", traces, matrixLayout("spot centres on the detector", sensor), PLOT_CONFIG);
}

// fig. 4.6: θ against r, the bench's points and the calibration through them
function radiusPlot(fit) {
  const byRadius = fit.data.slice().sort((a, b) => a.radius_px - b.radius_px);
  Plotly.react("radius-plot", [
    { type: "scatter", mode: "markers", name: "bench (true zenith)", x: fit.data.map((p) => p.radius_px),
      y: fit.data.map((p) => p.zenith_deg), marker: { size: 6 } },
    { type: "scatter", mode: "lines", name: `${fit.method} at the measured spots`, x: byRadius.map((p) => p.radius_px),
      y: byRadius.map((p) => p.zenith_fit_deg), line: { width: 1.5 } },
  ], plotLayout(`zenith vs radius from the ${fit.method} centre (${fmt(fit.x0_px, 2)}, ${fmt(fit.y0_px, 2)}) px`,
    "radius r [px]", "zenith θ [°]"), PLOT_CONFIG);
}

// the points of each bench azimuth, in zenith order
function byAzimuth(data) {
  const groups = new Map();
  for (const p of data) {
    const key = fmt(p.azimuth_deg, 1);
    if (!groups.has(key)) groups.set(key, []);
    groups.get(key).push(p);
  }
  return [...groups.entries()].sort((a, b) => Number(a[0]) - Number(b[0]))
    .map(([key, points]) => [key, points.sort((a, b) => a.zenith_deg - b.zenith_deg)]);
}

// fig. 4.7: zenith residuals, one line per azimuth (a tilted detector shows mirror-symmetric pairs)
function zenithResidualPlot(fit) {
  const traces = byAzimuth(fit.data.filter((p) => p.zenith_deg > 0.5)).map(([azimuth, points]) => ({
    type: "scatter", mode: "lines+markers", name: `φ ${azimuth}°`, x: points.map((p) => p.zenith_deg),
    y: points.map((p) => p.zenith_residual_deg), marker: { size: 5 },
  }));
  Plotly.react("zenith-residual-plot", traces, plotLayout(`zenith residuals of ${fit.method} by azimuth (fig. 4.7)`,
    "true zenith θ [°]", "θ fitted − θ true [°]"), PLOT_CONFIG);
}

// fig. 4.8: the azimuth set on the bench against the spot's azimuth φ_meas (eq. 10), with the calibration's
// azimuth, as eq. 11 relates them: φ = b1·φ_meas + b0, b1 = ±1 (a mirrored detector turns the other way).
// Near the axis the azimuth is undefined, so points within 5° of it are left out. φ_meas stays in [0°, 360°);
// the azimuths are unwrapped against b1·φ_meas + b0, so the line does not jump at 0°/360°.
const wrap = (a) => ((a + 180) % 360 + 360) % 360 - 180;

function azimuthLine(off) {
  const median = (values) => values.slice().sort((a, b) => a - b)[Math.floor(values.length / 2)] ?? 0;
  const spread = (b1) => {
    const offsets = off.map((p) => wrap(p.azimuth_deg - b1 * p.azimuth_spot_deg));
    const b0 = median(offsets);
    return { b1, b0, cost: offsets.reduce((sum, o) => sum + Math.abs(wrap(o - b0)), 0) };
  };
  const [plus, minus] = [spread(1), spread(-1)];
  return plus.cost <= minus.cost ? plus : minus;
}

function azimuthPlot(fit) {
  const off = fit.data.filter((p) => p.zenith_deg >= 5 && p.azimuth_fit_deg !== null);
  const { b1, b0 } = azimuthLine(off);
  const meas = off.map((p) => p.azimuth_spot_deg);
  const unwrap = (phi, i) => b1 * meas[i] + b0 + wrap(phi - b1 * meas[i] - b0);
  const order = off.map((_, i) => i).sort((i, j) => meas[i] - meas[j]);
  Plotly.react("azimuth-plot", [
    { type: "scatter", mode: "markers", name: "bench azimuth φ set", x: meas, y: off.map((p, i) => unwrap(p.azimuth_deg, i)),
      text: off.map((p) => `set ${fmt(p.azimuth_deg, 1)}°, zenith ${fmt(p.zenith_deg, 1)}°`), marker: { size: 6 } },
    { type: "scatter", mode: "lines", name: `${fit.method} azimuth`, x: order.map((i) => meas[i]),
      y: order.map((i) => unwrap(off[i].azimuth_fit_deg, i)), line: { width: 1.5 } },
    { type: "scatter", mode: "markers", name: "residual (right axis)", x: meas, yaxis: "y2",
      y: off.map((p) => p.azimuth_residual_deg), marker: { size: 4, symbol: "diamond" } },
  ], plotLayout(`azimuth of ${fit.method} against the spot's azimuth (fig. 4.8)`, "φ meas, eq. 10 [°]",
    `φ, unwrapped about ${b1 < 0 ? "−" : ""}φ meas ${b0 < 0 ? "−" : "+"} ${fmt(Math.abs(b0), 1)}° [°]`,
    { yaxis2: { title: { text: "residual [°]" }, overlaying: "y", side: "right", zeroline: false },
      margin: { t: 40, r: 60, b: 50, l: 60 } }), PLOT_CONFIG);
}

// azimuth is an angle: 0° and 360° get one colour
const CYCLIC = [[0, "#d62728"], [0.25, "#1f77b4"], [0.5, "#2ca02c"], [0.75, "#9467bd"], [1, "#d62728"]];

// fig. 4.9: the angle between the calibrated and the true direction, against zenith (fitted and held-out
// points together)
function errorPlot(fit) {
  Plotly.react("error-plot", [{
    type: "scatter", mode: "markers", name: "vector error", x: fit.data.map((p) => p.zenith_deg),
    y: fit.data.map((p) => p.error_deg), text: fit.data.map((p) => `azimuth ${fmt(p.azimuth_deg, 1)}°`),
    marker: { size: 6, color: fit.data.map((p) => p.azimuth_deg), colorscale: CYCLIC, cmin: 0, cmax: 360,
      colorbar: { title: { text: "azimuth [°]" } } },
    hovertemplate: "θ %{x:.1f}°: %{y:.4f}°<br>%{text}<extra></extra>",
  }], plotLayout(`vector error of ${fit.method} against zenith (fig. 4.9)`,
    "true zenith θ [°]", "vector error [°]", { showlegend: false }), PLOT_CONFIG);
}

const FIT_PLOTS = [radiusPlot, zenithResidualPlot, azimuthPlot, errorPlot];

function downloads(runId, method) {
  const button = (label, path, filename) => el("button", { onclick: () => download(path, filename).catch(report) }, label);
  $("#downloads").replaceChildren(
    button("bench data CSV", `/api/runs/${runId}/data.csv`, `run-${runId}-data.csv`),
    ...(method ? [button(`${method} JSON`, `/api/calibrations/${runId}/${method}.json`, `run-${runId}-${method}.json`),
      button(`${method} C header`, `/api/calibrations/${runId}/${method}.h`, `run-${runId}-${method}.h`)] : []));
}

async function showMethod(runId, points, method, sensor) {
  downloads(runId, method);
  let fit = null;
  if (method) {
    try { fit = await api(`/api/runs/${runId}/fit?method=${encodeURIComponent(method)}`); } catch (err) { report(err); }
  }
  spotMap(points, fit, sensor);
  $("#fit-plots").hidden = !fit;
  if (fit) for (const plot of FIT_PLOTS) plot(fit);
}

async function showRun(runId) {
  $("#run-summary").hidden = false;
  const [run, points, calibrations] = await Promise.all([
    api(`/api/runs/${runId}`), api(`/api/runs/${runId}/points`), api(`/api/runs/${runId}/calibrations`)]);
  // the detector's size for the spot map's axes: the bench's sensor now, if it answers (else the axes fit the
  // points); a run recorded with another sensor than today's still has its points drawn where they were
  const status = await api("/api/status").catch(() => null);
  $("#run-heading").textContent = `Run ${run.id} · sensor ${run.sensor_id}`;
  $("#run-info").textContent = `${run.plan_name}, ${run.status}${run.exit_reason ? ` (${run.exit_reason})` : ""}, `
    + `${run.n_points_recorded} / ${run.n_points_planned ?? "–"} points, ${run.started_utc ?? "–"} → ${run.ended_utc ?? "–"}`;
  const usable = calibrations.data.filter((c) => !c.metrics?.error);
  const chosen = usable.find((c) => c.chosen) || usable[0];
  const select = $("#method");
  select.replaceChildren(...usable.map((c) => el("option", { value: c.method, selected: c === chosen }, c.method + (c.chosen ? " (chosen)" : ""))));
  select.onchange = () => showMethod(runId, points.data, select.value, status?.sensor);
  if (calibrations.data.length) metricsTable(calibrations.data);
  if (!usable.length) {
    say(calibrations.data.length ? "every fit of this run failed: see the table"
      : `no calibration: the run ${run.status === "completed" ? "has none stored" : `was ${run.status} before its fit`}`, true);
  }
  await showMethod(runId, points.data, chosen?.method, status?.sensor);
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
