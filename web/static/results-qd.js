// The results view of a QD run (seed 002's quadrant-photodiode sun sensor), chosen by results.js from the run's
// family: every method's figures (held out between the grid's nodes, at the nodes, χ²/dof), the readings the fit
// rejected and its warnings; the angular error of the calibration shown over the field (its stored document
// applied to the run's readings: GET /api/runs/{id}/qd/error-map); the dark current of each quadrant against
// temperature with the document's dark model; the four quadrant currents of every point and their sum over the
// field. Everything is computed by the server (bench/qd_results.py); this module only draws it.
/* global Plotly */
import {
  $, amps, api, currentsPlot, el, fmt, leftOutTrace, listBox, methodOptions, noCalibrationReason, PLOT_CONFIG, plotLayout,
  QUADRANT_COLOURS as COLOURS, QUADRANTS, report, say,
} from "./common.js";

const deg = (v) => fmt(v, 4);

// -- every method's figures -------------------------------------------------------------------------------------
function metricsTable(metrics) {
  const rows = metrics.data.map((m) => {
    const h = m.heldout ?? {}, n = m.at_nodes ?? {};
    const scheme = m.heldout_scheme ? `${m.heldout_scheme} (${h.n_points ?? "–"})` : "–";
    return el("tr", { class: m.chosen ? "chosen" : "" }, el("td", {}, m.method + (m.chosen ? " ✓ chosen" : "")),
      el("td", {}, deg(h.max_deg)), el("td", {}, deg(h.rms_deg)), el("td", {}, deg(h.p99_deg)), el("td", {}, scheme),
      el("td", {}, deg(n.max_deg)), el("td", {}, deg(n.rms_deg)), el("td", {}, deg(n.p99_deg)),
      el("td", {}, fmt(m.chi2_dof, 1)), el("td", {}, m.error ?? ""));
  });
  $("#qd-metrics tbody").replaceChildren(...rows);
  $("#qd-metrics").hidden = !rows.length;
  $("#qd-metrics-none").hidden = rows.length > 0;
  listBox("#qd-warnings", metrics.warnings ?? []);
  const rejected = metrics.rejected ?? [];
  $("#qd-rejected-part").hidden = !rows.length;  // no fit, nothing rejected by it
  $("#qd-rejected").hidden = !rejected.length;
  $("#qd-rejected-none").hidden = rejected.length > 0;
  $("#qd-rejected tbody").replaceChildren(...rejected.map((r) => el("tr", {},
    el("td", {}, String(r.row ?? "–")), el("td", {}, r.key ?? "–"),
    el("td", {}, fmt(r.alpha_deg, 2)), el("td", {}, fmt(r.beta_deg, 2)), el("td", {}, r.reason))));
}

// -- the angular error over the field ---------------------------------------------------------------------------
// the grid's nodes as a heat map (α columns, β rows; null where there is no node), when they form a grid
function nodeGrid(nodes) {
  const key = (v) => Math.round(v * 100) / 100;
  const alphas = [...new Set(nodes.map((d) => key(d.alpha_deg)))].sort((a, b) => a - b);
  const betas = [...new Set(nodes.map((d) => key(d.beta_deg)))].sort((a, b) => a - b);
  if (!nodes.length || alphas.length * betas.length > 4 * nodes.length) return null;  // scattered: no grid
  const z = betas.map(() => alphas.map(() => null));
  const text = betas.map(() => alphas.map(() => ""));
  for (const d of nodes) {
    const i = betas.indexOf(key(d.beta_deg)), j = alphas.indexOf(key(d.alpha_deg));
    z[i][j] = d.error_deg;
    text[i][j] = `${d.key}<br>at the node (fitted)`;
  }
  return { alphas, betas, z, text };
}

function errorPlot(map, kind) {
  const used = map.data.filter((d) => !d.excluded && d.error_deg !== null);
  const nodes = used.filter((d) => d.kind === "node"), checks = used.filter((d) => d.kind === "check");
  const traces = [];
  const grid = kind !== "check" ? nodeGrid(nodes) : null;
  if (grid) {
    traces.push({ type: "heatmap", name: "at the nodes (fitted)", x: grid.alphas, y: grid.betas, z: grid.z,
      text: grid.text, coloraxis: "coloraxis", hoverongaps: false,
      hovertemplate: "α %{x:.2f}°, β %{y:.2f}°: %{z:.4f}°<br>%{text}<extra></extra>" });
  } else if (kind !== "check" && nodes.length) {
    traces.push({ type: "scatter", mode: "markers", name: "at the nodes (fitted)", x: nodes.map((d) => d.alpha_deg),
      y: nodes.map((d) => d.beta_deg), text: nodes.map((d) => d.key),
      marker: { symbol: "square", size: 9, color: nodes.map((d) => d.error_deg), coloraxis: "coloraxis" },
      hovertemplate: "α %{x:.2f}°, β %{y:.2f}°: %{marker.color:.4f}°<br>%{text}<extra></extra>" });
  }
  if (kind !== "node" && checks.length) {
    traces.push({ type: "scatter", mode: "markers", name: "held out (check points)", x: checks.map((d) => d.alpha_deg),
      y: checks.map((d) => d.beta_deg), text: checks.map((d) => d.key),
      marker: { symbol: "diamond", size: 9, color: checks.map((d) => d.error_deg), coloraxis: "coloraxis",
        line: { width: 1, color: "#fff" } },
      hovertemplate: "α %{x:.2f}°, β %{y:.2f}°: %{marker.color:.4f}° held out<br>%{text}<extra></extra>" });
  }
  const left = map.data.filter((d) => d.excluded && (kind === "both" || d.kind === kind));
  const leftOut = leftOutTrace(left, (d) => d.alpha_deg, (d) => d.beta_deg);
  if (leftOut) traces.push(leftOut);
  const field = map.field_deg ?? 40;
  const pad = 0.04 * field + 1;
  const what = { both: "at the nodes (squares) and held out between them (diamonds)", check: "held out at the check points",
    node: "at the fitted nodes" }[kind];
  const layout = plotLayout(`angular error of ${map.method} over ±${fmt(field, 0)}° × ±${fmt(field, 0)}°, ${what}`,
    "α [°]", "β [°]", {
      coloraxis: { colorscale: "Viridis", cmin: 0, colorbar: { title: { text: "angular error [°]", side: "right" } } },
    });
  layout.xaxis = { ...layout.xaxis, range: [-field - pad, field + pad], constrain: "domain", zeroline: false };
  layout.yaxis = { ...layout.yaxis, range: [-field - pad, field + pad], scaleanchor: "x", constrain: "domain",
    zeroline: false };
  Plotly.react("qd-error-plot", traces, layout, PLOT_CONFIG);
}

function errorInfo(map, record) {
  const { node, check } = map.summary;
  const part = (s, what) => (s && s.n_points ? `${what}: max ${deg(s.max_deg)}°, RMS ${deg(s.rms_deg)}° over ${s.n_points - s.n_failed}`
    + `${s.n_failed ? ` (${s.n_failed} without a direction)` : ""}` : null);
  const held = record?.heldout;
  const parts = [part(node, "At the nodes (fitted)"), part(check, "held out at the check points (never fitted)")].filter(Boolean);
  $("#qd-error-info").textContent = `${parts.join("; ")}. `
    + (held ? `The method is judged by its worst held-out scheme, ${record.heldout_scheme}: max ${deg(held.max_deg)}°, `
      + `RMS ${deg(held.rms_deg)}°, p99 ${deg(held.p99_deg)}° (leaving grid lines out needs a refit per fold, so it is not `
      + "in the map). " : "")
    + "The error is the angle between the direction the stored calibration gives for the direction's readings "
    + "(dark current subtracted, averaged) and the true one.";
}

// -- the dark current ---------------------------------------------------------------------------------------
function darkPlot(dark) {
  const nano = (v) => (v === null || v === undefined ? null : v * 1e9);
  const used = dark.readings.filter((r) => !r.left_out && r.currents_a);
  const left = dark.readings.filter((r) => r.left_out && r.currents_a);
  const traces = [];
  QUADRANTS.forEach((name, k) => {
    traces.push({ type: "scatter", mode: "markers", name: `${name} readings`, legendgroup: name,
      x: used.map((r) => r.temperature_c), y: used.map((r) => nano(r.currents_a[k])), text: used.map((r) => r.key),
      marker: { size: 5, color: COLOURS[k] }, hovertemplate: "%{x:.2f} °C: %{y:.4f} nA<br>%{text}<extra></extra>" });
    if (dark.curve) {
      traces.push({ type: "scatter", mode: "lines", name: `${name} ${dark.model}`, legendgroup: name,
        x: dark.curve.temperature_c, y: dark.curve.currents_a.map((c) => nano(c[k])),
        line: { color: COLOURS[k], width: 1.5 }, hoverinfo: "skip" });
    }
  });
  if (left.length) {
    traces.push(leftOutTrace(left.flatMap((r) => r.currents_a.map(() => r)), (r) => r.temperature_c, () => null, {
      y: left.flatMap((r) => r.currents_a.map((c) => nano(c))),
      text: left.flatMap((r) => r.currents_a.map((_, k) => `${r.key} ${QUADRANTS[k]}<br>left out of the fit: ${r.left_out}`)),
    }));
  }
  const shapes = dark.light_range_c ? [{ type: "rect", xref: "x", yref: "paper", x0: dark.light_range_c[0] - 0.25,
    x1: dark.light_range_c[1] + 0.25, y0: 0, y1: 1, fillcolor: "rgba(255, 200, 0, 0.18)", line: { width: 0 }, layer: "below" }] : [];
  const annotations = dark.light_range_c ? [{ xref: "x", yref: "paper", x: (dark.light_range_c[0] + dark.light_range_c[1]) / 2,
    y: 1, yanchor: "bottom", text: "lit readings", showarrow: false, font: { size: 11, color: "#8a5a00" } }] : [];
  const source = dark.source === "calibration" ? `the ${dark.model} model of ${dark.method}`
    : dark.source === "readings" ? `the ${dark.model} model fitted to these readings` : "no model";
  Plotly.react("qd-dark-plot", traces, plotLayout(`dark current of each quadrant, shutter closed, with ${source}`,
    "die temperature [°C]", "dark current [nA]", { shapes, annotations }), PLOT_CONFIG);
  const range = (r) => (r ? `${fmt(r[0], 1)} … ${fmt(r[1], 1)} °C` : "–");
  const outside = dark.light_range_c && dark.dark_range_c
    && (dark.light_range_c[0] < dark.dark_range_c[0] - 1 || dark.light_range_c[1] > dark.dark_range_c[1] + 1);
  $("#qd-dark-info").textContent = (dark.readings.length ? `${used.length} dark reading(s) over ${range(dark.dark_range_c)}`
    + `${left.length ? `, ${left.length} left out` : ""}; ` : "No dark reading: no dark current is subtracted; ")
    + (dark.light_range_c ? `lit readings at ${range(dark.light_range_c)}${outside ? " (the dark current is extrapolated there)" : ""}. `
      : "no lit reading. ")
    + (dark.note ? `${dark.note}. ` : "")
    + (dark.source === "readings" ? "The run has no calibration: the model is fitted here, as a grid run's fit would. " : "");
}

// -- the quadrant currents ------------------------------------------------------------------------------------
function currentsPlots(currents) {
  const points = currents.data.filter((p) => p.currents_a);
  const text = points.map((p) => `${p.key} (${p.stage})${p.temperature_c === null ? "" : `, ${fmt(p.temperature_c, 2)} °C`}`);
  currentsPlot("qd-currents-plot", `quadrant currents of the ${points.length} points in recording order (dark sweep `
    + "first)", points.map((p) => p.index), QUADRANTS.map((_, k) => points.map((p) => p.currents_a[k])),
  points.map((p) => p.sum_a), text);

  const lit = points.filter((p) => p.alpha_deg !== null);
  $("#qd-sum-section").hidden = !lit.length;  // a dark sweep lights nothing
  if (!lit.length) return;
  const sumLayout = plotLayout("summed current of each lit direction (the cos law over the field)", "α [°]", "β [°]");
  sumLayout.yaxis = { ...sumLayout.yaxis, scaleanchor: "x", constrain: "domain" };
  sumLayout.xaxis = { ...sumLayout.xaxis, constrain: "domain" };
  Plotly.react("qd-sum-plot", [{
    type: "scatter", mode: "markers", name: "sum of the four currents", x: lit.map((p) => p.alpha_deg),
    y: lit.map((p) => p.beta_deg), text: lit.map((p) => `${p.key}: ${amps(p.sum_a)}`),
    marker: { size: 7, symbol: lit.map((p) => (p.stage === "check" ? "diamond" : "square")),
      color: lit.map((p) => p.sum_a * 1e6), colorscale: "Cividis", colorbar: { title: { text: "sum [µA]", side: "right" } } },
    hovertemplate: "α %{x:.2f}°, β %{y:.2f}°<br>%{text}<extra></extra>",
  }], sumLayout, PLOT_CONFIG);
}

// -- one calibration shown ------------------------------------------------------------------------------------
async function showMethod(run, method, metrics, downloads) {
  downloads(method);
  const record = metrics.data.filter((m) => m.method === method).pop();
  const query = method ? `?method=${encodeURIComponent(method)}` : "";
  const [dark, map] = await Promise.all([
    api(`/api/runs/${run.id}/qd/dark${query}`).catch((err) => { report(err); return null; }),
    method ? api(`/api/runs/${run.id}/qd/error-map${query}`).catch((err) => { report(err); return null; }) : null]);
  if (dark) darkPlot(dark);
  $("#qd-error-section").hidden = !map;
  if (map) {
    $("#qd-error-heading").textContent = `Angular error of ${map.method} over the field`;
    const draw = () => errorPlot(map, $("#qd-error-kind").value);
    $("#qd-error-kind").onchange = draw;
    draw();
    errorInfo(map, record);
  }
}

/**
 * Show a QD run's results (results.js has drawn its header: heading, provenance, resumption).
 * @param {object} run  GET /api/runs/{id}
 * @param {{downloads: function(string|undefined)}} helpers  the results page's download buttons, for one method
 */
export async function showQdRun(run, { downloads }) {
  $("#qd-view").hidden = false;
  const [metrics, currents] = await Promise.all([api(`/api/runs/${run.id}/qd/metrics`), api(`/api/runs/${run.id}/qd/currents`)]);
  metricsTable(metrics);
  currentsPlots(currents);
  const chosen = metrics.data.find((m) => m.chosen) ?? metrics.data[0];
  const select = $("#method");
  methodOptions(select, metrics.data, chosen);
  select.onchange = () => showMethod(run, select.value, metrics, downloads).catch(report);
  if (!metrics.data.length) {
    const why = run.plan_name === "qd-dark" ? "a dark sweep calibrates no direction (a grid run's fit uses it)"
      : noCalibrationReason(run);
    $("#qd-metrics-none").textContent = `No calibration: ${why}.`;
    say(`no calibration: ${why}`, run.plan_name !== "qd-dark");
  }
  await showMethod(run, chosen?.method, metrics, downloads);
}
