// The results view of a CSS run (seed 000's coarse-sun-sensor head: six faces × a UV photodiode, a visible photodiode
// and a thermopile), chosen by results.js from the run's family: every response law's figures (the Sun's direction
// held out, at the check directions and at the fitted ones), the chosen calibration's warnings, the detectors it left
// out and the readings it rejected (GET /api/runs/{id}/css/metrics); a face × type grid of every detector's signal
// against the incidence on its calibrated normal with the calibration's curve, or its residuals, or its SNR (the
// thesis' "current versus angle", Figs 3.1–3.4); every detector's parameters ± 1σ (GET …/css/detectors); the Sun's
// direction from each reading with its stated 1σ (GET …/css/directions); the thesis' 5 × 6 quantiser codes of a reading
// and the azimuth/elevation they give (GET …/css/quantiser). Everything is computed by the server
// (bench/css_results.py); this module only draws it.
/* global Plotly */
import { $, api, el, fmt, listBox, methodOptions, noCalibrationReason, PLOT_CONFIG, plotLayout, report, say } from "./common.js";

const FACES = ["px", "py", "mx", "my", "pz", "mz"];
const DETECTORS = ["uv", "vis", "ir"];
const DETECTOR_NAMES = { uv: "UV (EPD-365)", vis: "visible (BPW 21)", ir: "IR (TPS 230)" };
const FAULTS = { stuck: "stuck", dead: "dead", saturated: "saturated", inverted: "inverted", unlit: "never lit" };
const CURVE_COLOURS = ["#222", "#8c564b", "#9467bd", "#17becf", "#bcbd22"];
const deg = (v) => fmt(v, 3);
// a number to `digits` significant digits, in powers of ten where it is small or large (currents of nA, µA)
const precise = (v, digits = 4) => {
  if (v === null || v === undefined || Number.isNaN(Number(v))) return "–";
  const x = Number(v);
  if (x !== 0 && (Math.abs(x) < 1e-3 || Math.abs(x) >= 1e5)) return x.toExponential(digits - 1);
  return Number(x.toPrecision(digits)).toString();
};
const pm = (value, sd, digits = 4) => `${precise(value, digits)}${sd === null || sd === undefined ? "" : ` ± ${precise(sd, 2)}`}`;
const figures = (f) => (f && f.n_points ? `${deg(f.rms_deg)} / ${deg(f.p95_deg)} / ${deg(f.max_deg)}` : "–");

// -- every response law's figures, the warnings, the faulty detectors, the rejected readings ----------------------------
function metricsTable(metrics) {
  const rows = metrics.data.map((m) => {
    const held = m.held_out ?? {};
    const faulty = Object.keys(m.faulty ?? {});
    return el("tr", { class: m.chosen ? "chosen" : "" }, el("td", {}, m.method + (m.chosen ? " ✓ chosen" : "")),
      el("td", {}, figures(m.held_out)), el("td", {}, held.n_points ? `${held.n_points} (${held.n_degenerate})` : "–"),
      el("td", {}, figures(m.check)), el("td", {}, figures(m.at_nodes)),
      el("td", held.normalised_rms > 2 ? { class: "over", title: "the stated uncertainty is too small" } : {},
        fmt(held.normalised_rms, 2)),
      el("td", {}, `${m.n_channels}${faulty.length ? ` (left out: ${faulty.join(", ")})` : ""}`),
      el("td", {}, m.error ?? (m.held_out ? "" : "not held out")));
  });
  $("#css-metrics tbody").replaceChildren(...rows);
  $("#css-metrics").hidden = !rows.length;
  $("#css-metrics-none").hidden = rows.length > 0;
  listBox("#css-warnings", metrics.warnings);
  listBox("#css-faulty", metrics.faulty.map((f) => `${f.channel} — ${FAULTS[f.fault] ?? f.fault ?? "faulty"}: ${f.words}`)
    .concat(metrics.missing.length ? [`no entry in the calibration: ${metrics.missing.join(", ")}`] : []));
  const rejected = metrics.rejected;
  $("#css-rejected-part").hidden = !rows.length;
  $("#css-rejected-summary").textContent = rejected.length
    ? `${rejected.length} single reading(s) of a detector rejected by the fit (the reading's other detectors stand)`
    : "No reading was rejected by the fit.";
  $("#css-rejected").hidden = !rejected.length;
  $("#css-rejected tbody").replaceChildren(...rejected.map((r) => el("tr", {},
    el("td", {}, String(r.row ?? "–")), el("td", {}, r.key ?? "–"), el("td", {}, r.channel ?? "–"),
    el("td", {}, fmt(r.zenith_deg, 2)), el("td", {}, fmt(r.azimuth_deg, 2)), el("td", {}, r.reason))));
}

// -- the face × type grid ----------------------------------------------------------------------------------------
// one subplot per detector, faces down (the thesis' order 1 … 6), types across; axis n of subplot (row, column)
const axisOf = (row, column) => {
  const n = row * DETECTORS.length + column + 1;
  return n === 1 ? "" : String(n);
};

function gridTraces(view, kind) {
  const traces = [];
  const seen = new Set();  // a legend entry per kind of trace, from the first subplot that has one
  const legend = (name) => { const first = !seen.has(name); seen.add(name); return first; };
  for (const d of view.data) {
    const a = axisOf(FACES.indexOf(d.face), DETECTORS.indexOf(d.detector));
    const axes = { xaxis: `x${a}`, yaxis: `y${a}` };
    const p = d.points;
    const rows = p.reading_id.map((_, i) => i);
    const text = (i) => `reading ${p.reading_id[i]}, ${fmt(p.temperature_c[i], 1)} °C${p.check[i] ? ", check (never fitted)" : ""}`
      + (p.left_out[i] ? `<br>left out of the fit: ${p.left_out[i]}` : "");
    const y = (i) => (kind === "residual" ? p.residual[i] : p.signal[i]);
    if (kind !== "snr" && !(kind === "residual" && !d.valid)) {
      // the signals of one plate temperature at a time (a thermopile's offset moves with the head's temperature more
      // than the lamp moves it): the full sweep's shown, the others a click on the legend away; residuals all shown
      const main = (i) => kind === "residual" || p.group[i] === view.main_temperature;
      const groups = [
        ["fitted readings", rows.filter((i) => main(i) && !p.left_out[i] && !p.check[i]), { size: 4, color: "#1f77b4" }],
        ["check readings (never fitted)", rows.filter((i) => main(i) && !p.left_out[i] && p.check[i]),
          { size: 6, symbol: "diamond", color: "#ff7f0e" }],
        ["left out of the fit", rows.filter((i) => main(i) && p.left_out[i]),
          { size: 7, symbol: "x-thin-open", color: "#d62728", line: { width: 1.5, color: "#d62728" } }],
        ...view.temperatures_c.map((t, k) => [`readings at ${fmt(t, 1)} °C`,
          rows.filter((i) => !main(i) && p.group[i] === k), { size: 4, color: CURVE_COLOURS[k % CURVE_COLOURS.length] },
          "legendonly"]),
      ];
      for (const [name, index, marker, visible = true] of groups) {
        if (!index.length) continue;
        traces.push({ type: "scatter", mode: "markers", name, legendgroup: name, showlegend: legend(name), visible,
          ...axes, x: index.map((i) => p.incidence_deg[i]), y: index.map(y), text: index.map(text), marker,
          hovertemplate: `${d.channel} %{x:.2f}°: %{y:.4s}${d.unit}<br>%{text}<extra></extra>` });
      }
    }
    if (!d.curve) continue;
    if (kind === "signal") {
      view.temperatures_c.forEach((t, k) => {
        const name = `calibration at ${fmt(t, 1)} °C`;
        traces.push({ type: "scatter", mode: "lines", name, legendgroup: name, showlegend: legend(name), ...axes,
          visible: k === view.main_temperature ? true : "legendonly", x: view.incidence_deg, y: d.curve.signals[k],
          line: { width: 1.5, color: CURVE_COLOURS[k % CURVE_COLOURS.length] },
          hovertemplate: `${d.channel} %{x:.0f}°: %{y:.4s}${d.unit} (${name})<extra></extra>` });
      });
    } else if (kind === "residual") {
      for (const sign of [1, -1]) {
        const name = "± 1σ noise of one reading";
        traces.push({ type: "scatter", mode: "lines", name, legendgroup: name, showlegend: sign > 0 && legend(name),
          ...axes, x: view.incidence_deg, y: d.curve.noise_sd.map((s) => (s === null ? null : sign * s)),
          line: { width: 1, dash: "dot", color: "#555" }, hoverinfo: "skip" });
      }
    } else {
      const name = `SNR at ${fmt(view.reference_temperature_c, 0)} °C`;
      traces.push({ type: "scatter", mode: "lines", name, legendgroup: name, showlegend: legend(name), ...axes,
        x: view.incidence_deg, y: d.curve.snr_db, line: { width: 1.5, color: "#2ca02c" },
        hovertemplate: `${d.channel} %{x:.0f}°: %{y:.1f} dB<extra></extra>` });
    }
  }
  return traces;
}

const KIND_UNITS = { signal: (d) => d.unit, residual: (d) => d.unit, snr: () => "dB" };

const ROW_PX = 220;  // the height of a face's row of plots

function curvesPlot(view) {
  const kind = $("#css-curves-kind").value;
  const temperature = fmt(view.temperatures_c[view.main_temperature], 1);
  $("#css-curves-heading").textContent = `${{ signal: `Each detector's signal at ${temperature} °C`,
    residual: "Each detector's residual (reading − calibration)", snr: "Each detector's signal-to-noise ratio" }[kind]} `
    + "against the incidence on its " + (view.method ? `calibrated normal (${view.method})`
    : "nominal normal (no calibration)");
  const layout = plotLayout("", "", "");
  delete layout.title;
  layout.grid = { rows: FACES.length, columns: DETECTORS.length, pattern: "independent", roworder: "top to bottom",
    xgap: 0.12, ygap: 0.38 };
  layout.height = ROW_PX * FACES.length + 110;
  layout.margin = { t: 70, r: 20, b: 45, l: 60 };
  layout.legend = { orientation: "h", x: 0, y: 1, yanchor: "top", yref: "container", font: { size: 12 } };
  layout.annotations = [];
  for (const d of view.data) {
    const row = FACES.indexOf(d.face), column = DETECTORS.indexOf(d.detector);
    const a = axisOf(row, column);
    const bottom = row === FACES.length - 1;
    layout[`xaxis${a}`] = { range: [0, view.incidence_limit_deg], dtick: 15, tickfont: { size: 10 }, zeroline: false,
      title: bottom ? { text: "incidence [°]", font: { size: 11 } } : undefined };
    layout[`yaxis${a}`] = { tickformat: kind === "snr" ? "" : "~s", tickfont: { size: 10 }, automargin: true, nticks: 5,
      title: { text: KIND_UNITS[kind](d), font: { size: 11 }, standoff: 2 } };
    const status = !d.valid ? ` — ${d.fault ? `left out: ${FAULTS[d.fault] ?? d.fault}` : "not calibrated"}` : "";
    layout.annotations.push({ xref: `x${a} domain`, yref: `y${a} domain`, x: 0, y: 1, xanchor: "left", yanchor: "bottom",
      showarrow: false, text: `face ${d.thesis_face} ${d.face} · ${DETECTOR_NAMES[d.detector]}${status}`,
      font: { size: 11, color: d.valid ? "#222" : "#b3261e" } });
  }
  Plotly.react("css-curves-plot", gridTraces(view, kind), layout, PLOT_CONFIG);
  const behind = view.data.reduce((n, d) => n + d.behind.n, 0);
  const dark = view.data[0]?.dark.n ?? 0;
  $("#css-curves-info").textContent = `${view.n_readings} readings of the run's lineage, every detector read at each: `
    + `those with the Sun within ${fmt(view.incidence_limit_deg, 0)}° of a detector's normal are drawn on its plot `
    + `(${behind} detector readings with the Sun behind, and ${dark} shutter-closed readings per detector, are not). `
    + (view.method ? `The curves are the ${view.method} law of the calibration at the plate temperature of the full `
      + `sweep, ${temperature} °C; the readings and curves at the run's other temperatures `
      + `(${view.temperatures_c.filter((_, k) => k !== view.main_temperature).map((t) => `${fmt(t, 1)} °C`).join(", ") || "none"}) `
      + "show with a click on their legend entry (the residuals are of every reading, each at its own temperature). "
      + "The SNR is of one reading, from the noise model the fit measured (the repeat scatter), not the thesis' "
      + "front-end design (Table C.2)."
      : "The run has no calibration: incidence on the faces' nominal normals, no curve.");
}

// -- every detector's parameters --------------------------------------------------------------------------------
function parametersTable(view) {
  const spline = view.response === "spline";  // its shape is its coefficients: counted, listed in the tooltip
  const shape = view.response === "power" ? "power" : "kappa";
  const shapeLabel = spline ? "spline coefficients" : view.response === "power" ? "exponent p" : "Kelly κ";
  const heads = ["detector", "scale S", "offset b", "normal zenith / azimuth [°]", shapeLabel, "FOV cut-off θc [°]",
    "c_T [1/°C]", "b_T [unit/°C]", "fit RMS (readings)", "χ²/dof", "held-out RMS (in σ)", "status"];
  $("#css-parameters thead").replaceChildren(el("tr", {}, ...heads.map((h) => el("th", {}, h))));
  $("#css-parameters tbody").replaceChildren(...view.data.map((d) => {
    const name = el("td", { title: `face ${d.thesis_face} ${d.face}, ${DETECTOR_NAMES[d.detector]}` },
      `${d.channel} [${d.unit}]`);
    if (!d.valid) {
      return el("tr", { class: "muted" }, name, el("td", { colspan: heads.length - 2 }, "–"),
        el("td", { class: "over" }, d.fault ? `left out: ${FAULTS[d.fault] ?? d.fault}` : "not calibrated"));
    }
    const p = Object.fromEntries(d.parameters.map((q) => [q.name, q]));
    const cell = (q, digits) => el("td", q && !q.fitted ? { class: "muted", title: "held, not fitted" } : {},
      q ? (q.value === null ? "none" : pm(q.value, q.sd, digits)) : "–");
    const n = d.normal;
    const held = d.heldout;
    const worse = held && d.at_nodes?.rms && held.rms > 3 * d.at_nodes.rms;
    return el("tr", {}, name, cell(p.scale), cell(p.bias, 3),
      el("td", {}, `${fmt(n.zenith_deg, 3)} / ${fmt(n.azimuth_deg, 3)} ± ${precise(n.sd_deg, 2)}`),
      spline ? el("td", { title: d.parameters.filter((q) => q.name.startsWith("spline_"))
        .map((q) => `${q.name} ${pm(q.value, q.sd, 4)}`).join("\n") },
      `${d.parameters.filter((q) => q.name.startsWith("spline_")).length}`) : cell(p[shape], 4),
      cell(p.fov_half_deg, 4), cell(p.temp_coeff_per_c, 3), cell(p.bias_temp_coeff_per_c, 3),
      el("td", {}, `${precise(d.fit?.rms, 3)} (${d.fit?.n_points ?? "–"})`), el("td", {}, fmt(d.fit?.chi2_dof, 1)),
      el("td", worse ? { class: "over", title: "much larger held out than at the fitted directions" } : {},
        held ? `${precise(held.rms, 3)} (${fmt(held.rms_normalised, 1)} σ)` : "–"),
      el("td", {}, d.warnings.length ? `${d.warnings.length} warning(s)` : "ok"));
  }));
  $("#css-parameters-heading").textContent = view.method
    ? `Every detector's parameters ± 1σ (${view.method} law; S and b at ${fmt(view.reference_temperature_c, 0)} °C)`
    : "Every detector's parameters: the run has no calibration";
  $("#css-parameters-note").textContent = "Model: signal = S·(1 + c_T (T − 25 °C))·R(cos θ)·E(θ) + b + b_T (T − 25 °C), "
    + "θ the incidence on the detector's normal, R the response law, E the field-of-view cut-off at θc. ± 1σ from the "
    + "fit's covariance; a grey value was held, not fitted. S and b are in the detector's unit (A for the photodiodes, "
    + "V for the thermopiles). The held-out RMS is the residual at directions left out of the fit (its folds refitted), "
    + "and in units of the noise; the warnings are listed above.";
}

// -- the Sun's direction from each reading -------------------------------------------------------------------------
function directionsPlot(directions) {
  const against = $("#css-directions-x").value;
  const scored = directions.data.filter((d) => !d.failed && !d.degenerate);
  const degenerate = against === "elevation" ? directions.data.filter((d) => !d.failed && d.degenerate) : [];
  const text = (d) => `${d.key}, reading ${d.reading_id}<br>true az ${fmt(d.az_deg, 1)}°, el ${fmt(d.el_deg, 1)}°; `
    + `estimated az ${fmt(d.az_fit_deg, 1)}°, el ${fmt(d.el_fit_deg, 1)}° ± ${fmt(d.sigma_scaled_deg, 3)}° (1σ), `
    + `${d.n_faces_lit} lit face(s)`;
  const x = (d) => (against === "elevation" ? d.el_deg : d.sigma_scaled_deg);
  const traces = [["fitted", "at the fitted directions", "circle", "#1f77b4"],
    ["check", "at the check directions (never fitted)", "diamond", "#ff7f0e"]].map(([kind, name, symbol, color]) => {
    const points = scored.filter((d) => d.kind === kind);
    return points.length ? { type: "scatter", mode: "markers", name, x: points.map(x), y: points.map((d) => d.error_deg),
      text: points.map(text), marker: { symbol, size: 6, color },
      hovertemplate: "error %{y:.3f}°<br>%{text}<extra></extra>" } : null;
  }).filter(Boolean);
  if (degenerate.length) {
    traces.push({ type: "scatter", mode: "markers", name: "fewer than two non-coplanar lit faces (not scored)",
      x: degenerate.map((d) => d.el_deg), y: degenerate.map((d) => d.error_deg), text: degenerate.map(text),
      marker: { symbol: "circle-open", size: 5, color: "#999" },
      hovertemplate: "error %{y:.3f}°, direction undetermined<br>%{text}<extra></extra>" });
  }
  const sigmas = scored.map((d) => d.sigma_scaled_deg).filter((v) => v > 0);
  if (against === "sigma" && sigmas.length) {
    // the error at 1, 2 and 3 × the stated 1σ: an honest uncertainty has about 2/3 of the points under the first
    const low = Math.min(...sigmas) / 2, high = Math.max(...sigmas) * 2;
    [[1, "solid"], [2, "dash"], [3, "dot"]].forEach(([k, dash]) => traces.push({ type: "scatter", mode: "lines",
      name: `error = ${k} × stated 1σ`, x: [low, high], y: [k * low, k * high], line: { width: 1, dash, color: "#555" },
      hoverinfo: "skip" }));
  }
  const layout = plotLayout(`the Sun's direction from each reading through ${directions.method}: its angle to the true `
    + (against === "elevation" ? "direction against the true elevation" : "direction against the stated 1σ"),
  against === "elevation" ? "true elevation (thesis) [°]" : "stated 1σ of the direction [°]", "error [°]");
  layout.yaxis = { ...layout.yaxis, type: "log", exponentformat: "power" };
  if (against === "sigma") layout.xaxis = { ...layout.xaxis, type: "log", exponentformat: "power" };
  Plotly.react("css-directions-plot", traces, layout, PLOT_CONFIG);
  const s = directions.summary;
  const part = (f, what) => (f && f.n_points ? `${what}: RMS ${deg(f.rms_deg)}°, p95 ${deg(f.p95_deg)}°, max ${deg(f.max_deg)}° `
    + `over ${f.n_points} readings (${f.n_degenerate} degenerate), ${fmt(f.normalised_rms, 2)}× the stated 1σ` : null);
  $("#css-directions-info").textContent = [part(s.heldout, "Held out (directions left out of the fit, refitted)"),
    part(s.check, "at the check directions (never fitted)"), part(s.fitted, "at the fitted directions")]
    .filter(Boolean).join("; ") + ". The direction is the calibration's weighted least-squares estimate from all 18 "
    + "detectors (readings the fit rejected left out); its stated 1σ is the estimator's × the calibration's "
    + `uncertainty scale ${fmt(directions.uncertainty_scale, 2)}. A reading lighting one face only (or two opposite `
    + "faces) leaves the direction on a cone: it is not scored (drawn grey against the elevation).";
}

// -- the thesis' quantiser codes --------------------------------------------------------------------------------
const VARIANTS = {
  listing: "listing D.6's tables",
  calibrated: "tables rebuilt from this calibration",
};

function codeMatrix(title, rows, codes, faces, detector) {
  const header = el("tr", {}, el("th", {}, "bit"), ...faces.map((f) => el("th", {}, `${f.thesis_face} ${f.face}`)));
  const bits = rows.map((row, r) => el("tr", {}, el("td", {}, `b${4 - r}`),
    ...[...row].map((c) => el("td", { class: c === "x" ? "bit unused" : "bit" }, c))));
  const code = el("tr", {}, el("td", {}, "code"), ...codes.map((c) => el("td", {}, c < 0 ? "–" : String(c))));
  const truth = el("tr", { class: "muted" }, el("td", {}, "at the true incidence"),
    ...faces.map((f) => el("td", { title: `incidence ${fmt(f[`${detector}_incidence_deg`], 2)}°` },
      String(f[`${detector}_true_code`]))));
  return el("table", {}, el("caption", {}, title), el("thead", {}, header), el("tbody", {}, ...bits, code, truth));
}

function quantiserSection(codes) {
  const r = codes.reading;
  $("#css-quantiser-heading").textContent = `The thesis' quantiser codes of reading ${r.id} (${r.key})`;
  $("#css-quantiser-reading").textContent = `${r.stage} reading at ${fmt(r.temperature_c, 2)} °C; `
    + (r.zenith_deg === null ? "the shutter closed: no Sun. "
      : `the true Sun at azimuth ${fmt(r.az_deg, 2)}°, elevation ${fmt(r.el_deg, 2)}° (body zenith ${fmt(r.zenith_deg, 2)}°). `)
    + (r.clipped.length ? `Clipped: ${r.clipped.join(", ")}. ` : "");
  const tables = [];
  for (const [name, title] of Object.entries(VARIANTS)) {
    const v = codes.variants[name];
    if (!v) continue;
    tables.push(codeMatrix(`EPDsun, ${title}`, v.matrices.EPDsun, v.codes.EPDsun, codes.faces, "epd"),
      codeMatrix(`BPWsun, ${title}`, v.matrices.BPWsun, v.codes.BPWsun, codes.faces, "bpw"));
  }
  $("#css-quantiser").replaceChildren(...tables);
  const bound = `± ${fmt(codes.quantisation_deg, 1)}° (half a code's bin)`;
  const rows = [el("tr", { class: "chosen" }, el("td", {}, "the truth (the table's setting)"), el("td", {}, fmt(r.az_deg, 2)),
    el("td", {}, fmt(r.el_deg, 2)), el("td", {}, "–"), el("td", {}, "–"), el("td", {}, "–"))];
  for (const [name, title] of Object.entries(VARIANTS)) {
    const v = codes.variants[name];
    if (!v) continue;
    for (const [key, faces, label] of [["epd", v.sun_faces_epd, "EPD"], ["bpw", v.sun_faces_bpw, "BPW"]]) {
      const s = v.sun[key];
      rows.push(el("tr", {}, el("td", {}, `the thesis' algorithm, ${label} codes, ${title}`), el("td", {}, fmt(s.az_deg, 1)),
        el("td", {}, fmt(s.el_deg, 1)), el("td", {}, faces.join(", ")), el("td", {}, fmt(s.error_deg, 2)), el("td", {}, bound)));
    }
  }
  const e = codes.estimate;
  if (e) {
    rows.push(el("tr", {}, el("td", {}, `least squares through ${codes.method} (all 18 detectors)`),
      el("td", {}, fmt(e.az_deg, 2)), el("td", {}, fmt(e.el_deg, 2)), el("td", {}, `${e.n_faces_lit} lit`),
      el("td", {}, fmt(e.error_deg, 3)),
      el("td", {}, e.degenerate ? "none: too few lit faces" : `± ${fmt(e.sigma_deg, 3)}° (1σ)`)));
  }
  $("#css-quantiser-sun tbody").replaceChildren(...rows);
  const listing = codes.variants.listing;
  $("#css-quantiser-note").textContent = "Codes: 0 brighter than the table's 0°, k the incidence bin "
    + "[5(k−1), 5k]°, 19 not lit; a column of x: the face was not used. The elevation comes from face 5 or 6, the "
    + "azimuth from faces 1–4 (exact only at elevation 0, digest §5.4). "
    + (listing.offsets_subtracted ? "Listing D.6's tables compare photocurrents: the calibration's offsets are "
      + "subtracted first; the rebuilt tables hold them and take the raw readings. "
      : "Without a calibration the raw readings go through listing D.6's tables. ")
    + codes.tps_note;
}

// the latest request of each kind wins: an answer to an earlier one (another calibration, another reading) that
// arrives after it is dropped
const latest = { reading: 0, method: 0 };
let shownReading = "";  // the reading whose codes are shown ("": the latest lit one), kept for another calibration

async function showReading(run, method, readingId) {
  const ticket = ++latest.reading;
  const params = new URLSearchParams();
  if (method) params.set("method", method);
  if (readingId) params.set("reading_id", readingId);
  const text = params.toString();
  try {
    const codes = await api(`/api/runs/${run.id}/css/quantiser${text ? `?${text}` : ""}`);
    if (ticket !== latest.reading) return;
    shownReading = readingId;
    quantiserSection(codes);
    $("#css-quantiser-section").hidden = false;
  } catch (err) {
    if (ticket !== latest.reading) return;
    if (err.status === 404 && !readingId) $("#css-quantiser-section").hidden = true;  // no lit reading yet
    else report(err);
  }
}

// -- one calibration shown ----------------------------------------------------------------------------------------
async function showMethod(run, method, downloads) {
  const ticket = ++latest.method;
  downloads(method);
  const query = method ? `?method=${encodeURIComponent(method)}` : "";
  const [view, directions] = await Promise.all([
    api(`/api/runs/${run.id}/css/detectors${query}`).catch((err) => { report(err); return null; }),
    method ? api(`/api/runs/${run.id}/css/directions${query}`).catch((err) => { report(err); return null; }) : null]);
  if (ticket !== latest.method) return;
  if (view) {
    const draw = () => curvesPlot(view);
    $("#css-curves-kind").onchange = draw;
    draw();
    parametersTable(view);
  }
  $("#css-directions-section").hidden = !directions;
  if (directions) {
    $("#css-directions-x").onchange = () => directionsPlot(directions);
    directionsPlot(directions);
  }
  $("#css-reading-form").onsubmit = (event) => {
    event.preventDefault();
    showReading(run, method, $("#css-reading").value.trim());
  };
  await showReading(run, method, shownReading);
}

/**
 * Show a CSS run's results (results.js has drawn its header: heading, provenance, resumption).
 * @param {object} run  GET /api/runs/{id}
 * @param {{downloads: function(string|undefined)}} helpers  the results page's download buttons, for one method
 */
export async function showCssRun(run, { downloads }) {
  $("#css-view").hidden = false;
  const metrics = await api(`/api/runs/${run.id}/css/metrics`);
  metricsTable(metrics);
  const usable = metrics.data.filter((m) => !m.error);
  const chosen = usable.find((m) => m.chosen) ?? usable[0];
  const select = $("#method");
  methodOptions(select, usable, chosen);
  select.onchange = () => showMethod(run, select.value, downloads).catch(report);
  if (!usable.length) {
    const why = metrics.data.length ? "every fit of this run failed: see the table" : noCalibrationReason(run);
    $("#css-metrics-none").textContent = `No calibration: ${why}.`;
    say(`no calibration: ${why}`, true);
  }
  await showMethod(run, chosen?.method, downloads);
}
