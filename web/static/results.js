// Results of a run: the metrics of every method (table 4.1) and seed 003's figures 4.4 and 4.6–4.9, and of the
// calibration shown its quality (warnings, rejected frames) and its 1σ pointing uncertainty over the field; of a
// physical-plan run, its stopping rule's decision after each batch (GET /api/runs/{id}/values).
// The radius and the fitted directions come from GET /api/runs/{id}/fit (computed by the calibration code); the
// quality and the uncertainty map from the calibration documents, as GET /api/runs/{id}/calibrations serves them.
/* global Plotly */
import { $, api, download, el, fmt, initTokenForm, matrixLayout, PLOT_CONFIG, plotLayout, query, report, say, stopsEarly }
  from "./common.js";

const runParam = query("run");

// "24 / 40 points", or "24 / at most 40" for a plan whose planned points are its cap
const pointsText = (run) => `${run.n_points_recorded} / ${stopsEarly(run.plan_name) ? "at most " : ""}${run.n_points_planned ?? "–"}`;
const sig = (v) => (v === null || v === undefined || Number.isNaN(v) ? "–" : Number(v).toPrecision(3));

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
    el("td", {}, r.plan_name), el("td", {}, r.status), el("td", {}, pointsText(r)), el("td", {}, r.ended_utc ?? "–"))));
  if (!runs.length) $("#runs-table tbody").append(el("tr", {}, el("td", { colspan: 7 }, "no run recorded yet")));
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

// fig. 4.7: zenith residuals, one line per azimuth (a tilted detector shows mirror-symmetric pairs). That needs
// the bench's grid (every azimuth at several zeniths, as seed 003's 8 × 7); directions scattered over the field
// (the physical plan's) are drawn as points against zenith, coloured by their azimuth
const LINE_MIN_POINTS = 3;  // off-axis points an azimuth needs for its own line

function zenithResidualPlot(fit) {
  const off = fit.data.filter((p) => p.zenith_deg > 0.5);
  const groups = byAzimuth(off);
  const grid = groups.length > 0 && groups.every(([, points]) => points.length >= LINE_MIN_POINTS);
  $("#zenith-residual-heading").textContent = grid ? "Zenith residuals by azimuth (fig. 4.7)"
    : "Zenith residuals against zenith (no azimuth grid for fig. 4.7's lines)";
  const traces = grid ? groups.map(([azimuth, points]) => ({
    type: "scatter", mode: "lines+markers", name: `φ ${azimuth}°`, x: points.map((p) => p.zenith_deg),
    y: points.map((p) => p.zenith_residual_deg), marker: { size: 5 },
  })) : [{
    type: "scatter", mode: "markers", name: "zenith residual", x: off.map((p) => p.zenith_deg),
    y: off.map((p) => p.zenith_residual_deg), text: off.map((p) => `azimuth ${fmt(p.azimuth_deg, 1)}°, ${p.stage}`),
    marker: { size: 7, color: off.map((p) => p.azimuth_deg), colorscale: CYCLIC, cmin: 0, cmax: 360,
      colorbar: { title: { text: "azimuth [°]" } } },
    hovertemplate: "θ %{x:.1f}°: %{y:.4f}°<br>%{text}<extra></extra>",
  }];
  Plotly.react("zenith-residual-plot", traces, plotLayout(grid ? `zenith residuals of ${fit.method} by azimuth (fig. 4.7)`
    : `zenith residuals of ${fit.method} at ${off.length} directions`, "true zenith θ [°]", "θ fitted − θ true [°]",
  grid ? {} : { showlegend: false }), PLOT_CONFIG);
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

// the physical plan's stopping rule as the run recorded it (physical_batch_<k>, physical_stop): after each batch
// the check directions' RMS and every parameter's 1σ against their targets, and the final decision
function stoppingSection(physical) {
  $("#stopping-section").hidden = !physical;
  if (!physical) return;
  const { batches, stop } = physical;
  const cap = physical.n_batches ?? "–";
  $("#stopping-verdict").textContent = stop
    ? `Stopped after batch ${stop.batches_measured} of ${cap}: ${stop.reason}`
      + `${stop.reasons.length ? ` (${stop.reasons.join("; ")})` : ""}. Check RMS target ${fmt(physical.check_rms_target_deg, 4)}°; `
      + `the cap: ${physical.n_fit_directions ?? "–"} fit and ${physical.n_check_directions ?? "–"} check directions.`
    : `No final decision recorded: the plan did not reach its end (${batches.length} of ${cap} batches decided).`;
  $("#batches tbody").replaceChildren(...batches.map((b) => el("tr", { class: b.stop ? "chosen" : "" },
    el("td", {}, String(b.batch)), el("td", {}, String(b.n_fit_directions)), el("td", {}, String(b.n_check_directions)),
    el("td", {}, fmt(b.check_rms_deg, 4)), el("td", {}, fmt(b.check_max_deg, 4)),
    el("td", {}, b.stop ? "stop: every target met" : `go on: ${b.reasons.join("; ")}`))));
  const names = [...new Set(batches.flatMap((b) => [...Object.keys(b.targets), ...Object.keys(b.sigmas)]))];
  const targets = Object.assign({}, ...batches.map((b) => b.targets));
  $("#sigmas thead").replaceChildren(el("tr", {}, el("th", {}, "parameter [its unit]"), el("th", {}, "target 1σ"),
    ...batches.map((b) => el("th", {}, `1σ after batch ${b.batch}`))));
  $("#sigmas tbody").replaceChildren(...names.map((name) => el("tr", {}, el("td", {}, name), el("td", {}, sig(targets[name])),
    ...batches.map((b) => {
      const sigma = b.sigmas[name];
      const over = sigma !== null && sigma !== undefined && b.targets[name] !== undefined && !(sigma <= b.targets[name]);
      return el("td", over ? { class: "over", title: "above its target" } : {}, sig(sigma));
    }))));
}

// the fit's quality in words (its warnings first), its figures and the frames it left out; documents written
// before these were recorded have none of it (null), and then the section stays hidden
function qualitySection(record) {
  const quality = record?.quality ?? null;
  const rejected = record?.rejected ?? null;
  $("#quality-section").hidden = !quality && !rejected;
  if (!quality && !rejected) return;
  $("#quality-heading").textContent = `Quality of the ${record.method} calibration`;
  const warnings = quality?.warnings ?? [];
  $("#quality-warnings").hidden = !warnings.length;
  $("#quality-warnings ul").replaceChildren(...warnings.map((w) => el("li", {}, w)));
  $("#quality-ok").hidden = !quality || warnings.length > 0;
  const figures = quality ? [
    ["χ²/dof (residuals against the repeat scatter; 1 when the model explains the data)", fmt(quality.chi2_dof, 2)],
    ["scatter of repeated frames [px]", fmt(quality.repeat_scatter_px, 4)],
    ["RMS residual of the fit [px]", fmt(quality.residual_rms_px, 4)],
    ...(quality.frames !== null && quality.frames !== undefined
      ? [["frames fitted / bench directions", `${quality.frames} / ${quality.directions ?? "–"}`]] : [])] : [];
  $("#quality-figures").replaceChildren(...figures.flatMap(([name, value]) => [el("dt", {}, name), el("dd", {}, value)]));
  $("#rejected-part").hidden = !rejected;
  const rows = rejected ?? [];
  $("#rejected-none").hidden = rows.length > 0;
  $("#rejected").hidden = !rows.length;
  $("#rejected tbody").replaceChildren(...rows.map((r) => el("tr", {},
    el("td", {}, r.row === null || r.row === undefined ? "–" : String(r.row)), el("td", {}, fmt(r.zenith_deg, 2)),
    el("td", {}, fmt(r.azimuth_deg, 2)), el("td", {}, fmt(r.x_px, 2)), el("td", {}, fmt(r.y_px, 2)),
    el("td", {}, fmt(r.offset_px, 2)), el("td", {}, r.reason))));
}

// the calibration's 1σ pointing uncertainty (RMS vector error from its parameter covariance) on its zenith ×
// azimuth grid, as a polar map seen along the boresight: one wedge per grid node, zenith outwards
function uncertaintyPlot(record) {
  const map = record?.uncertainty_map ?? null;
  $("#uncertainty-section").hidden = !map;
  if (!map) {
    Plotly.purge("uncertainty-plot");
    return;
  }
  const zenithStep = map.zenith_deg.length > 1 ? map.zenith_deg[1] - map.zenith_deg[0] : 5;
  const azimuthStep = 360 / map.azimuth_deg.length;
  const cells = { r: [], base: [], theta: [], color: [], text: [] };
  map.zenith_deg.forEach((zenith, i) => map.azimuth_deg.forEach((azimuth, j) => {
    const sigma = map.sigma_deg[i][j];
    if (sigma === null) return;
    const low = Math.max(zenith - zenithStep / 2, 0);
    const ellipse = map.semi_major_deg ? `<br>ellipse ${fmt(map.semi_major_deg[i][j], 4)}° × ${fmt(map.semi_minor_deg[i][j], 4)}°` : "";
    cells.base.push(low);
    cells.r.push(zenith + zenithStep / 2 - low);
    cells.theta.push(azimuth);
    cells.color.push(sigma);
    cells.text.push(`θ ${fmt(zenith, 0)}°, φ ${fmt(azimuth, 0)}°: σ ${fmt(sigma, 4)}°${ellipse}`);
  }));
  const outer = map.zenith_deg[map.zenith_deg.length - 1] + zenithStep / 2;
  Plotly.react("uncertainty-plot", [{
    type: "barpolar", r: cells.r, base: cells.base, theta: cells.theta, width: azimuthStep, text: cells.text,
    marker: { color: cells.color, colorscale: "Viridis", line: { width: 0 },
      colorbar: { title: { text: "1σ pointing uncertainty [°]", side: "right" } } },
    hovertemplate: "%{text}<extra></extra>",
  }], {
    title: { text: `1σ pointing uncertainty [°] of ${record.method}` },
    polar: { bargap: 0, radialaxis: { range: [0, outer], ticksuffix: "°", angle: 0 }, angularaxis: { ticksuffix: "°" } },
    margin: { t: 50, r: 10, b: 30, l: 10 }, showlegend: false,
  }, PLOT_CONFIG);
  const noise = map.noise_sigma_deg ? Math.max(...map.noise_sigma_deg.flat().filter((v) => v !== null)) : null;
  $("#uncertainty-info").textContent = `Largest ${fmt(map.max_deg, 4)}°, RMS over the field ${fmt(map.rms_deg, 4)}°: `
    + "the RMS angle between the direction the calibration reports and the true one, from the uncertainty of its "
    + "fitted parameters (first order), zenith outwards, body azimuth around. "
    + (noise === null ? "A frame read in flight adds its own centroid noise."
      : `A frame read in flight adds its centroid noise: up to ${fmt(noise, 4)}° for ${fmt(map.noise_px, 3)} px.`);
}

function downloads(runId, method) {
  const button = (label, path, filename) => el("button", { onclick: () => download(path, filename).catch(report) }, label);
  $("#downloads").replaceChildren(
    button("bench data CSV", `/api/runs/${runId}/data.csv`, `run-${runId}-data.csv`),
    ...(method ? [button(`${method} JSON`, `/api/calibrations/${runId}/${method}.json`, `run-${runId}-${method}.json`),
      button(`${method} C header`, `/api/calibrations/${runId}/${method}.h`, `run-${runId}-${method}.h`)] : []));
}

async function showMethod(runId, points, method, sensor, calibrations) {
  downloads(runId, method);
  const record = calibrations.filter((c) => c.method === method).pop();  // the latest, as the downloads
  qualitySection(record);
  uncertaintyPlot(record);
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
  const [run, points, calibrations, values] = await Promise.all([
    api(`/api/runs/${runId}`), api(`/api/runs/${runId}/points`), api(`/api/runs/${runId}/calibrations`),
    api(`/api/runs/${runId}/values`)]);
  // the detector's size for the spot map's axes: the bench's sensor now, if it answers (else the axes fit the
  // points); a run recorded with another sensor than today's still has its points drawn where they were
  const status = await api("/api/status").catch(() => null);
  $("#run-heading").textContent = `Run ${run.id} · sensor ${run.sensor_id}`;
  $("#run-info").textContent = `${run.plan_name}, ${run.status}${run.exit_reason ? ` (${run.exit_reason})` : ""}, `
    + `${pointsText(run)} points, ${run.started_utc ?? "–"} → ${run.ended_utc ?? "–"}`;
  stoppingSection(values.physical);
  const usable = calibrations.data.filter((c) => !c.metrics?.error);
  const chosen = usable.find((c) => c.chosen) || usable[0];
  const select = $("#method");
  select.replaceChildren(...usable.map((c) => el("option", { value: c.method, selected: c === chosen }, c.method + (c.chosen ? " (chosen)" : ""))));
  select.onchange = () => showMethod(runId, points.data, select.value, status?.sensor, calibrations.data);
  if (calibrations.data.length) metricsTable(calibrations.data);
  if (!usable.length) {
    say(calibrations.data.length ? "every fit of this run failed: see the table"
      : `no calibration: the run ${run.status === "completed" ? "has none stored" : `was ${run.status} before its fit`}`, true);
  }
  await showMethod(runId, points.data, chosen?.method, status?.sensor, calibrations.data);
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
