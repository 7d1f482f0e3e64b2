// Field data (issue 13): a field CSV and, for a file of spots, the sensor's calibration, read here and posted to
// POST /api/field/analyse; the answer drawn as seed 003's figures 5.1–5.5 (the readings against SPA's Sun over
// time, clear samples apart from cloudy and out-of-field ones), its statistics, notes and warnings in words, and
// the site located from the Sun's track with its uncertainty ellipse beside the site the file states.
/* global Plotly */
import { $, api, el, fmt, initTokenForm, listBox, PLOT_CONFIG, plotLayout, report, say } from "./common.js";

// -- reading the files -----------------------------------------------------------------------------------------
const readText = (file) => new Promise((resolve, reject) => {
  const reader = new FileReader();
  reader.onload = () => resolve(reader.result);
  reader.onerror = () => reject(new Error(`cannot read ${file.name}: ${reader.error?.message ?? "unknown error"}`));
  reader.readAsText(file);
});

// the request body from the form (the files read); throws an Error saying what is wrong with them
async function requestBody(form) {
  const csvFile = $("#field-csv").files[0];
  if (!csvFile) throw new Error("choose a field CSV file first");
  const calibrationFile = $("#field-calibration").files[0];
  let calibration = null;
  if (calibrationFile) {
    const text = await readText(calibrationFile);
    try {
      calibration = JSON.parse(text);
    } catch (err) {
      throw new Error(`${calibrationFile.name} is not a calibration JSON file: ${err.message}`);
    }
    if (calibration === null || typeof calibration !== "object" || Array.isArray(calibration)) {
      throw new Error(`${calibrationFile.name} is not a calibration JSON file: it holds no JSON object`);
    }
  }
  const fov = form.elements.fov_half_deg.value.trim();
  const levelSd = form.elements.level_sd_deg.value.trim();
  return {
    csv: await readText(csvFile), calibration, heading: form.elements.heading.value, level: form.elements.level.value,
    locate: form.elements.locate.checked, fov_half_deg: fov === "" ? null : Number(fov),
    level_sd_deg: levelSd === "" ? null : Number(levelSd), name: csvFile.name,
  };
}

// -- the samples: clear, cloudy, out of the field of view ------------------------------------------------------
const GROUPS = [
  { key: "clear", name: "clear sky, Sun in the field of view", marker: { size: 5, color: "#1f77b4" } },
  { key: "cloud", name: "cloudy", marker: { size: 6, color: "#ff7f0e", symbol: "circle-open" } },
  { key: "out", name: "out of the field of view", marker: { size: 7, color: "#d62728", symbol: "x-thin-open",
    line: { width: 1.5, color: "#d62728" } } },
  { key: "other", name: "other samples (not counted as clear)", marker: { size: 6, color: "#7f7f7f", symbol: "diamond-open" } },
];

// the clear-sky statistics count the clear samples with the Sun in the field of view (`clear` alone says nothing
// of the field of view): out of it first, then cloud
function groupOf(c, i) {
  if (c.in_fov && c.in_fov[i] === false) return "out";
  if (c.cloud?.[i]) return "cloud";
  if (c.clear?.[i]) return "clear";
  return "other";
}

// plotly reads "2019-09-29T03:58:17.000" as a date (its zone, always UTC here, dropped)
const plotTime = (t) => String(t).replace(/(?:Z|[+-]00:?00)$/i, "");

// one trace per group of samples with any value of `y` (an array of the comparison), at their times
function sampleTraces(c, y, unit = "°") {
  const x = c.time_utc.map(plotTime);
  const groups = c.time_utc.map((_, i) => groupOf(c, i));
  return GROUPS.map((g) => {
    const index = groups.flatMap((k, i) => (k === g.key && y[i] !== null && y[i] !== undefined ? [i] : []));
    if (!index.length) return null;
    return { type: "scatter", mode: "markers", name: g.name, x: index.map((i) => x[i]), y: index.map((i) => y[i]),
      marker: g.marker, hovertemplate: `%{x}<br>%{y:.4f}${unit}<extra>${g.name}</extra>` };
  }).filter(Boolean);
}

function spaTrace(c, y, name) {
  return { type: "scatter", mode: "lines", name, x: c.time_utc.map(plotTime), y, line: { width: 1.5, color: "#333" },
    hovertemplate: "%{x}<br>%{y:.4f}°<extra>SPA</extra>" };
}

const timeLayout = (title, yTitle, extra = {}) => {
  const layout = plotLayout(title, "time (UTC)", yTitle, extra);
  layout.xaxis = { ...layout.xaxis, type: "date" };
  return layout;
};

// seed 003 figs. 5.1–5.5
function comparisonPlots(c) {
  const relative = c.heading?.fitted;
  Plotly.react("zenith-plot", [spaTrace(c, c.sun_zenith_deg, "SPA apparent zenith"),
    ...sampleTraces(c, c.measured_zenith_deg)],
  timeLayout("measured and SPA zenith against time (fig. 5.1)", "zenith [°]"), PLOT_CONFIG);
  Plotly.react("zenith-error-plot", sampleTraces(c, c.zenith_error_deg),
    timeLayout("zenith error, measured − SPA (fig. 5.2)", "zenith error [°]"), PLOT_CONFIG);
  Plotly.react("azimuth-plot", [spaTrace(c, c.sun_azimuth_deg, "SPA azimuth"), ...sampleTraces(c, c.measured_azimuth_deg)],
    timeLayout(`measured and SPA azimuth against time (fig. 5.3)${relative ? ", heading fitted" : ""}`,
      "azimuth, east of north [°]"), PLOT_CONFIG);
  $("#azimuth-error-heading").textContent = relative
    ? "Azimuth error against time, relative to the fitted heading (fig. 5.4)" : "Azimuth error against time (fig. 5.4)";
  Plotly.react("azimuth-error-plot", sampleTraces(c, c.azimuth_error_deg),
    timeLayout(`azimuth error, measured − SPA${relative ? " (relative: the heading is fitted)" : ""} (fig. 5.4)`,
      "azimuth error [°]"), PLOT_CONFIG);
  Plotly.react("vector-error-plot", sampleTraces(c, c.vector_error_deg),
    timeLayout("vector error: angle between the measured and SPA's direction (fig. 5.5)", "vector error [°]"),
    PLOT_CONFIG);
}

// -- the figures in words ------------------------------------------------------------------------------------
const STATS = [["n", 0], ["rms_zenith_deg", 4], ["rms_azimuth_deg", 4], ["rms_vector_deg", 4], ["std_vector_deg", 4],
  ["max_vector_deg", 4]];
const STATS_ROWS = [["clear", "clear sky, Sun in the field of view"],
  ["all", "all with the Sun in the field of view, cloudy too"]];

function statsTable(stats) {
  $("#stats tbody").replaceChildren(...STATS_ROWS.filter(([key]) => stats?.[key]).map(([key, name]) => el("tr",
    { class: key === "clear" ? "chosen" : "" }, el("td", {}, name),
    ...STATS.map(([field, digits]) => el("td", {}, fmt(stats[key][field], digits))))));
  if (!$("#stats tbody").children.length) {
    $("#stats tbody").append(el("tr", {}, el("td", { colspan: STATS.length + 1 }, "no statistics: no sample to compare")));
  }
}

const site = (s) => (s ? `${fmt(s.latitude_deg, 5)}°, ${fmt(s.longitude_deg, 5)}°`
  + `${s.altitude_m !== null && s.altitude_m !== undefined ? `, ${fmt(s.altitude_m, 0)} m` : ""}` : null);

function headingText(h) {
  if (!h) return "";
  if (h.fitted) {
    return `Heading ${fmt(h.deg, 3)}°${h.sd_deg !== null && h.sd_deg !== undefined ? ` ± ${fmt(h.sd_deg, 3)}° (1σ)` : ""}, `
      + "fitted to the track: the azimuth errors are relative to it, not to true north.";
  }
  return `Heading ${fmt(h.deg, 3)}° east of north, from the file.`;
}

const levelText = (l) => (l ? ` Level: roll ${fmt(l.roll_deg, 3)}°, pitch ${fmt(l.pitch_deg, 3)}°, `
  + `${l.fitted ? "fitted to the track" : "from the file"}.` : "");

function summarySection(result) {
  const c = result.comparison;
  $("#summary-section").hidden = false;
  $("#summary-heading").textContent = `${result.name}: comparison with SPA`;
  const stated = site(result.site);
  $("#summary-info").textContent = `${result.n} rows; the file states the site ${stated ?? "nowhere (no latitude and "
    + "longitude in its header)"}.${c ? "" : " No comparison: the analysis gave none."}`;
  $("#stats").hidden = !c;
  statsTable(c?.stats);
  $("#heading-info").textContent = headingText(c?.heading) + levelText(c?.level);
  listBox("#field-warnings", c?.warnings ?? []);
  const notes = [...(result.notes ?? []), ...(c?.notes ?? [])];
  $("#notes-part").hidden = !notes.length;
  $("#field-notes").replaceChildren(...notes.map((line) => el("li", {}, line)));
}

// -- the located site ------------------------------------------------------------------------------------------
const km = (v) => (v === null || v === undefined ? "" : ` ± ${fmt(v, 2)} km`);

function locationFigures(location, stated) {
  const level = location.ellipse_level ?? "1σ";
  const rows = [
    ["Latitude (located)", `${fmt(location.latitude_deg, 5)}°${km(location.sd_latitude_km)}`],
    ["Longitude (located)", `${fmt(location.longitude_deg, 5)}°${km(location.sd_longitude_km)}`],
    ["Heading (located)", `${fmt(location.heading_deg, 3)}°${location.sd_heading_deg !== null
      && location.sd_heading_deg !== undefined ? ` ± ${fmt(location.sd_heading_deg, 3)}°` : ""}`],
    ["Ellipse drawn", `the ${level} region (the ± figures are 1σ)`],
    ...(location.semi_axes_km?.length === 2 ? [["Ellipse semi-axes (1σ)",
      `${fmt(location.semi_axes_km[0], 2)} × ${fmt(location.semi_axes_km[1], 2)} km`]] : []),
    ["Site the file states", site(stated) ?? "none"],
    ["Distance from it", location.error_km !== null && location.error_km !== undefined ? `${fmt(location.error_km, 2)} km`
      : "– (the file states no site)"],
    ["Samples used", location.n ?? "–"],
    ["Residual RMS of the fit", `${fmt(location.residual_rms_deg, 4)}°`],
  ];
  $("#location-figures").replaceChildren(...rows.flatMap(([name, value]) => [el("dt", {}, name),
    el("dd", {}, String(value))]));
}

// the located site, its ellipse and the file's site on plain axes: longitude on x, latitude on y, a degree of
// latitude drawn 1/cos(latitude) times as long as one of longitude, so a kilometre is as long either way
function locationPlot(location, stated) {
  const e = location.ellipse ?? { latitude_deg: [], longitude_deg: [] };
  const level = location.ellipse_level ?? "1σ";
  const traces = [];
  if (e.latitude_deg?.length) {
    traces.push({ type: "scatter", mode: "lines", name: `${level} uncertainty ellipse`, x: e.longitude_deg,
      y: e.latitude_deg, fill: "toself", fillcolor: "rgba(31,119,180,0.15)", line: { color: "#1f77b4", width: 1.5 },
      hoverinfo: "skip" });
  }
  traces.push({ type: "scatter", mode: "markers", name: "located site", x: [location.longitude_deg],
    y: [location.latitude_deg], marker: { symbol: "cross", size: 11, color: "#1f77b4" },
    hovertemplate: "located: %{y:.5f}°, %{x:.5f}°<extra></extra>" });
  if (stated && stated.latitude_deg !== null && stated.longitude_deg !== null) {
    traces.push({ type: "scatter", mode: "markers", name: "site the file states", x: [stated.longitude_deg],
      y: [stated.latitude_deg], marker: { symbol: "star", size: 14, color: "#d62728" },
      hovertemplate: "stated: %{y:.5f}°, %{x:.5f}°<extra></extra>" });
  }
  const latitude = location.latitude_deg ?? stated?.latitude_deg ?? 0;
  const cos = Math.max(Math.cos((latitude * Math.PI) / 180), 0.05);
  const layout = plotLayout(`located site and its ${level} ellipse${location.error_km !== null
    && location.error_km !== undefined ? `, ${fmt(location.error_km, 2)} km from the stated site` : ""}`,
  "longitude, east [°]", "latitude, north [°]");
  layout.xaxis = { ...layout.xaxis, tickformat: ".3f" };
  layout.yaxis = { ...layout.yaxis, tickformat: ".3f", scaleanchor: "x", scaleratio: 1 / cos };
  Plotly.react("location-plot", traces, layout, PLOT_CONFIG);
}

function locationSection(result, asked) {
  const location = result.location;
  $("#location-section").hidden = !location;
  $("#location-none").hidden = !!location || !asked;
  if (!location) {
    Plotly.purge("location-plot");
    $("#location-none-text").textContent = "The analysis located no site from this file.";
    return;
  }
  listBox("#location-warnings", location.warnings ?? []);
  locationFigures(location, result.site);
  locationPlot(location, result.site);
}

// -- the form ---------------------------------------------------------------------------------------------------
function show(result, asked) {
  summarySection(result);
  const c = result.comparison;
  $("#comparison-plots").hidden = !c;
  if (c) comparisonPlots(c);
  locationSection(result, asked);
}

async function analyse(event) {
  event.preventDefault();
  const form = event.target;
  const button = $("#analyse");
  let body;
  try {
    body = await requestBody(form);
  } catch (err) {
    say(err.message, true);
    return;
  }
  button.disabled = true;
  say(`analysing ${body.name}…`);
  try {
    const result = await api("/api/field/analyse", { method: "POST", body });
    show(result, body.locate);
    const warned = (result.comparison?.warnings?.length ?? 0) + (result.location?.warnings?.length ?? 0);
    say(`${result.name}: ${result.n} rows analysed${warned ? `, ${warned} warning(s): see below` : ""}`);
  } catch (err) {
    report(err);
  } finally {
    button.disabled = false;
  }
}

$("#field-form").addEventListener("submit", analyse);
initTokenForm();
