// Shared by every page: the token (localStorage), fetch with Authorization: Bearer, small DOM helpers.
/* global Plotly */
const KEY = "sunbench.token";

export const getToken = () => localStorage.getItem(KEY) || "";
export const setToken = (t) => (t ? localStorage.setItem(KEY, t.trim()) : localStorage.removeItem(KEY));

export class ApiError extends Error {
  constructor(status, detail) {
    super(`${status}: ${typeof detail === "string" ? detail : JSON.stringify(detail)}`);
    this.status = status;
    this.detail = detail;
  }
}

// fetch an API path with the token; JSON bodies in and out; throws ApiError on a non-2xx answer. A 401 with a
// token set means the server refused that token: the token box says so (and opens) until a request succeeds.
export async function api(path, { method = "GET", body, raw = false, headers: extra = {} } = {}) {
  const headers = { ...extra };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const response = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  if (!response.ok) {
    let detail = response.statusText;
    try { detail = (await response.json()).detail; } catch (_) { /* not JSON */ }
    if (response.status === 401) {
      tokenState(token ? "refused" : "none");
      showTokenForm(true);
    }
    throw new ApiError(response.status, detail);
  }
  if (token && token === getToken()) tokenState("set");  // the server took it
  if (raw) return response;
  return response.status === 204 ? null : response.json();
}

// save a download (CSV, JSON, C header) fetched with the token: a plain link could not send it
export async function download(path, filename) {
  const blob = await (await api(path, { raw: true })).blob();
  const url = URL.createObjectURL(blob);
  const a = el("a", { href: url, download: filename });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) node.setAttribute(k, v === true ? "" : v);
  }
  node.append(...children.flat().filter((c) => c !== null && c !== undefined));
  return node;
}

export const $ = (sel) => document.querySelector(sel);
export const fmt = (v, digits = 3) => (v === null || v === undefined || Number.isNaN(v) ? "–" : Number(v).toFixed(digits));

// a current in words with its SI prefix: "1.062 µA", "308.7 pA"
const PREFIXES = [[1e-3, "mA"], [1e-6, "µA"], [1e-9, "nA"], [1e-12, "pA"], [1e-15, "fA"]];
export function amps(v, digits = 4) {
  if (v === null || v === undefined || Number.isNaN(v)) return "–";
  const size = Math.abs(v);
  const [scale, unit] = PREFIXES.find(([s]) => size >= s) ?? (size === 0 ? [1, "A"] : PREFIXES[PREFIXES.length - 1]);
  return `${Number((v / scale).toPrecision(digits))} ${unit}`;
}

export function duration(s) {
  if (s === null || s === undefined) return "–";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return h ? `${h} h ${m} min` : m ? `${m} min ${sec} s` : `${sec} s`;
}

// the message line (#message): what the last action did, or why it was refused. A message is about the moment
// it was said: a success fades after INFO_S, a refusal stays until the next action or a new token (never
// over a later state it no longer describes); `kind` "token" marks a refusal of the token itself
const INFO_S = 10;
let fade = null;

export function say(text, error = false, kind = "") {
  const box = $("#message");
  if (!box) return;
  clearTimeout(fade);
  box.textContent = text;
  box.className = error ? "message error" : "message";
  box.dataset.kind = kind;
  if (text && !error) fade = setTimeout(() => clearMessage(), INFO_S * 1000);
}

// clear the message line (only the messages of `kind` when given)
export function clearMessage(kind) {
  const box = $("#message");
  if (!box || (kind !== undefined && box.dataset.kind !== kind)) return;
  clearTimeout(fade);
  box.textContent = "";
  box.className = "message";
  box.dataset.kind = "";
}

const TOKEN_FILE = "~/.config/sunbench/token on the bench computer";

// an API refusal in words; a 401 is about the token: missing, or not the server's
export function refusal(err) {
  if (!(err instanceof ApiError)) return String(err);
  if (err.status === 401) {
    return getToken() ? `token refused: the server does not know the token pasted; paste the one in ${TOKEN_FILE}`
      : `no token: paste the token (in ${TOKEN_FILE}) to use the bench`;
  }
  return `Refused: ${err.message}`;
}

export const report = (err) => say(refusal(err), true, err instanceof ApiError && err.status === 401 ? "token" : "");

// the token form in the header of every page
function showTokenForm(open) {
  const details = $("#token-box");
  if (details) details.open = open;
}

const TOKEN_STATES = { none: "no token", set: "token set", refused: "token refused" };

// what the header says of the token: none pasted, set, or refused by the server (in red)
function tokenState(state) {
  const box = $("#token-state");
  if (!box) return;
  box.textContent = TOKEN_STATES[state];
  box.className = state === "refused" ? "refused" : "";
}

export function initTokenForm(onChange) {
  const form = $("#token-form");
  if (!form) return;
  const input = form.querySelector("input");
  const refresh = () => tokenState(getToken() ? "set" : "none");
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    setToken(input.value);
    input.value = "";
    refresh();
    showTokenForm(false);
    // what was refused was refused with the old token: it says nothing of the new one (a new refusal will)
    if (document.querySelector("#message.error")) clearMessage();
    if (onChange) onChange();
  });
  form.querySelector("[data-forget]").addEventListener("click", () => { setToken(""); refresh(); });
  refresh();
  if (!getToken()) showTokenForm(true);
}

// plans with a stopping rule (bench/plans.py physical_plan, bench/families/qd.py qd_physical_plan): a run's
// planned points are its cap, so its point total, progress and ETA are upper bounds (preflight says so of a
// campaign: the dry run's upper_bound)
const STOPPING_PLANS = new Set(["physical", "qd-physical"]);
export const stopsEarly = (planName) => STOPPING_PLANS.has(planName);

export const query = (name) => new URLSearchParams(location.search).get(name);

// a plot title in lines of at most `width` characters: plotly never wraps a title, and a long one ran off the
// card's edge
export function wrapTitle(text, width = 46) {
  const lines = [];
  for (const word of text.split(" ")) {
    const last = lines.length - 1;
    if (last >= 0 && (lines[last] + " " + word).length <= width) lines[last] += " " + word;
    else lines.push(word);
  }
  return lines.join("<br>");
}

const AXIS = { automargin: true, tickfont: { size: 12 }, nticks: 8, title: { font: { size: 13 }, standoff: 8 } };

// the common plotly layout: a wrapped title on top (its margin grows to fit it), axes whose margins fit their
// ticks and titles, the legend under the plot
export function plotLayout(title, xTitle, yTitle, extra = {}) {
  return {
    // above the plot area, pushing the top margin as far as its lines need (plotly's title.automargin)
    title: { text: wrapTitle(title), font: { size: 14 }, xref: "paper", x: 0, xanchor: "left", yref: "paper", y: 1,
      yanchor: "bottom", automargin: true, pad: { b: 12 } },
    xaxis: { ...AXIS, title: { ...AXIS.title, text: xTitle } },
    yaxis: { ...AXIS, title: { ...AXIS.title, text: yTitle } },
    margin: { t: 30, r: 20, b: 40, l: 50 },
    legend: { orientation: "h", x: 0, y: -0.22, yanchor: "top", font: { size: 12 } },
    font: { size: 12 },
    ...extra,
  };
}

// a detector map: y down, square pixels, the detector's outline; its size from the status (GET /api/status:
// sensor), else the axes fit the points
export function matrixLayout(title, sensor) {
  const layout = plotLayout(title, "x [px]", "y [px]");
  const size = sensor?.width_px && sensor?.height_px;
  const pad = size ? 0.03 * Math.max(sensor.width_px, sensor.height_px) : 0;
  layout.xaxis = { ...layout.xaxis, constrain: "domain", ...(size ? { range: [-pad, sensor.width_px + pad] } : {}) };
  layout.yaxis = { ...layout.yaxis, scaleanchor: "x", constrain: "domain",
    ...(size ? { range: [sensor.height_px + pad, -pad] } : { autorange: "reversed" }) };
  if (size) {
    // pixel centres: pixel (0, 0) is centred at (0, 0), so the detector spans −0.5 … width − 0.5
    layout.shapes = [{ type: "rect", xref: "x", yref: "y", x0: -0.5, y0: -0.5, x1: sensor.width_px - 0.5,
      y1: sensor.height_px - 0.5, line: { color: "#555", width: 1.5 }, fillcolor: "rgba(0,0,0,0.03)", layer: "below" }];
    layout.annotations = [{ xref: "x", yref: "y", x: sensor.width_px - 0.5, y: -0.5, xanchor: "right", yanchor: "bottom",
      text: `detector ${sensor.width_px} × ${sensor.height_px} px`, showarrow: false, font: { size: 11, color: "#555" } }];
  }
  return layout;
}
export const PLOT_CONFIG = { displaylogo: false, responsive: true };

// points the fit left out (GET /api/runs/{id}/fit: `excluded`, why): drawn apart, in one trace named so
export const LEFT_OUT_NAME = "left out of the fit";
export const LEFT_OUT_MARKER = { symbol: "x-thin-open", size: 11, color: "#d62728", line: { width: 2, color: "#d62728" } };

// split points into those the fit used and those it left out
export const splitExcluded = (points) => [points.filter((p) => !p.excluded), points.filter((p) => p.excluded)];

// a trace of left-out points at (x(p), y(p)), its hover text saying why; null when there is none (a plot's
// traces are filtered with .filter(Boolean))
export function leftOutTrace(points, x, y, extra = {}) {
  if (!points.length) return null;
  return {
    type: "scatter", mode: "markers", name: LEFT_OUT_NAME, x: points.map(x), y: points.map(y),
    text: points.map((p) => `${p.key ?? ""}<br>left out of the fit: ${p.excluded}`), marker: LEFT_OUT_MARKER,
    hovertemplate: "(%{x:.3f}, %{y:.3f})<br>%{text}<extra></extra>", showlegend: true, ...extra,
  };
}

// the latest frame (GET /api/frame.png) into `canvas`, its spot (GET /api/frame/spot) marked; what it found in
// words into `caption`. Returns false when there is no frame yet.
export async function drawLatestFrame(canvas, caption) {
  let image;
  try {
    const blob = await (await api("/api/frame.png", { raw: true })).blob();
    image = await createImageBitmap(blob);
  } catch (err) {
    if (err.status === 404) {
      caption.textContent = "no frame yet: open the shutter";
      return false;
    }
    throw err;
  }
  const ctx = canvas.getContext("2d");
  canvas.width = image.width;
  canvas.height = image.height;
  ctx.drawImage(image, 0, 0);
  let spot = null;
  try { spot = await api("/api/frame/spot"); } catch (_) { /* no spot */ }
  if (spot && spot.x_px !== null && spot.y_px !== null) {
    // pixel centres: pixel (0, 0) is centred at (0, 0), the canvas' pixel at (0.5, 0.5)
    const x = spot.x_px + 0.5, y = spot.y_px + 0.5;
    ctx.strokeStyle = "#ff3b30";
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.arc(x, y, 10, 0, 2 * Math.PI);
    ctx.moveTo(x - 18, y); ctx.lineTo(x - 4, y); ctx.moveTo(x + 4, y); ctx.lineTo(x + 18, y);
    ctx.moveTo(x, y - 18); ctx.lineTo(x, y - 4); ctx.moveTo(x, y + 4); ctx.lineTo(x, y + 18);
    ctx.stroke();
    caption.textContent = `spot at (${fmt(spot.x_px, 2)}, ${fmt(spot.y_px, 2)}) px, peak ${fmt(spot.peak_dn, 0)} DN`;
  } else {
    caption.textContent = spot?.error ? `no spot: ${spot.error}` : "no spot";
  }
  return true;
}

// a run that ended without making the bench safe (the engine's "unsafe" event; "ended unsafe: …" in its exit
// reason): the words, or null
export const unsafeText = (run) => {
  const reason = run?.exit_reason ?? "";
  const at = reason.indexOf("ended unsafe");
  return at >= 0 ? reason.slice(at) : null;
};

// what the run and results pages say first, in red, of run `id` that ended unsafe (`text`: "ended unsafe: …")
export const unsafeMessage = (id, text) => `RUN ${id ?? ""} ENDED UNSAFE: ${text.replace(/^ended unsafe:\s*/, "")}. `
  + "See to the bench (shutter, lamp, table) before the next run.";

// a crashed, aborted or failed run that no run resumed yet (`runs`: every run, GET /api/runs) can be resumed
const RESUMABLE = new Set(["aborted", "failed", "crashed"]);
export const resumable = (run, runs) => RESUMABLE.has(run.status) && !runs.some((r) => r.parent_run_id === run.id);

// -- the results views (results.js, results-qd.js) -------------------------------------------------------------
// why a run has no calibration, in words
export const noCalibrationReason = (run) => `the run ${run.status === "completed" ? "has none stored"
  : `was ${run.status} before its fit`}`;

// the calibration <select>: one option per calibration record (`method`, `chosen`), `selected` the one shown
export function methodOptions(select, records, selected) {
  select.replaceChildren(...records.map((c) => el("option", { value: c.method, selected: c === selected },
    c.method + (c.chosen ? " (chosen)" : ""))));
}

// a box of lines (a fit's warnings): its <ul> filled, the box hidden when there are none
export function listBox(selector, lines) {
  $(selector).hidden = !lines.length;
  $(`${selector} ul`).replaceChildren(...lines.map((line) => el("li", {}, line)));
}

// -- quadrant currents (the qd family: the live run page and the results view) -----------------------------------
export const QUADRANTS = ["Q1", "Q2", "Q3", "Q4"];
export const QUADRANT_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728"];

// each quadrant's current at each point and their sum, on a log axis: `x` the points' numbers, `currents[k]`
// quadrant k+1's currents [A], `sum` theirs, `text` each point's hover line; `extra` goes into the layout
export function currentsPlot(id, title, x, currents, sum, text, extra = {}) {
  const layout = plotLayout(title, "point", "current [A], dark current included", extra);
  layout.yaxis = { ...layout.yaxis, type: "log", exponentformat: "SI" };
  Plotly.react(id, [...QUADRANTS.map((name, k) => ({
    type: "scatter", mode: "lines+markers", name, x, y: currents[k], text,
    marker: { size: 3, color: QUADRANT_COLOURS[k] }, line: { width: 1, color: QUADRANT_COLOURS[k] },
    hovertemplate: `${name} %{y:.4s}A<br>%{text}<extra></extra>`,
  })), { type: "scatter", mode: "lines", name: "sum", x, y: sum, text, line: { width: 1.5, color: "#333", dash: "dot" },
    hovertemplate: "sum %{y:.4s}A<br>%{text}<extra></extra>" }], layout, PLOT_CONFIG);
}
