// Results of a run, in the results view of its sensor family (GET /api/runs/{id}: `results_view`): a QD run's is
// results-qd.js, a camera run's results-camera.js, a CSS run's results-css.js, a horizon run's results-horizon.js;
// a CMOS run's is this module's.
// The CMOS view: the metrics of every method (table 4.1) and seed 003's figures 4.4 and 4.6–4.9, and of the
// calibration shown its quality (warnings, rejected frames) and its 1σ pointing uncertainty over the field; of a
// physical-plan run, its stopping rule's decision after each batch (GET /api/runs/{id}/values).
// The radius and the fitted directions come from GET /api/runs/{id}/fit (computed by the calibration code); the
// quality and the uncertainty map from the calibration documents, as GET /api/runs/{id}/calibrations serves them.
/* global Plotly */
import {
  $, api, download, el, fmt, initTokenForm, leftOutTrace, listBox, matrixLayout, methodOptions, noCalibrationReason,
  PLOT_CONFIG, plotLayout, query, report, resumable, say, splitExcluded, stopsEarly, unsafeMessage, unsafeText,
} from "./common.js";
import { showCameraRun } from "./results-camera.js";
import { showCssRun } from "./results-css.js";
import { showHorizonRun } from "./results-horizon.js";
import { showQdRun } from "./results-qd.js";

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
    el("td", {}, r.family ?? "–"),
    el("td", {}, r.campaign_id ? el("a", { href: `/fleet?campaign=${r.campaign_id}` }, String(r.campaign_id)) : "–"),
    el("td", {}, r.plan_name), el("td", {}, r.status), el("td", {}, pointsText(r)), el("td", {}, r.ended_utc ?? "–"))));
  if (!runs.length) $("#runs-table tbody").append(el("tr", {}, el("td", { colspan: 8 }, "no run recorded yet")));
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

// fig. 4.4: the mean spot of each point; those the fit left out (clipped at the detector's edge, or rejected by
// the calibration shown) apart, with why
function spotMap(points, fit, sensor) {
  $("#spot-section").hidden = false;
  const [good, left] = splitExcluded(fit ? fit.data : points.filter((p) => p.x_px !== null));
  const traces = [{
    type: "scatter", mode: "markers", name: "mean spot per point",
    x: good.map((p) => p.x_px), y: good.map((p) => p.y_px), text: good.map((p) => p.key),
    marker: { size: 6, color: good.map((p) => p.zenith_deg), colorscale: "Viridis", colorbar: { title: { text: "zenith [°]" } } },
    hovertemplate: "(%{x:.2f}, %{y:.2f}) px<br>%{text}<extra></extra>",
  }, leftOutTrace(left, (p) => p.x_px, (p) => p.y_px)].filter(Boolean);
  if (fit) {
    traces.push({ type: "scatter", mode: "markers", name: `centre (${fit.method})`, x: [fit.x0_px], y: [fit.y0_px],
      marker: { symbol: "x", size: 12, color: "red" } });
  }
  Plotly.react("spot-plot", traces, matrixLayout("spot centres on the detector", sensor), PLOT_CONFIG);
}

// fig. 4.6: θ against r, the bench's points and the calibration through them
function radiusPlot(fit) {
  const [used, left] = splitExcluded(fit.data);
  const byRadius = used.slice().sort((a, b) => a.radius_px - b.radius_px);
  Plotly.react("radius-plot", [
    { type: "scatter", mode: "markers", name: "bench (true zenith)", x: used.map((p) => p.radius_px),
      y: used.map((p) => p.zenith_deg), marker: { size: 6 } },
    { type: "scatter", mode: "lines", name: `${fit.method} at the measured spots`, x: byRadius.map((p) => p.radius_px),
      y: byRadius.map((p) => p.zenith_fit_deg), line: { width: 1.5 } },
    leftOutTrace(left, (p) => p.radius_px, (p) => p.zenith_deg),
  ].filter(Boolean), plotLayout(`zenith vs radius from the ${fit.method} centre (${fmt(fit.x0_px, 2)}, ${fmt(fit.y0_px, 2)}) px`,
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
  const [off, left] = splitExcluded(fit.data.filter((p) => p.zenith_deg > 0.5));
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
  const leftOut = leftOutTrace(left, (p) => p.zenith_deg, (p) => p.zenith_residual_deg);
  Plotly.react("zenith-residual-plot", leftOut ? [...traces, leftOut] : traces, plotLayout(grid ? `zenith residuals of ${fit.method} by azimuth (fig. 4.7)`
    : `zenith residuals of ${fit.method} at ${off.length} directions`, "true zenith θ [°]", "θ fitted − θ true [°]",
  grid || left.length ? {} : { showlegend: false }), PLOT_CONFIG);
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
  const [off, left] = splitExcluded(fit.data.filter((p) => p.zenith_deg >= 5 && p.azimuth_fit_deg !== null));
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
    leftOutTrace(left, (p) => p.azimuth_spot_deg,
      (p) => b1 * p.azimuth_spot_deg + b0 + wrap(p.azimuth_deg - b1 * p.azimuth_spot_deg - b0)),
  ].filter(Boolean), plotLayout(`azimuth of ${fit.method} against the spot's azimuth (fig. 4.8)`, "φ meas, eq. 10 [°]",
    `φ, unwrapped about ${b1 < 0 ? "−" : ""}φ meas ${b0 < 0 ? "−" : "+"} ${fmt(Math.abs(b0), 1)}° [°]`,
    { yaxis2: { title: { text: "residual [°]", font: { size: 13 } }, overlaying: "y", side: "right", zeroline: false,
      automargin: true, tickfont: { size: 12 }, nticks: 8 } }), PLOT_CONFIG);
}

// azimuth is an angle: 0° and 360° get one colour
const CYCLIC = [[0, "#d62728"], [0.25, "#1f77b4"], [0.5, "#2ca02c"], [0.75, "#9467bd"], [1, "#d62728"]];

// fig. 4.9: the angle between the calibrated and the true direction, against zenith (fitted and held-out
// points together)
function errorPlot(fit) {
  const [used, left] = splitExcluded(fit.data);
  Plotly.react("error-plot", [{
    type: "scatter", mode: "markers", name: "vector error", x: used.map((p) => p.zenith_deg),
    y: used.map((p) => p.error_deg), text: used.map((p) => `azimuth ${fmt(p.azimuth_deg, 1)}°`),
    marker: { size: 6, color: used.map((p) => p.azimuth_deg), colorscale: CYCLIC, cmin: 0, cmax: 360,
      colorbar: { title: { text: "azimuth [°]" } } },
    hovertemplate: "θ %{x:.1f}°: %{y:.4f}°<br>%{text}<extra></extra>", showlegend: false,
  }, leftOutTrace(left, (p) => p.zenith_deg, (p) => p.error_deg)].filter(Boolean), plotLayout(
    `vector error of ${fit.method} against zenith (fig. 4.9)`, "true zenith θ [°]", "vector error [°]",
    { showlegend: left.length > 0 }), PLOT_CONFIG);
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
  listBox("#quality-warnings", warnings);
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
    el("td", {}, String(r.row ?? "–")), el("td", {}, fmt(r.zenith_deg, 2)),
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

// the fitted parameters of the calibration shown, with their 1σ where its fit gives one (the document's
// `parameters` and `parameters.uncertainties`); a parameter the model holds fixed says so
const NOT_PARAMETERS = new Set(["uncertainties", "correlation", "fitted"]);
const precise = (v, digits) => (typeof v === "number" ? Number(v.toPrecision(digits)).toString() : String(v));

function parameterValue(value) {
  if (!Array.isArray(value)) return precise(value, 7);
  if (value.some(Array.isArray)) {
    return `${value.length} × ${Math.max(...value.map((v) => v.length))} coefficients (in the JSON download)`;
  }
  return `[${value.map((v) => precise(v, 5)).join(", ")}]`;
}

function parametersSection(record) {
  const parameters = record?.parameters ?? null;
  $("#parameters-section").hidden = !parameters;
  if (!parameters) return;
  const sigmas = parameters.uncertainties ?? {};
  const fitted = new Set(parameters.fitted ?? []);
  const names = Object.keys(parameters).filter((k) => !NOT_PARAMETERS.has(k));
  const order = [...names.filter((n) => fitted.has(n)), ...names.filter((n) => !fitted.has(n))];
  $("#parameters-heading").textContent = `Fitted parameters of ${record.method}`;
  $("#parameters tbody").replaceChildren(...order.map((name) => {
    const sigma = sigmas[name];
    const held = parameters.fitted && !fitted.has(name);
    return el("tr", { class: held ? "muted" : "" }, el("td", {}, name), el("td", {}, parameterValue(parameters[name])),
      el("td", {}, sigma !== undefined && sigma !== null ? `± ${precise(sigma, 2)}` : held ? "not fitted" : "–"));
  }));
  $("#parameters-note").textContent = Object.keys(sigmas).length
    ? "± 1σ from the fit's covariance (the unit is the name's: _px, _mm, _deg; others are ratios)."
    : "This method's fit gives no 1σ of its parameters (the unit is the name's: _px, _mm, _deg).";
}

// where the run's figures come from: the bench's configuration, the software, the operator, the devices
function provenanceSection(run) {
  const p = run.provenance ?? {};
  const devices = p.devices ?? {};
  const rows = [
    ["Bench", p.simulated === undefined ? "–" : p.simulated ? "simulated (no real device measured this run)" : "real"],
    ["Bench configuration hash", p.bench_config_hash ?? "–"],
    ["Software", p.software_version ?? "–"],
    ["Operator", p.operator ?? "–"],
    ["Sensor serial", p.sensor_serial ?? run.sensor_id],
    ...Object.entries(devices).map(([role, identity]) => [`Device: ${role}`, identity]),
    ["Frames kept", p.frames ?? "–"],
    ["Campaign", run.campaign_id ? el("a", { href: `/fleet?campaign=${run.campaign_id}` }, `campaign ${run.campaign_id}`) : "–"],
    ...(run.parent_run_id ? [["Resumes", el("a", { href: `/results?run=${run.parent_run_id}` }, `run ${run.parent_run_id}`)]] : []),
  ];
  $("#provenance").replaceChildren(...rows.flatMap(([name, value]) => [el("dt", {}, name), el("dd", {}, value)]));
}

// a run that ended unsafe: first, in red
function unsafeBox(run) {
  const text = unsafeText(run);
  $("#unsafe-box").hidden = !text;
  $("#unsafe-box").textContent = text ? unsafeMessage(run.id, text) : "";
}

// a crashed, aborted or failed run nothing resumed yet: Resume run here, then follow it on /run?run=N
function resumeBox(run, runs) {
  const offer = resumable(run, runs);
  $("#resume-box").hidden = !offer;
  if (!offer) return;
  $("#resume-text").textContent = `This run ${run.status}${run.exit_reason ? ` (${run.exit_reason})` : ""} after `
    + `${pointsText(run)} points. Resuming it measures only the missing points, then the rest of its campaign.`;
  $("#resume-link").href = `/run?run=${run.id}`;
  $("#resume-run").onclick = async () => {
    try {
      say((await api(`/api/runs/${run.id}/resume`, { method: "POST" })).message);
      $("#resume-run").disabled = true;
    } catch (err) { report(err); }
  };
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
  parametersSection(record);
  uncertaintyPlot(record);
  let fit = null;
  if (method) {
    try { fit = await api(`/api/runs/${runId}/fit?method=${encodeURIComponent(method)}`); } catch (err) { report(err); }
  }
  spotMap(points, fit, sensor);
  $("#fit-plots").hidden = !fit;
  if (fit) for (const plot of FIT_PLOTS) plot(fit);
}

// what every family's run shows first: who, what and how it ended, whether to resume it, where it came from
function runHeader(run, runs) {
  $("#run-heading").textContent = `Run ${run.id} · sensor ${run.sensor_id} (${run.family ?? "cmos"})`;
  $("#run-info").textContent = `${run.plan_name}, ${run.status}${run.exit_reason ? ` (${run.exit_reason})` : ""}, `
    + `${pointsText(run)} points, ${run.started_utc ?? "–"} → ${run.ended_utc ?? "–"}`;
  unsafeBox(run);
  resumeBox(run, runs);
  provenanceSection(run);
}

async function showRun(runId) {
  $("#run-summary").hidden = false;
  const [run, runs] = await Promise.all([api(`/api/runs/${runId}`), api("/api/runs")]);
  runHeader(run, runs.data);
  // the results view of the run's family
  const views = { qd: showQdRun, camera: showCameraRun, css: showCssRun, horizon: showHorizonRun };
  if (views[run.results_view]) {
    await views[run.results_view](run, { downloads: (method) => downloads(run.id, method) });
    return;
  }
  const [points, calibrations, values] = await Promise.all([
    api(`/api/runs/${runId}/points`), api(`/api/runs/${runId}/calibrations`), api(`/api/runs/${runId}/values`)]);
  // the detector's size for the spot map's axes: the bench's sensor now, if it answers (else the axes fit the
  // points); a run recorded with another sensor than today's still has its points drawn where they were
  const status = await api("/api/status").catch(() => null);
  stoppingSection(values.physical);
  const usable = calibrations.data.filter((c) => !c.metrics?.error);
  const chosen = usable.find((c) => c.chosen) || usable[0];
  const select = $("#method");
  methodOptions(select, usable, chosen);
  select.onchange = () => showMethod(runId, points.data, select.value, status?.sensor, calibrations.data);
  if (calibrations.data.length) metricsTable(calibrations.data);
  if (!usable.length) {
    say(calibrations.data.length ? "every fit of this run failed: see the table"
      : `no calibration: ${noCalibrationReason(run)}`, true);
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
