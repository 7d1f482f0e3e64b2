// Shared by every page: the token (localStorage), fetch with Authorization: Bearer, small DOM helpers.
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

// fetch an API path with the token; JSON bodies in and out; throws ApiError on a non-2xx answer
export async function api(path, { method = "GET", body, raw = false } = {}) {
  const headers = {};
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const response = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  if (!response.ok) {
    let detail = response.statusText;
    try { detail = (await response.json()).detail; } catch (_) { /* not JSON */ }
    if (response.status === 401) showTokenForm(true);
    throw new ApiError(response.status, detail);
  }
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

export function duration(s) {
  if (s === null || s === undefined) return "–";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return h ? `${h} h ${m} min` : m ? `${m} min ${sec} s` : `${sec} s`;
}

// a message line in #message (errors in red)
export function say(text, error = false) {
  const box = $("#message");
  if (!box) return;
  box.textContent = text;
  box.className = error ? "message error" : "message";
}

export const report = (err) => say(err instanceof ApiError ? `Refused: ${err.message}` : String(err), true);

// the token form in the header of every page
function showTokenForm(open) {
  const details = $("#token-box");
  if (details) details.open = open;
}

export function initTokenForm(onChange) {
  const form = $("#token-form");
  if (!form) return;
  const input = form.querySelector("input");
  const state = $("#token-state");
  const refresh = () => { state.textContent = getToken() ? "token set" : "no token"; };
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    setToken(input.value);
    input.value = "";
    refresh();
    showTokenForm(false);
    if (onChange) onChange();
  });
  form.querySelector("[data-forget]").addEventListener("click", () => { setToken(""); refresh(); });
  refresh();
  if (!getToken()) showTokenForm(true);
}

// plans with a stopping rule (bench/plans.py physical_plan): a run's planned points are its cap, so its point
// total, progress and ETA are upper bounds (preflight says so of a campaign: the dry run's upper_bound)
const STOPPING_PLANS = new Set(["physical"]);
export const stopsEarly = (planName) => STOPPING_PLANS.has(planName);

export const query = (name) => new URLSearchParams(location.search).get(name);

// the common plotly layout: title on top, legend under the plot (clear of the x-axis title)
export function plotLayout(title, xTitle, yTitle, extra = {}) {
  return {
    title: { text: title },
    xaxis: { title: { text: xTitle } },
    yaxis: { title: { text: yTitle } },
    margin: { t: 40, r: 10, b: 50, l: 60 },
    legend: { orientation: "h", x: 0, y: -0.18, yanchor: "top" },
    ...extra,
  };
}

// a detector map: y down, square pixels; the detector's size from the status (GET /api/status: sensor),
// else the axes fit the points
export function matrixLayout(title, sensor) {
  const layout = plotLayout(title, "x [px]", "y [px]");
  const size = sensor?.width_px && sensor?.height_px;
  layout.xaxis = { ...layout.xaxis, constrain: "domain", ...(size ? { range: [0, sensor.width_px] } : {}) };
  layout.yaxis = { ...layout.yaxis, scaleanchor: "x", constrain: "domain",
    ...(size ? { range: [sensor.height_px, 0] } : { autorange: "reversed" }) };
  return layout;
}
export const PLOT_CONFIG = { displaylogo: false, responsive: true };
