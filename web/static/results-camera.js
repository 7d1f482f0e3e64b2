// The results view of a camera run (seed 001's camera sun sensor), chosen by results.js from the run's family: the
// calibration's figures (the fit's over every frame it used; held out by whole zenith rings and by whole azimuths, the
// worse scheme marked) and its warnings in words; OpenCV's camera model (fx, fy, cx, cy, k1, k2, p1, p2, k3 and the
// camera's rotation against the body frame, each ± 1σ); the run's spots in the frame coloured by their angular
// residual, with each residual vector drawn to scale (a quiver); the angular residual against the field angle.
// Everything is computed by the server (GET /api/runs/{id}/camera/fit, bench/camera_results.py); this module only
// draws it.
/* global Plotly */
import {
  $, api, el, fmt, leftOutTrace, listBox, matrixLayout, methodOptions, noCalibrationReason, PLOT_CONFIG, plotLayout,
  report, say,
} from "./common.js";

const deg = (v) => fmt(v, 4);
const precise = (v, digits) => (v === null || v === undefined ? "–" : Number(Number(v).toPrecision(digits)).toString());

// what each parameter is, for people (the API's names carry the unit: _px, _deg)
const LABELS = {
  fx_px: "fx, focal length along x", fy_px: "fy, focal length along y", cx_px: "cx, principal point x",
  cy_px: "cy, principal point y", k1: "k1, radial", k2: "k2, radial", p1: "p1, tangential", p2: "p2, tangential",
  k3: "k3, radial", rot_x_deg: "rotation x (tilt)", rot_y_deg: "rotation y (tilt)",
  rot_z_deg: "rotation z (about the boresight)",
};
const SCHEMES = { rings: "rings left out", azimuths: "azimuths left out" };

// azimuth is an angle: 0° and 360° get one colour
const CYCLIC = [[0, "#d62728"], [0.25, "#1f77b4"], [0.5, "#2ca02c"], [0.75, "#9467bd"], [1, "#d62728"]];

// -- the figures and the warnings --------------------------------------------------------------------------------
function metricsTable(fit) {
  const { figures } = fit;
  const f = figures.fit;
  $("#camera-metrics-heading").textContent = `Accuracy of ${fit.method} (held out by whole zenith rings and by whole `
    + "azimuths; the worse scheme decides)";
  const rows = [el("tr", {}, el("td", {}, "fit (every frame it used)"), el("td", {}, String(f.n_points ?? "–")),
    el("td", {}, "none"), el("td", {}, deg(f.rms_deg)), el("td", {}, deg(f.max_deg)), el("td", {}, fmt(f.rms_px, 4)),
    el("td", {}, "at the points fitted"))];
  for (const s of figures.held_out) {
    const symbol = { rings: "θ", azimuths: "φ" }[s.scheme] ?? "";
    const groups = `${s.n_groups}: ${symbol} ${s.groups_deg.map((g) => `${fmt(g, 1)}°`).join(", ")}`;
    rows.push(el("tr", { class: s.worse ? "worse" : "" },
      el("td", {}, SCHEMES[s.scheme] ?? s.scheme), el("td", {}, String(s.n_points ?? "–")), el("td", {}, groups),
      el("td", s.worse ? { class: "over" } : {}, deg(s.rms_deg)), el("td", {}, deg(s.max_deg)), el("td", {}, "–"),
      el("td", {}, `${s.left_out}${s.worse ? "; the worse scheme: the calibration is judged by it" : ""}`)));
  }
  $("#camera-metrics tbody").replaceChildren(...rows);
  $("#camera-metrics").hidden = false;
  $("#camera-metrics-none").hidden = figures.held_out.length > 0;
  $("#camera-metrics-none").textContent = figures.held_out.length ? ""
    : "The fit was not held out: the figures above are at the points it fitted only.";
  listBox("#camera-warnings", fit.warnings);
  $("#camera-ok").hidden = fit.warnings.length > 0;
  const items = [
    ["χ²/dof (residuals against the repeat scatter; 1 when the model explains the data)", fmt(f.reduced_chi2, 2)],
    ["centroid noise the χ² is against [px]", fmt(f.noise_px, 4)],
    ["held out: RMS of the worse scheme, largest of either [°]", figures.worse_scheme
      ? `${deg(figures.heldout_rms_deg)} (${SCHEMES[figures.worse_scheme] ?? figures.worse_scheme}), ${deg(figures.heldout_max_deg)}`
      : "–"],
    ["points fitted (the mean spot of each): RMS, largest residual [°]",
      `${fit.points.n_points} points: ${deg(fit.points.rms_deg)}, ${deg(fit.points.max_deg)}`],
    ["frame; half field of view at its corners", `${fit.width_px} × ${fit.height_px} px; ${fmt(fit.fov_half_deg, 2)}°`],
  ];
  $("#camera-figures").replaceChildren(...items.flatMap(([name, value]) => [el("dt", {}, name), el("dd", {}, value)]));
}

// -- the camera model ---------------------------------------------------------------------------------------------
function parametersTable(fit) {
  $("#camera-parameters-heading").textContent = `Camera model of ${fit.method} (OpenCV's, and its rotation body → camera)`;
  $("#camera-parameters tbody").replaceChildren(...fit.parameters.map((p) => el("tr", { class: p.fitted ? "" : "muted" },
    el("td", {}, `${LABELS[p.name] ?? p.name}${p.unit ? ` [${p.unit}]` : ""}`), el("td", {}, precise(p.value, 7)),
    el("td", {}, p.sd !== null ? `± ${precise(p.sd, 2)}` : p.fitted ? "–" : "not fitted"))));
  $("#camera-parameters-note").textContent = fit.parameters_note;
}

// -- the spots in the frame ---------------------------------------------------------------------------------------
// a round scale (1, 2 or 5 × 10^k) that draws a typical residual vector (the upper quartile's) about `typical` px
// long, and none longer than `longest` px
function arrowScale(vectors, typical, longest) {
  const lengths = vectors.map(([dx, dy]) => Math.hypot(dx, dy)).filter((v) => v > 0).sort((a, b) => a - b);
  if (!lengths.length) return 1;
  const raw = Math.min(typical / lengths[Math.floor(0.75 * (lengths.length - 1))], longest / lengths[lengths.length - 1]);
  const power = 10 ** Math.floor(Math.log10(raw));
  return [5, 2, 1].map((m) => m * power).find((s) => s <= raw) ?? power;
}

function spotPlot(fit) {
  const used = fit.data.filter((p) => !p.excluded && p.error_deg !== null);
  const left = fit.data.filter((p) => p.excluded);
  const withVector = used.filter((p) => p.residual_x_px !== null && p.residual_y_px !== null);
  const scale = arrowScale(withVector.map((p) => [p.residual_x_px, p.residual_y_px]), 0.05 * fit.width_px,
    0.2 * fit.width_px);
  const arrows = { x: [], y: [] };
  for (const p of withVector) {
    arrows.x.push(p.x_px, p.x_px + scale * p.residual_x_px, null);
    arrows.y.push(p.y_px, p.y_px + scale * p.residual_y_px, null);
  }
  const traces = [{
    type: "scatter", mode: "markers", name: "mean spot of each point", x: used.map((p) => p.x_px), y: used.map((p) => p.y_px),
    text: used.map((p) => `${p.key}: θ ${fmt(p.zenith_deg, 2)}°, φ ${fmt(p.azimuth_deg, 1)}°<br>residual ${deg(p.error_deg)}°, `
      + `(${fmt(p.residual_x_px, 4)}, ${fmt(p.residual_y_px, 4)}) px`),
    marker: { size: 8, color: used.map((p) => p.error_deg), colorscale: "Viridis", cmin: 0,
      colorbar: { title: { text: "angular residual [°]", side: "right" } }, line: { width: 0.5, color: "#333" } },
    hovertemplate: "(%{x:.2f}, %{y:.2f}) px<br>%{text}<extra></extra>",
  }, {
    type: "scatter", mode: "lines", name: `residual × ${scale} (to where the model puts the direction set)`,
    x: arrows.x, y: arrows.y, line: { color: "#d62728", width: 1.5 }, hoverinfo: "skip",
  }, leftOutTrace(left, (p) => p.x_px, (p) => p.y_px)].filter(Boolean);
  Plotly.react("camera-spot-plot", traces, matrixLayout(`spots of ${fit.method}'s ${fit.count} points in the frame, `
    + `residual vectors × ${scale}`, { width_px: fit.width_px, height_px: fit.height_px }), PLOT_CONFIG);
  $("#camera-spot-info").textContent = `${used.length} point(s) fitted${left.length ? `, ${left.length} left out` : ""}. `
    + "Each spot is the mean of its frames the fit used; its line runs to where the calibration puts the direction "
    + `the table set, ${scale} times as long as it is (the residual of the fit, model − measured).`;
}

// -- the residual against the field angle -------------------------------------------------------------------------
function errorPlot(fit) {
  const used = fit.data.filter((p) => !p.excluded && p.error_deg !== null);
  const left = fit.data.filter((p) => p.excluded);
  const span = [0, Math.max(1, ...fit.data.map((p) => p.zenith_deg)) * 1.03];
  const { figures } = fit;
  const levels = [[figures.fit.rms_deg, `fit RMS ${deg(figures.fit.rms_deg)}° (every frame)`, "dot"]];
  if (figures.worse_scheme) {
    levels.push([figures.heldout_rms_deg, `held-out RMS ${deg(figures.heldout_rms_deg)}° (${SCHEMES[figures.worse_scheme]
      ?? figures.worse_scheme})`, "dash"]);
  }
  const traces = [{
    type: "scatter", mode: "markers", name: "mean spot of each point", x: used.map((p) => p.zenith_deg),
    y: used.map((p) => p.error_deg), text: used.map((p) => `${p.key}, azimuth ${fmt(p.azimuth_deg, 1)}°`),
    marker: { size: 7, color: used.map((p) => p.azimuth_deg), colorscale: CYCLIC, cmin: 0, cmax: 360,
      colorbar: { title: { text: "azimuth [°]", side: "right" } } },
    hovertemplate: "θ %{x:.2f}°: %{y:.4f}°<br>%{text}<extra></extra>",
  }, ...levels.filter(([value]) => value !== null).map(([value, name, dash]) => ({
    type: "scatter", mode: "lines", name, x: span, y: [value, value], line: { dash, width: 1.5, color: "#444" },
    hoverinfo: "skip",
  })), leftOutTrace(left, (p) => p.zenith_deg, (p) => p.error_deg)].filter(Boolean);
  const layout = plotLayout(`angular residual of ${fit.method} against the field angle`, "field angle: true zenith θ [°]",
    "angular residual [°]");
  layout.xaxis = { ...layout.xaxis, range: span };
  layout.yaxis = { ...layout.yaxis, rangemode: "tozero" };
  Plotly.react("camera-error-plot", traces, layout, PLOT_CONFIG);
  $("#camera-error-info").textContent = `Over the points' mean spots: RMS ${deg(fit.points.rms_deg)}°, largest `
    + `${deg(fit.points.max_deg)}°; over every frame the fit used (the fit's own figures): RMS ${deg(fit.frames.rms_deg)}°, `
    + `largest ${deg(fit.frames.max_deg)}°. These are at the points fitted; the held-out line is what the calibration `
    + "does between them.";
}

// -- one calibration shown ------------------------------------------------------------------------------------
function showSections(shown) {
  for (const id of ["#camera-parameters-section", "#camera-spot-section", "#camera-error-section"]) $(id).hidden = !shown;
}

async function showMethod(run, method, downloads) {
  downloads(method);
  let fit = null;
  if (method) {
    try { fit = await api(`/api/runs/${run.id}/camera/fit?method=${encodeURIComponent(method)}`); } catch (err) { report(err); }
  }
  showSections(Boolean(fit));
  if (!fit) return;
  metricsTable(fit);
  parametersTable(fit);
  spotPlot(fit);
  errorPlot(fit);
}

/**
 * Show a camera run's results (results.js has drawn its header: heading, provenance, resumption).
 * @param {object} run  GET /api/runs/{id}
 * @param {{downloads: function(string|undefined)}} helpers  the results page's download buttons, for one method
 */
export async function showCameraRun(run, { downloads }) {
  $("#camera-view").hidden = false;
  const calibrations = (await api(`/api/runs/${run.id}/calibrations`)).data;
  const usable = calibrations.filter((c) => !c.metrics?.error);
  const chosen = usable.find((c) => c.chosen) ?? usable[0];
  const select = $("#method");
  methodOptions(select, usable, chosen);
  select.onchange = () => showMethod(run, select.value, downloads).catch(report);
  if (!usable.length) {
    const why = calibrations.length ? "every fit of this run failed" : noCalibrationReason(run);
    $("#camera-metrics").hidden = true;
    $("#camera-warnings").hidden = true;
    $("#camera-metrics-none").hidden = false;
    $("#camera-metrics-none").textContent = `No calibration: ${why}.`;
    say(`no calibration: ${why}`, true);
  }
  await showMethod(run, chosen?.method, downloads);
}
