// Live run: progress, ETA and the spot map from the server-sent events; pause / resume / abort.
/* global Plotly */
import {
  $, api, duration, el, getToken, initTokenForm, matrixLayout, PLOT_CONFIG, query, report, say, stopsEarly,
} from "./common.js";

const spots = { x: [], y: [], zenith: [], text: [] };
const seenKeys = new Set(); // the points of the run on the map, so a late catch-up adds each once
let runId = null;
// what the progress line shows: the engine's figures, the run's plan (its record) and how the run ended
const shown = { index: 0, total: null, eta_s: null, plan: null, ended: null };
const TERMINAL = new Set(["completed", "aborted", "failed", "crashed"]);
let source = null;
let drawPending = false;
let detector = null; // the detector's size (width_px, height_px), from the status

function draw() {
  if (drawPending) return;
  drawPending = true;
  requestAnimationFrame(() => {
    drawPending = false;
    Plotly.react("spot-plot", [{
      type: "scatter",
      mode: "markers", name: "spots", x: spots.x, y: spots.y, text: spots.text,
      marker: { size: 5, color: spots.zenith, colorscale: "Viridis", colorbar: { title: { text: "zenith stage [°]" } } },
      hovertemplate: "(%{x:.2f}, %{y:.2f}) px<br>%{text}<extra></extra>",
    }], {
      ...matrixLayout(runId ? `run ${runId}` : "spots", detector), showlegend: false,
      datarevision: `${runId}:${spots.x.length}`, // the arrays grow in place: react redraws only on a new revision
    }, PLOT_CONFIG);
  });
}

function resetSpots() {
  for (const k of Object.keys(spots)) spots[k] = [];
  seenKeys.clear();
  draw();
}

function addSpot(x, y, zenith, label) {
  if (x === null || y === null || x === undefined || y === undefined) return;
  spots.x.push(x); spots.y.push(y); spots.zenith.push(zenith); spots.text.push(label);
}

function progress(index, total, eta_s) {
  Object.assign(shown, { index, total, eta_s });
  renderProgress();
}

// a plan with a stopping rule (physical) counts its cap as its total: the total and the ETA are upper bounds,
// and a run that stopped before its cap is complete all the same
function renderProgress() {
  const { index, total, eta_s, ended } = shown;
  const bound = stopsEarly(shown.plan) ? "at most " : "";
  const bar = $("#progress");
  bar.max = total || 1;
  bar.value = index || 0;
  if (bound && ended === "completed") bar.max = Math.max(bar.value, 1);
  $("#progress-text").textContent = `${index ?? 0} / ${bound}${total ?? "–"}`;
  $("#eta").textContent = ended || eta_s === null || eta_s === undefined ? "–" : `${bound}${duration(eta_s)}`;
  $("#bound-note").hidden = !bound;
}

// the run's record says its plan (and whether it has ended); the events do not
async function readRun(id) {
  let run;
  try { run = await api(`/api/runs/${id}`); } catch (err) { report(err); return; }
  if (runId !== id) return;
  shown.plan = run.plan_name;
  if (TERMINAL.has(run.status)) shown.ended = run.status;
  $("#run-title").textContent = `${id} · sensor ${run.sensor_id} · plan ${run.plan_name}`;
  renderProgress();
}

function log(kind, text, when = new Date()) {
  const list = $("#log");
  const time = when.toLocaleTimeString();
  list.prepend(el("li", { class: kind }, `${time} ${kind}: ${text}`));
  while (list.children.length > 300) list.lastChild.remove();
}

function setRun(id, sensor) {
  runId = id;
  Object.assign(shown, { plan: null, ended: null });
  $("#run-title").textContent = id ? `${id}${sensor ? ` · sensor ${sensor}` : ""}` : "– waiting for events";
  $("#result-link").replaceChildren();
  if (id) readRun(id);
}

function finishedLink(id) {
  if (id) $("#result-link").replaceChildren(el("a", { href: `/results?run=${id}` }, `results of run ${id}`));
}

// what the bench is doing now, and the points already recorded (joining a run midway)
async function catchUp() {
  let status;
  try { status = await api("/api/status"); } catch (err) { report(err); return; }
  const e = status.engine;
  if (status.sensor?.width_px && !detector) { detector = status.sensor; draw(); }
  $("#engine-state").textContent = e.state;
  showMount(status.mount);
  offerResume(e.state);
  progress(e.index, e.total, e.eta_s);
  if (e.run_id && e.run_id !== runId) {
    const id = e.run_id;
    setRun(id, e.sensor_id);
    resetSpots();
    let points, runLog;
    try {
      [points, runLog] = await Promise.all([api(`/api/runs/${id}/points`), api(`/api/runs/${id}/log`)]);
    } catch (err) { report(err); return; }
    if (runId !== id) return; // another run started while these were on their way: its events own the page
    // points that arrived as events meanwhile are on the map already
    for (const p of points.data) if (!seenKeys.has(p.key)) addSpot(p.x_px, p.y_px, p.zenith_stage_deg, p.key);
    draw();
    // what happened before the page joined, below what it saw live (the list is newest first)
    const list = $("#log");
    const live = [...list.children];
    list.replaceChildren();
    for (const entry of runLog.data) log(entry.kind, entry.message, new Date(entry.t_utc));
    list.prepend(...live);
    if (e.state === "idle") finishedLink(id);
  } else if (e.run_id && e.state === "idle" && !shown.ended) {
    readRun(e.run_id); // it ended while the stream was away: its record says how
  }
}

const HANDLERS = {
  queued: (d) => log("queued", `campaign ${d.campaign_id}: ${d.upper_bound ? "at most " : ""}${d.points} points per sensor`),
  "run-started": (d) => { showMount(null); setRun(d.run_id, d.sensor_id); resetSpots(); progress(0, null, null); log("run-started", `run ${d.run_id} on ${d.sensor_id}`); },
  state: (d) => { $("#engine-state").textContent = d.state; offerResume(d.state); log("state", `${d.previous} → ${d.state}${d.reason ? ` (${d.reason})` : ""}`); },
  point: (d) => {
    if (d.run_id && d.run_id !== runId) setRun(d.run_id);
    progress(d.index, d.total, d.eta_s);
    seenKeys.add(d.key);
    for (const [x, y] of d.spots || []) addSpot(x, y, d.zenith_stage_deg, d.key);
    draw();
  },
  log: (d) => log("log", d.message),
  warning: (d) => log("warning", d.message ?? JSON.stringify(d)),
  error: (d) => log("error", d.message ?? JSON.stringify(d)),
  finished: (d) => {
    log("finished", `${d.status}${d.reason ? `: ${d.reason}` : ""}`);
    finishedLink(d.run_id ?? runId);
    if (!d.run_id || d.run_id === runId) { shown.ended = d.status; renderProgress(); }
  },
  "campaign-finished": (d) => {
    log("campaign-finished", `campaign ${d.campaign_id}${d.status ? `: ${d.status}` : ""}${d.reason ? ` (${d.reason})` : ""}`);
    showMount(null);
    offerResume("idle");
  },
  mount: (d) => { showMount(d); log("mount", `waiting for the operator: ${d.prompt}`); },
  "mount-answered": (d) => {
    showMount(null);
    log("mount", `sensor ${d.sensor_id} ${d.confirmed ? "confirmed mounted" : "not confirmed: the campaign stops"}`);
  },
  "resume-queued": (d) => log("queued", d.run_id ? `resumption of run ${d.run_id}` : `the rest of campaign ${d.campaign_id}`),
};

// -- a fleet's next sensor: the bench waits until the operator has mounted it and says so ------------------
let awaitedMount = null;

function showMount(mount) {
  awaitedMount = mount || null;
  $("#mount-prompt").hidden = !awaitedMount;
  if (!awaitedMount) return;
  $("#mount-text").textContent = mount.prompt[0].toUpperCase() + mount.prompt.slice(1);
  $("#resume-box").hidden = true;
}

async function confirmMount() {
  if (!awaitedMount) return;
  const body = { sensor_id: awaitedMount.sensor_id }; // named, so a stale page cannot confirm another sensor
  try {
    say((await api("/api/run/mount", { method: "POST", body })).message);
    showMount(null);
  } catch (err) { report(err); }
}

// -- a run that ended without completing (?run=N, else the newest): offered for resumption -----------------
const RESUMABLE = new Set(["aborted", "failed", "crashed"]);
const runParam = /^\d+$/.test(query("run") ?? "") ? Number(query("run")) : null;

async function offerResume(state) {
  if (state !== "idle" || awaitedMount) { $("#resume-box").hidden = true; return; }
  let runs;
  try { runs = (await api("/api/runs")).data; } catch (err) { return; } // the status read says why already
  const id = runParam ?? runs.at(-1)?.id;
  const run = runs.find((r) => r.id === id);
  const offer = Boolean(run) && RESUMABLE.has(run.status) && !runs.some((r) => r.parent_run_id === id);
  $("#resume-box").hidden = !offer || Boolean(awaitedMount);
  if (!offer) return;
  $("#resume-text").textContent = `Run ${id} (sensor ${run.sensor_id}) ${run.status}`
    + `${run.exit_reason ? `: ${run.exit_reason}` : ""}. It recorded ${run.n_points_recorded} of `
    + `${run.n_points_planned ?? "–"} points; resuming measures only the missing ones, then the rest of its campaign.`;
  $("#resume-run").dataset.run = String(id);
}

async function resumeRun() {
  const id = $("#resume-run").dataset.run;
  try {
    say((await api(`/api/runs/${id}/resume`, { method: "POST" })).message);
    $("#resume-box").hidden = true;
  } catch (err) { report(err); }
}

function connect() {
  if (source) source.close();
  const token = getToken();
  // EventSource cannot send an Authorization header: the token goes as ?token=
  source = new EventSource(token ? `/api/events?token=${encodeURIComponent(token)}` : "/api/events");
  source.onopen = () => { $("#stream-state").textContent = "connected"; catchUp(); };
  source.onerror = () => {
    const closed = source.readyState === EventSource.CLOSED;
    $("#stream-state").textContent = closed ? "refused (check the token)" : "reconnecting …";
    if (closed) say("the event stream was refused: paste the token", true);
  };
  for (const [kind, handle] of Object.entries(HANDLERS)) {
    source.addEventListener(kind, (message) => {
      if (message.data === undefined) return; // the connection's own "error" (onerror says it), not an event
      try { handle(JSON.parse(message.data)); } catch (err) { console.error(kind, err); }
    });
  }
}

async function control(action) {
  try { say((await api(`/api/run/${action}`, { method: "POST" })).message); } catch (err) { report(err); }
}

initTokenForm(connect);
$("#pause").onclick = () => control("pause");
$("#mount-confirm").onclick = confirmMount;
$("#resume-run").onclick = resumeRun;
$("#resume").onclick = () => control("resume");
$("#abort").onclick = () => { if (confirm("Abort the run? Its recorded points stay.")) control("abort"); };
draw();
catchUp();
connect();
setInterval(() => { if (!document.hidden) catchUp(); }, 10000);
