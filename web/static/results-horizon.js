// The results view of a horizon run (seed 004's scanning Earth-horizon sensor: two cones sweeping across an IR Earth
// simulator's disc), chosen by results.js from the run's family: the sensor's own errors ± 1σ against the nominal
// design, the fit's figures, its warnings and rejected edges in words, the parameters' correlation (GET
// /api/runs/{id}/horizon/metrics); the roll and pitch the calibrated sensor reports against the table's, held out
// and beside the nominal sensor's, and their maps over the grid (GET …/horizon/attitude); each edge's phase residual
// against roll, pitch and disc radius per cone (GET …/horizon/edges); the pulse of a reading with the locator's
// threshold and its edges (GET …/horizon/pulse). Everything is computed by the server (bench/horizon_results.py);
// this module only draws it.
/* global Plotly */
import { $, api, el, fmt, listBox, methodOptions, noCalibrationReason, PLOT_CONFIG, plotLayout, report, say } from "./common.js";

const EDGE_NAMES = { out: "falling edge (Earth → space)", in: "rising edge (space → Earth)" };
const CONE_COLOURS = { out: "#1f77b4", in: "#ff7f0e" };
const DIVERGING = "RdBu";
// a small angle to 4 significant digits, in powers of ten when tiny
const precise = (v, digits = 4) => {
  if (v === null || v === undefined || Number.isNaN(Number(v))) return "–";
  const x = Number(v);
  if (x !== 0 && Math.abs(x) < 1e-4) return x.toExponential(digits - 1);
  return Number(x.toPrecision(digits)).toString();
};
const pm = (value, sd) => `${fmt(value, 4)}${sd === null || sd === undefined ? "" : ` ± ${precise(sd, 2)}`}`;

// -- the calibration: parameters, figures, warnings, rejected edges ------------------------------------------------
function calibrationSection(cal) {
  $("#horizon-calibration-heading").textContent = `The sensor's own errors ± 1σ against the nominal design (${cal.method}`
    + `${cal.chosen ? ", chosen" : ""})`;
  listBox("#horizon-warnings", cal.warnings);
  $("#horizon-ok").hidden = cal.warnings.length > 0;
  $("#horizon-none").hidden = true;
  $("#horizon-parameters").hidden = false;
  $("#horizon-parameters tbody").replaceChildren(...cal.parameters.map((p) => {
    const far = p.difference_sigma !== null && Math.abs(p.difference_sigma) > 3;
    return el("tr", p.fitted ? {} : { class: "muted", title: "not fitted" },
      el("td", { title: p.name }, `${p.symbol} (${p.name})`), el("td", {}, p.words), el("td", {}, fmt(p.nominal, 4)),
      el("td", {}, p.fitted ? pm(p.value, p.sd) : `${fmt(p.value, 4)} (not fitted)`),
      el("td", {}, `${p.difference >= 0 ? "+" : ""}${fmt(p.difference, 4)}`),
      el("td", far ? { title: "the sensor differs from the design by more than 3σ" } : {},
        p.difference_sigma === null ? "–" : fmt(p.difference_sigma, 1)));
  }));
  const f = cal.fit;
  const noise = cal.noise.map((n) => `cone ${n.cone} ${n.edge} ${precise(n.sigma_deg, 2)}°`).join(", ");
  const rows = [
    ["χ²/dof (residuals against the repeat scatter; 1 when the model explains the data)", `${fmt(f.chi2_dof, 2)} `
      + `(${f.dof} dof; the 1σ above are widened by √${fmt(f.uncertainty_scale, 2)})`],
    ["RMS phase residual of the fitted edges", `${precise(f.rms_deg, 3)}°`],
    ["noise of one edge (1σ, from " + (f.noise_source === "repeats" ? "repeated scans" : "the residuals") + ")", noise],
    ["scans fitted / edges fitted / edges not found", `${f.n_scans} / ${f.n_edges} / ${f.n_missing}`],
    ["condition number (scaled Jacobian)", precise(cal.condition_number, 3)],
    ...(cal.design.ifov_half_angle_deg !== undefined ? [["the design's IFOV half-angle / locator threshold (known, "
      + "not fitted)", `${fmt(cal.design.ifov_half_angle_deg, 2)}° / C1 = ${cal.design.locator_level}`]] : []),
    ["disc radii [°]", (cal.plan.disc_radii_deg ?? []).map((r) => fmt(r, 3)).join(", ")],
    ["roll × pitch spanned [°]", `${fmt(cal.plan.roll_span_deg?.[0], 1)} … ${fmt(cal.plan.roll_span_deg?.[1], 1)} × `
      + `${fmt(cal.plan.pitch_span_deg?.[0], 1)} … ${fmt(cal.plan.pitch_span_deg?.[1], 1)}`],
  ];
  $("#horizon-figures").replaceChildren(...rows.flatMap(([name, value]) => [el("dt", {}, name), el("dd", {}, value)]));
  const rejected = cal.rejected;
  $("#horizon-rejected-part").hidden = false;
  $("#horizon-rejected-summary").textContent = rejected.length
    ? `${rejected.length} edge(s) rejected by the fit (the scan's other edges stand)` : "No edge was rejected by the fit.";
  $("#horizon-rejected").hidden = !rejected.length;
  $("#horizon-rejected tbody").replaceChildren(...rejected.map((r) => el("tr", {},
    el("td", {}, String(r.reading_id ?? "–")), el("td", {}, r.key ?? "–"), el("td", {}, String(r.cone ?? "–")),
    el("td", {}, r.edge ?? "–"), el("td", {}, fmt(r.roll_deg, 2)), el("td", {}, fmt(r.pitch_deg, 2)),
    el("td", {}, fmt(r.disc_radius_deg, 3)), el("td", {}, precise(r.residual_deg, 3)), el("td", {}, r.reason))));
}

// calibrated − nominal of every fitted parameter with its 1σ: what the bench found the sensor to be
function deviationPlot(cal) {
  const fitted = cal.parameters.filter((p) => p.fitted);
  Plotly.react("horizon-deviation-plot", [{
    type: "scatter", mode: "markers", name: "calibrated − nominal ± 1σ", x: fitted.map((p) => p.symbol),
    y: fitted.map((p) => p.difference), error_y: { type: "data", array: fitted.map((p) => p.sd), visible: true },
    text: fitted.map((p) => `${p.words}: ${pm(p.value, p.sd)}° (nominal ${fmt(p.nominal, 4)}°)`),
    marker: { size: 9, color: "#1f77b4" }, hovertemplate: "%{x}: %{y:.4f}°<br>%{text}<extra></extra>",
  }], plotLayout(`${cal.method}: each parameter's difference from the nominal design`, "parameter",
    "calibrated − nominal [°]", { showlegend: false }), PLOT_CONFIG);
}

function correlationPlot(cal) {
  const names = cal.correlation.names ?? [];
  const symbols = names.map((n) => cal.parameters.find((p) => p.name === n)?.symbol ?? n);
  Plotly.react("horizon-correlation-plot", [{
    type: "heatmap", name: "correlation", x: symbols, y: symbols, z: cal.correlation.matrix, zmin: -1, zmax: 1,
    colorscale: DIVERGING, reversescale: true, texttemplate: "%{z:.2f}", colorbar: { title: { text: "correlation" } },
    hovertemplate: "%{y} · %{x}: %{z:.3f}<extra></extra>",
  }], { ...plotLayout(`correlation of the fitted parameters (condition number ${precise(cal.condition_number, 3)})`,
    "", ""), yaxis: { autorange: "reversed" } }, PLOT_CONFIG);
}

// -- held out: roll and pitch against the table, calibrated and nominal ---------------------------------------------
function heldoutRows(cal) {
  const h = cal.heldout;
  const rows = [];
  if (h.check) {
    rows.push(["check points (never fitted)", "calibrated", h.check.calibrated, h.check.phase_rms_deg]);
    rows.push(["check points (never fitted)", "nominal", h.check.nominal, null]);
  }
  for (const r of h.radius_out) {
    rows.push([`disc radius ${fmt(r.disc_radius_deg, 3)}° left out (refitted without it)`, "calibrated", r.calibrated,
      r.phase_rms_deg]);
  }
  if (h.at_nodes) {
    rows.push(["fitted scans", "calibrated", h.at_nodes.calibrated, h.at_nodes.phase_rms_deg]);
    rows.push(["fitted scans", "nominal", h.at_nodes.nominal, null]);
  }
  return rows;
}

function heldoutSection(cal) {
  const rows = heldoutRows(cal);
  $("#horizon-heldout tbody").replaceChildren(...rows.map(([what, sensor, f, phase]) => el("tr",
    { class: sensor === "nominal" ? "muted" : what.startsWith("check") ? "chosen" : "" },
    el("td", {}, what), el("td", {}, sensor), el("td", {}, f ? String(f.n_scans) : "–"),
    el("td", {}, precise(f?.roll_rms_deg, 3)), el("td", {}, precise(f?.roll_max_deg, 3)),
    el("td", {}, precise(f?.pitch_rms_deg, 3)), el("td", {}, precise(f?.pitch_max_deg, 3)),
    el("td", {}, phase === null ? "–" : precise(phase, 3)))));
  const groups = [...new Set(rows.map((r) => r[0]))];
  const value = (group, sensor, key) => rows.find((r) => r[0] === group && r[1] === sensor)?.[2]?.[key] ?? null;
  const traces = [["calibrated", "roll_rms_deg", "roll RMS, calibrated", "#1f77b4"],
    ["calibrated", "pitch_rms_deg", "pitch RMS, calibrated", "#2ca02c"],
    ["nominal", "roll_rms_deg", "roll RMS, nominal sensor", "#aec7e8"],
    ["nominal", "pitch_rms_deg", "pitch RMS, nominal sensor", "#98df8a"]].map(([sensor, key, name, color]) => ({
    type: "bar", name, x: groups, y: groups.map((g) => value(g, sensor, key)), marker: { color },
    hovertemplate: `${name}: %{y:.4f}°<extra>%{x}</extra>`,
  }));
  const layout = plotLayout("RMS roll and pitch error against the table: the calibrated sensor and the nominal one",
    "", "RMS error [°]", { barmode: "group" });
  layout.yaxis = { ...layout.yaxis, type: "log", exponentformat: "power" };
  Plotly.react("horizon-heldout-plot", traces, layout, PLOT_CONFIG);
  const check = cal.heldout.check;
  $("#horizon-heldout-info").textContent = (check
    ? `At the ${check.calibrated.n_scans} check scans (never fitted) the calibrated sensor's roll is off the table's by `
      + `${precise(check.calibrated.roll_rms_deg, 3)}° RMS (max ${precise(check.calibrated.roll_max_deg, 3)}°) and its `
      + `pitch by ${precise(check.calibrated.pitch_rms_deg, 3)}° RMS (max ${precise(check.calibrated.pitch_max_deg, 3)}°); `
      + `the nominal sensor's by ${precise(check.nominal.roll_rms_deg, 3)}° and ${precise(check.nominal.pitch_rms_deg, 3)}° RMS. `
    : "No check scans: held out by leaving disc radii out only. ")
    + "Each scan's roll and pitch are solved from its crossings through the sensor's parameters and turned into the "
    + "table's frame through the fitted mount; leaving a disc radius out refits without it and scores on it.";
}

// -- each edge's phase residual against roll, pitch or the disc radius, a plot per cone -------------------------------
const X_OF = { roll: ["roll_deg", "the table's roll φ [°]"], pitch: ["pitch_deg", "the table's pitch θ [°]"],
  radius: ["disc_radius_deg", "the disc radius ρ [°]"] };

function residualsPlot(edges) {
  const [xKey, xTitle] = X_OF[$("#horizon-residuals-x").value];
  const nominal = $("#horizon-residuals-model").value === "nominal" || !edges.method;
  const yKey = nominal ? "residual_nominal_deg" : "residual_deg";
  const rows = edges.reading_id.map((_, i) => i);
  const traces = [];
  const seen = new Set();
  for (const cone of [1, 2]) {
    const axes = cone === 1 ? { xaxis: "x", yaxis: "y" } : { xaxis: "x2", yaxis: "y2" };
    const groups = [];
    for (const edge of ["out", "in"]) {
      groups.push([`${EDGE_NAMES[edge]}, fitted`, rows.filter((i) => edges.cone[i] === cone && edges.edge[i] === edge
        && !edges.check[i] && !edges.rejected[i]), { size: 5, color: CONE_COLOURS[edge] }]);
      groups.push([`${EDGE_NAMES[edge]}, check (never fitted)`, rows.filter((i) => edges.cone[i] === cone
        && edges.edge[i] === edge && edges.check[i] && !edges.rejected[i]),
      { size: 8, symbol: "diamond-open", color: CONE_COLOURS[edge], line: { width: 1.5 } }]);
    }
    groups.push(["rejected by the fit", rows.filter((i) => edges.cone[i] === cone && edges.rejected[i]),
      { size: 10, symbol: "x-thin-open", color: "#d62728", line: { width: 2, color: "#d62728" } }]);
    for (const [name, index, marker] of groups) {
      if (!index.length) continue;
      const first = !seen.has(name);
      seen.add(name);
      traces.push({ type: "scatter", mode: "markers", name, legendgroup: name, showlegend: first, ...axes,
        x: index.map((i) => edges[xKey][i]), y: index.map((i) => edges[yKey][i]), marker,
        text: index.map((i) => `reading ${edges.reading_id[i]} ${edges.key[i] ?? ""}<br>roll ${fmt(edges.roll_deg[i], 2)}°, `
          + `pitch ${fmt(edges.pitch_deg[i], 2)}°, ρ ${fmt(edges.disc_radius_deg[i], 3)}°`
          + (edges.rejected[i] ? `<br>rejected: ${edges.rejected[i]}` : "")),
        hovertemplate: `cone ${cone} residual %{y:.4f}°<br>%{text}<extra></extra>` });
    }
  }
  const layout = plotLayout("", "", "");
  delete layout.title;
  layout.grid = { rows: 1, columns: 2, pattern: "independent", xgap: 0.1 };
  const yTitle = `reported − ${nominal ? "nominal" : "calibrated"} phase [°]`;
  layout.xaxis = { ...layout.xaxis, title: { text: xTitle } };
  layout.xaxis2 = { ...layout.xaxis, title: { text: xTitle } };
  layout.yaxis = { ...layout.yaxis, title: { text: yTitle } };
  layout.yaxis2 = { ...layout.yaxis, title: { text: yTitle } };
  layout.annotations = [1, 2].map((cone) => ({ xref: `x${cone === 1 ? "" : 2} domain`, yref: "paper", x: 0, y: 1.02,
    xanchor: "left", yanchor: "bottom", showarrow: false, text: `cone ${cone}`, font: { size: 13 } }));
  layout.margin = { t: 40, r: 20, b: 50, l: 60 };
  layout.legend = { orientation: "h", x: 0, y: -0.2, yanchor: "top", font: { size: 12 } };
  Plotly.react("horizon-residuals-plot", traces, layout, PLOT_CONFIG);
  $("#horizon-residuals-heading").textContent = `Each edge's phase residual against ${xTitle.replace(/ \[°\]$/, "")}, `
    + `${nominal ? "of the nominal sensor" : `of the calibrated sensor (${edges.method})`}`;
  const s = edges.summary.filter((r) => r.kind === "fitted");
  $("#horizon-residuals-info").textContent = `${edges.count} edges of the run's scans. `
    + (edges.method ? `Calibrated: RMS ${precise(edges.fitted_rms_deg, 3)}° over the fitted edges it used` : "No calibration")
    + `; nominal sensor: ${s.map((r) => `cone ${r.cone} ${r.edge} ${precise(r.rms_nominal_deg, 3)}°`).join(", ")} RMS. `
    + "A pattern against roll is a mount roll or yaw left over, against the disc radius a cone angle or threshold bias "
    + "left over; noise alone scatters evenly about zero.";
}

// -- roll and pitch errors over the grid, per disc radius -------------------------------------------------------
function mapsPlot(attitude) {
  const k = Number($("#horizon-maps-radius").value || 0);
  const map = attitude.maps[k];
  if (!map) return;
  const nominal = $("#horizon-maps-model").value === "nominal" || !attitude.method;
  const suffix = nominal ? "_nominal_deg" : "_deg";
  const z = [map[`roll_error${suffix}`], map[`pitch_error${suffix}`]];
  const values = z.flat(2).filter((v) => v !== null);
  const check = attitude.reading_id.map((_, i) => i).filter((i) => attitude.check[i]
    && Math.abs(attitude.disc_radius_deg[i] - map.disc_radius_deg) < 1e-3);
  const checkErrors = ["roll", "pitch"].map((q) => check.map((i) => attitude[`${q}_error${suffix}`][i]));
  const limit = Math.max(...values.map(Math.abs), ...checkErrors.flat().filter((v) => v !== null).map(Math.abs), 1e-6);
  const traces = [];
  ["roll", "pitch"].forEach((q, j) => {
    const axes = j === 0 ? { xaxis: "x", yaxis: "y" } : { xaxis: "x2", yaxis: "y2" };
    traces.push({ type: "heatmap", name: `${q} error at the grid's nodes`, ...axes, x: map.roll_deg, y: map.pitch_deg,
      z: z[j], coloraxis: "coloraxis", hovertemplate: `roll %{x}°, pitch %{y}°: ${q} error %{z:.4f}°<extra></extra>` });
    traces.push({ type: "scatter", mode: "markers", name: "check points (never fitted)", legendgroup: "check",
      showlegend: j === 0, ...axes, x: check.map((i) => attitude.roll_deg[i]), y: check.map((i) => attitude.pitch_deg[i]),
      marker: { size: 11, symbol: "diamond", color: checkErrors[j], coloraxis: "coloraxis", line: { width: 1.5, color: "#222" } },
      text: check.map((i) => `reading ${attitude.reading_id[i]}`),
      hovertemplate: `check: roll %{x:.2f}°, pitch %{y:.2f}°: ${q} error %{marker.color:.4f}°<br>%{text}<extra></extra>` });
  });
  const layout = plotLayout("", "", "");
  delete layout.title;
  layout.grid = { rows: 1, columns: 2, pattern: "independent", xgap: 0.12 };
  layout.xaxis = { ...layout.xaxis, title: { text: "the table's roll φ [°]" } };
  layout.xaxis2 = { ...layout.xaxis };
  layout.yaxis = { ...layout.yaxis, title: { text: "the table's pitch θ [°]" } };
  layout.yaxis2 = { ...layout.yaxis };
  layout.coloraxis = { colorscale: DIVERGING, reversescale: true, cmin: -limit, cmax: limit,
    colorbar: { title: { text: "error [°]", side: "right" } } };
  layout.annotations = ["roll error", "pitch error"].map((text, j) => ({ xref: `x${j === 0 ? "" : 2} domain`,
    yref: "paper", x: 0, y: 1.02, xanchor: "left", yanchor: "bottom", showarrow: false, text, font: { size: 13 } }));
  layout.margin = { t: 40, r: 20, b: 50, l: 60 };
  layout.legend = { orientation: "h", x: 0, y: -0.18, yanchor: "top" };
  Plotly.react("horizon-maps-plot", traces, layout, PLOT_CONFIG);
  $("#horizon-maps-heading").textContent = `Roll and pitch errors over the grid at the disc radius `
    + `${fmt(map.disc_radius_deg, 3)}°, ${nominal ? "of the nominal sensor" : `of the calibrated sensor (${attitude.method})`}`;
  const s = attitude.summary.fitted?.[nominal ? "nominal" : "calibrated"];
  $("#horizon-maps-info").textContent = "Each node is the mean error of its scans: the roll and pitch the sensor reports "
    + "(through its parameters, turned into the table's frame through the mount) minus the table's. "
    + (s ? `Over every fitted scan: roll ${precise(s.roll_rms_deg, 3)}° RMS, pitch ${precise(s.pitch_rms_deg, 3)}° RMS. ` : "")
    + "The diamonds are the check points of this radius (never fitted), on the same colour scale.";
}

// -- the pulse of a reading -------------------------------------------------------------------------------------
function pulseSection(pulse) {
  const r = pulse.reading;
  $("#horizon-pulse-heading").textContent = `The pulse of reading ${r.id} (${r.key})`;
  $("#horizon-pulse-reading").textContent = `${r.stage} scan at the table's roll ${fmt(r.roll_deg, 3)}°, pitch `
    + `${fmt(r.pitch_deg, 3)}°, disc radius ${fmt(r.disc_radius_deg, 4)}°; revolution ${r.revolution ?? "–"}, period `
    + `${fmt(r.period_s * 1000, 3)} ms, head ${fmt(r.temperature_c, 2)} °C.`;
  const zoom = $("#horizon-pulse-zoom").value;
  const traces = [];
  const marks = [["detected_deg", "detected by the module", "#d62728", "solid"],
    ["calibrated_deg", "the calibrated model's edge", "#2ca02c", "dash"],
    ["nominal_deg", "the nominal model's edge", "#7f7f7f", "dot"]];
  pulse.cones.forEach((c, j) => {
    const axes = j === 0 ? { xaxis: "x", yaxis: "y" } : { xaxis: "x2", yaxis: "y2" };
    traces.push({ type: "scatter", mode: "lines", name: "pulse (drawn from the calibration)", legendgroup: "pulse",
      showlegend: j === 0, ...axes, x: pulse.phase_deg, y: c.level, line: { width: 1.5, color: "#1f77b4" },
      hovertemplate: `cone ${c.cone} %{x:.2f}°: %{y:.0f}<extra></extra>` });
    traces.push({ type: "scatter", mode: "lines", name: `threshold (C1 = ${pulse.threshold_fraction})`,
      legendgroup: "threshold", showlegend: j === 0, ...axes, x: [0, 360], y: [c.threshold, c.threshold],
      line: { width: 1, dash: "dash", color: "#444" }, hoverinfo: "skip" });
    for (const [key, name, color, dash] of marks) {
      const x = ["out", "in"].map((e) => c[key][e]).filter((v) => v !== null);
      // each edge as a vertical line (a trace, so that it has a legend entry and a hover)
      traces.push({ type: "scatter", mode: "lines", name, legendgroup: key, showlegend: j === 0, ...axes,
        x: x.flatMap((v) => [v, v, null]), y: x.flatMap(() => [c.level_space ?? 0, c.level_earth ?? 1, null]),
        line: { width: 1.5, color, dash }, hovertemplate: `cone ${c.cone} ${name}: %{x:.4f}°<extra></extra>` });
    }
  });
  const around = (edge) => {
    const centres = pulse.cones.map((c) => c.detected_deg[edge] ?? c.calibrated_deg[edge]).filter((v) => v !== null);
    return centres.map((v) => [v - 3, v + 3]);
  };
  const ranges = zoom === "all" ? [[0, 360], [0, 360]] : around(zoom);
  const layout = plotLayout("", "", "");
  delete layout.title;
  layout.grid = { rows: 2, columns: 1, pattern: "independent", ygap: 0.3 };
  layout.xaxis = { ...layout.xaxis, range: ranges[0], title: { text: "reported phase 360° · t / T [°]" } };
  layout.xaxis2 = { ...layout.xaxis, range: ranges[1] ?? ranges[0] };
  layout.yaxis = { ...layout.yaxis, title: { text: "detector [counts]" } };
  layout.yaxis2 = { ...layout.yaxis };
  layout.annotations = pulse.cones.map((c, j) => ({ xref: `x${j === 0 ? "" : 2} domain`, yref: `y${j === 0 ? "" : 2} domain`,
    x: 0, y: 1.02, xanchor: "left", yanchor: "bottom", showarrow: false,
    text: `cone ${c.cone}${c.saturated ? " — saturated (its edges are not fitted)" : ""}`, font: { size: 13 } }));
  layout.height = 640;
  layout.margin = { t: 40, r: 20, b: 50, l: 70 };
  layout.legend = { orientation: "h", x: 0, y: -0.12, yanchor: "top" };
  Plotly.react("horizon-pulse-plot", traces, layout, PLOT_CONFIG);
  const diff = (a, b) => (a === null || b === null ? "–" : `${a - b >= 0 ? "+" : ""}${precise(a - b, 3)}`);
  $("#horizon-pulse-edges tbody").replaceChildren(...pulse.cones.flatMap((c) => ["out", "in"].map((e) => el("tr", {},
    el("td", {}, String(c.cone)), el("td", {}, EDGE_NAMES[e]), el("td", {}, fmt(c.detected_deg[e], 4)),
    el("td", {}, fmt(c.calibrated_deg[e], 4)), el("td", {}, fmt(c.nominal_deg[e], 4)),
    el("td", {}, diff(c.detected_deg[e], c.calibrated_deg[e])), el("td", {}, diff(c.detected_deg[e], c.nominal_deg[e]))))));
  $("#horizon-pulse-info").textContent = "The run keeps each scan's edges and the pulse's two levels, not its samples: "
    + `the pulse is drawn from ${pulse.method ? `the calibration (${pulse.method})` : "the nominal sensor"} — the share `
    + `of the ${fmt(pulse.ifov_half_angle_deg, 0)}° IFOV that sees the disc along each cone's scan, with the cone's `
    + "half-angle, phase offset and the mount, the disc's radius with the threshold bias (and the 50 % locator's offset "
    + "on a curved limb) — between the space and Earth levels the module reported. The module's locator fires where "
    + "the pulse crosses the threshold; its edges are marked beside those the calibrated and the nominal model predict.";
}

// the latest request of each kind wins: an earlier answer that arrives after it is dropped
const latest = { reading: 0, method: 0 };
let shownReading = "";

async function showReading(run, method, readingId) {
  const ticket = ++latest.reading;
  const params = new URLSearchParams();
  if (method) params.set("method", method);
  if (readingId) params.set("reading_id", readingId);
  const text = params.toString();
  try {
    const pulse = await api(`/api/runs/${run.id}/horizon/pulse${text ? `?${text}` : ""}`);
    if (ticket !== latest.reading) return;
    shownReading = readingId;
    $("#horizon-pulse-section").hidden = false;
    $("#horizon-pulse-zoom").onchange = () => pulseSection(pulse);
    pulseSection(pulse);
  } catch (err) {
    if (ticket !== latest.reading) return;
    if (err.status === 404 && !readingId) $("#horizon-pulse-section").hidden = true;  // no usable scan
    else report(err);
  }
}

// -- one calibration shown ----------------------------------------------------------------------------------------
async function showMethod(run, method, downloads) {
  const ticket = ++latest.method;
  downloads(method);
  const query = method ? `?method=${encodeURIComponent(method)}` : "";
  const quiet = (err) => { if (err.status !== 404) report(err); return null; };  // 404: no usable scan
  const [edges, attitude] = await Promise.all([api(`/api/runs/${run.id}/horizon/edges${query}`).catch(quiet),
    api(`/api/runs/${run.id}/horizon/attitude${query}`).catch(quiet)]);
  if (ticket !== latest.method) return;
  $("#horizon-residuals-section").hidden = !edges;
  if (edges) {
    const draw = () => residualsPlot(edges);
    $("#horizon-residuals-x").onchange = draw;
    $("#horizon-residuals-model").onchange = draw;
    draw();
  }
  $("#horizon-maps-section").hidden = !attitude || !attitude.maps.length;
  if (attitude && attitude.maps.length) {
    $("#horizon-maps-radius").replaceChildren(...attitude.maps.map((m, k) => el("option", { value: String(k) },
      `${fmt(m.disc_radius_deg, 3)}°`)));
    const draw = () => mapsPlot(attitude);
    $("#horizon-maps-radius").onchange = draw;
    $("#horizon-maps-model").onchange = draw;
    draw();
  }
  $("#horizon-reading-form").onsubmit = (event) => {
    event.preventDefault();
    showReading(run, method, $("#horizon-reading").value.trim());
  };
  await showReading(run, method, shownReading);
}

async function showCalibration(run, method) {
  const query = method ? `?method=${encodeURIComponent(method)}` : "";
  let cal = null;
  try {
    cal = await api(`/api/runs/${run.id}/horizon/metrics${query}`);
  } catch (err) {
    if (err.status !== 404) report(err);
  }
  for (const id of ["#horizon-deviation-section", "#horizon-correlation-section", "#horizon-heldout-section"]) {
    $(id).hidden = !cal;
  }
  $("#horizon-parameters").hidden = !cal;
  $("#horizon-rejected-part").hidden = !cal;
  if (!cal) return;
  calibrationSection(cal);
  deviationPlot(cal);
  correlationPlot(cal);
  heldoutSection(cal);
}

/**
 * Show a horizon run's results (results.js has drawn its header: heading, provenance, resumption).
 * @param {object} run  GET /api/runs/{id}
 * @param {{downloads: function(string|undefined)}} helpers  the results page's download buttons, for one method
 */
export async function showHorizonRun(run, { downloads }) {
  $("#horizon-view").hidden = false;
  const calibrations = (await api(`/api/runs/${run.id}/calibrations`)).data;
  const usable = calibrations.filter((c) => !c.metrics?.error);
  const chosen = usable.find((c) => c.chosen) ?? usable.at(-1);
  const select = $("#method");
  methodOptions(select, usable, chosen);
  select.onchange = () => Promise.all([showCalibration(run, select.value), showMethod(run, select.value, downloads)])
    .catch(report);
  if (!usable.length) {
    const why = calibrations.length ? "every fit of this run failed" : noCalibrationReason(run);
    $("#horizon-none").hidden = false;
    $("#horizon-none").textContent = `No calibration: ${why}. The residuals, maps and pulse below are of the nominal `
      + "sensor.";
    $("#horizon-ok").hidden = true;
    listBox("#horizon-warnings", []);
    say(`no calibration: ${why}`, true);
  }
  await Promise.all([showCalibration(run, chosen?.method), showMethod(run, chosen?.method, downloads)]);
}
