// Live run: progress, ETA, each point as it lands (stage, angles, exposure, its spots, the latest frame), the spot
// map and a log line per point and per stage result, from the server-sent events; pause / resume / abort, each
// offered only when the engine's state allows it; a run that ended unsafe, said first.
// What a point shows is what its readings are (the `point` event's fields, the family's summary): spots of a frame
// (cmos), or quadrant currents (qd: the latest currents and a plot of every point's, instead of the frame and
// the spot map; a horizon sensor: each cone's edge phases and Earth chord, and a plot of every point's chords).
// The page starts with its bench's kind (<body data-frames>) and follows the events.
/* global Plotly */
import {
  $, amps, api, currentsPlot, drawLatestFrame, duration, el, fmt, getToken, initTokenForm, LEFT_OUT_MARKER, matrixLayout,
  PLOT_CONFIG, plotLayout, QUADRANTS, query, report, resumable, say, stopsEarly, unsafeMessage, unsafeText,
} from "./common.js";

const EDGE = "clipped at the detector's edge: left out of the fit";
const spots = { x: [], y: [], zenith: [], text: [] };
const clipped = { x: [], y: [], text: [] };
const seenKeys = new Set(); // the points of the run on the map, so a late catch-up adds each once
let runId = null;
// what the progress line shows: the engine's figures, the run's plan (its record) and how the run ended
const shown = { index: 0, total: null, eta_s: null, plan: null, ended: null };
const TERMINAL = new Set(["completed", "aborted", "failed", "crashed"]);
let source = null;
let drawPending = false;
let detector = null; // the detector's size (width_px, height_px), from the status
let engineState = null;

// -- what a reading is: "spots" (a frame's) or "currents" (a photodiode's) ----------------------------------------
let reading = document.body.dataset.frames === "false" ? "currents" : "spots";
const currents = { index: [], q: [[], [], [], []], sum: [], text: [] };

function showReading(kind) {
  if (kind === reading && document.querySelector(`[data-reading="${kind}"]:not([hidden])`)) return;
  reading = kind;
  for (const node of document.querySelectorAll("[data-reading]")) node.hidden = node.dataset.reading !== kind;
  draw();
}

function addCurrents(index, values, label) {
  if (!Array.isArray(values)) return;
  currents.index.push(index);
  values.forEach((v, k) => currents.q[k].push(v));
  currents.sum.push(values.reduce((a, b) => a + b, 0));
  currents.text.push(label);
}

// a horizon sensor's point (bench/families/horizon.py summary): each cone's mean edge phases [°] and its Earth chord,
// the rising edge (space → Earth) to the falling one (Earth → space), and the disc radius the source reported
const horizon = { index: [], chord: [[], []], text: [] };
const isHorizon = (p) => Boolean(p) && "phase_out_deg" in p;
const chordOf = (p, k) => {
  const out = p.phase_out_deg?.[k], into = p.phase_in_deg?.[k];
  return out === null || out === undefined || into === null || into === undefined ? null : (((out - into) % 360) + 360) % 360;
};
const phasesText = (p) => (p.phase_out_deg ? `${[0, 1].map((k) => `cone ${k + 1} in ${fmt(p.phase_in_deg[k], 2)}° out `
  + `${fmt(p.phase_out_deg[k], 2)}° chord ${fmt(chordOf(p, k), 2)}°`).join("; ")}; disc ${fmt(p.disc_radius_deg, 3)}°`
  : "no edges");

function addChords(index, p, label) {
  horizon.index.push(index);
  [0, 1].forEach((k) => horizon.chord[k].push(chordOf(p, k)));
  horizon.text.push(label);
}

// the page's currents parts, named for a horizon sensor (its readings are phases, not currents)
function nameForHorizon() {
  const dt = document.querySelector("dt[data-reading='currents']");
  if (dt) dt.textContent = "Phases";
  const heading = $("#currents-section h2");
  if (heading) heading.textContent = "Each cone's Earth chord at each point";
  const body = $("#n-body").previousElementSibling;  // the source is the Earth simulator's disc, not the Sun
  if (body) body.textContent = "Disc centre in the body frame";
}

function drawChords() {
  Plotly.react("currents-plot", [0, 1].map((k) => ({
    type: "scatter", mode: "lines+markers", name: `cone ${k + 1}`, x: horizon.index, y: horizon.chord[k],
    text: horizon.text, marker: { size: 4 }, line: { width: 1 },
    hovertemplate: `cone ${k + 1} chord %{y:.3f}°<br>%{text}<extra></extra>`,
  })), { ...plotLayout(runId ? `Earth chords of run ${runId}` : "Earth chords", "point", "chord (rising → falling edge) [°]"),
    datarevision: `${runId}:${horizon.index.length}` }, PLOT_CONFIG);
}

const currentsText = (values) => (Array.isArray(values)
  ? `${values.map((v, k) => `${QUADRANTS[k]} ${amps(v)}`).join(", ")}; sum ${amps(values.reduce((a, b) => a + b, 0))}`
  : "no reading");

function drawCurrents() {
  currentsPlot("currents-plot", runId ? `quadrant currents of run ${runId}` : "quadrant currents", currents.index,
    currents.q, currents.sum, currents.text, { datarevision: `${runId}:${currents.index.length}` });
}

function draw() {
  if (drawPending) return;
  drawPending = true;
  requestAnimationFrame(() => {
    drawPending = false;
    if (reading === "currents") {
      if (horizon.index.length) drawChords();
      else drawCurrents();
      return;
    }
    Plotly.react("spot-plot", [{
      type: "scatter",
      mode: "markers", name: "spots", x: spots.x, y: spots.y, text: spots.text,
      marker: { size: 5, color: spots.zenith, colorscale: "Viridis", colorbar: { title: { text: "zenith stage [°]" } } },
      hovertemplate: "(%{x:.2f}, %{y:.2f}) px<br>%{text}<extra></extra>",
    }, {
      type: "scatter", mode: "markers", name: EDGE, x: clipped.x, y: clipped.y, text: clipped.text,
      marker: LEFT_OUT_MARKER, hovertemplate: "(%{x:.2f}, %{y:.2f}) px<br>%{text}<extra></extra>",
    }], {
      ...matrixLayout(runId ? `spots of run ${runId}` : "spots", detector),
      showlegend: clipped.x.length > 0,
      datarevision: `${runId}:${spots.x.length}:${clipped.x.length}`, // the arrays grow in place: a new revision redraws
    }, PLOT_CONFIG);
  });
}

function resetSpots() {
  for (const k of Object.keys(spots)) spots[k] = [];
  for (const k of Object.keys(clipped)) clipped[k] = [];
  Object.assign(currents, { index: [], q: [[], [], [], []], sum: [], text: [] });
  Object.assign(horizon, { index: [], chord: [[], []], text: [] });
  seenKeys.clear();
  draw();
}

function addSpot(x, y, zenith, label, edge = false) {
  if (x === null || y === null || x === undefined || y === undefined) return;
  if (edge) {
    clipped.x.push(x); clipped.y.push(y); clipped.text.push(`${label}<br>${EDGE}`);
  } else {
    spots.x.push(x); spots.y.push(y); spots.zenith.push(zenith); spots.text.push(label);
  }
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

// -- the buttons follow the engine's state ------------------------------------------------------------------
const ABORTABLE = new Set(["running", "pausing", "paused", "suspended"]);

function followState(state) {
  engineState = state;
  $("#engine-state").textContent = state ?? "–";
  $("#pause").disabled = state !== "running";
  $("#resume").disabled = !(state === "paused" || state === "pausing");
  $("#abort").disabled = !(ABORTABLE.has(state) || awaitedMount);
}

// -- a run that ended without making the bench safe: said first, in red ----------------------------------------
function showUnsafe(id, text) {
  const box = $("#unsafe-box");
  box.hidden = !text;
  box.textContent = text ? unsafeMessage(id, text) : "";
}

// the run's record says its plan (and whether it has ended, and how); the events do not
async function readRun(id) {
  let run;
  try { run = await api(`/api/runs/${id}`); } catch (err) { report(err); return null; }
  if (runId !== id) return run;
  shown.plan = run.plan_name;
  if (TERMINAL.has(run.status)) shown.ended = run.status;
  const ended = TERMINAL.has(run.status) && engineState === "idle" ? ` · ${run.status}` : "";
  $("#run-title").textContent = `${id} · sensor ${run.sensor_id} (${run.family ?? "cmos"}) · plan ${run.plan_name}${ended}`;
  if (unsafeText(run)) showUnsafe(id, unsafeText(run));
  renderProgress();
  return run;
}

function log(kind, text, when = new Date()) {
  const list = $("#log");
  const time = when.toLocaleTimeString();
  list.prepend(el("li", { class: kind }, `${time} ${kind}: ${text}`));
  while (list.children.length > 500) list.lastChild.remove();
}

// a stage result is logged once, whether it came as an event or with the history read on joining
const loggedResults = new Set();

function logResult(text, when = new Date()) {
  if (loggedResults.has(text)) return;
  loggedResults.add(text);
  log("result", text, when);
}

function setRun(id, sensor) {
  runId = id;
  loggedResults.clear();
  Object.assign(shown, { plan: null, ended: null });
  $("#run-title").textContent = id ? `${id}${sensor ? ` · sensor ${sensor}` : ""}` : "– waiting for events";
  $("#result-link").replaceChildren();
  showUnsafe(null, null);
  if (id) readRun(id);
}

// a page that joined midway may have missed the points between its snapshot and the stream's first event: once
// the run has ended, the catalogue's count is the one shown
async function settleCount(id) {
  if (!id) return;
  let run;
  try { run = await api(`/api/runs/${id}`); } catch (_) { return; } // the count shown stays
  if (id === runId && Number.isInteger(run.n_points_recorded)) { shown.index = run.n_points_recorded; renderProgress(); }
}

function finishedLink(id) {
  if (id) $("#result-link").replaceChildren(el("a", { href: `/results?run=${id}` }, `results of run ${id}`));
}

// -- each point as it lands -----------------------------------------------------------------------------------
const spotText = (x, y) => `(${fmt(x, 2)}, ${fmt(y, 2)}) px`;

// a CSS head's point (bench/families/css.py summary): its signals by channel; the three brightest visible
// photodiodes say which faces the source lights
const signalsText = (signals) => {
  if (!signals) return "no reading";
  const lit = Object.entries(signals).filter(([name]) => name.endsWith("_vis")).sort((a, b) => b[1] - a[1]);
  return lit.slice(0, 3).map(([name, v]) => `${name} ${amps(v)}`).join(", ");
};

function pointLine(p, edgeFlags) {
  const where = `table azimuth ${fmt(p.azimuth_deg, 1)}°, zenith stage ${fmt(p.zenith_stage_deg, 2)}°`;
  if ("currents_a" in p) return `${p.key} (${p.stage}): ${where} → ${currentsText(p.currents_a)}`;
  if (isHorizon(p)) return `${p.key} (${p.stage}): ${where} → ${phasesText(p)}`;
  if ("signals" in p) return `${p.key} (${p.stage}): ${where} → ${signalsText(p.signals)}`;
  const found = p.spots.length ? p.spots.map(([x, y], i) => spotText(x, y) + (edgeFlags[i] ? " clipped at the edge" : ""))
    .join(", ") : "no spot";
  return `${p.key} (${p.stage}): ${where} → ${found}`;
}

function showPoint(d) {
  const edge = d.spots_clipped || [];
  $("#n-point").textContent = `${d.key} (${d.index} / ${stopsEarly(shown.plan) ? "at most " : ""}${d.total ?? "–"})`;
  $("#n-stage").textContent = d.stage;
  $("#n-table").textContent = `azimuth ${fmt(d.azimuth_deg, 3)}°, zenith stage ${fmt(d.zenith_stage_deg, 3)}°`;
  $("#n-body").textContent = d.zenith_deg === undefined ? "–"
    : `zenith ${fmt(d.zenith_deg, 3)}°, azimuth ${fmt(d.azimuth_body_deg, 3)}°`;
  if ("currents_a" in d || "signals" in d || isHorizon(d)) {
    $("#n-currents").textContent = "signals" in d ? signalsText(d.signals)
      : isHorizon(d) ? phasesText(d) : currentsText(d.currents_a);
    $("#n-temperature").textContent = d.temperature_c === null || d.temperature_c === undefined ? "–"
      : `${fmt(d.temperature_c, 2)} °C`;
    return;
  }
  $("#n-exposure").textContent = d.exposure_ms === null || d.exposure_ms === undefined ? "–" : `${fmt(d.exposure_ms, 3)} ms`;
  const spotsText = (d.spots || []).map(([x, y], i) => spotText(x, y) + (edge[i] ? ` (${EDGE})` : ""));
  $("#n-spots").textContent = spotsText.length
    ? `${spotsText.length} of ${d.n_frames ?? spotsText.length} frames: ${spotsText.join("; ")}` : "no spot found";
  refreshFrame();
}

// the latest frame, at most one fetch at a time (points may land faster than frames load)
let frameBusy = false, frameAgain = false;

async function refreshFrame() {
  if (reading !== "spots") return;  // a photodiode has no frame
  if (frameBusy) { frameAgain = true; return; }
  frameBusy = true;
  try { await drawLatestFrame($("#frame"), $("#frame-text")); } catch (_) { /* the status read reports a refusal */ }
  frameBusy = false;
  if (frameAgain) { frameAgain = false; setTimeout(refreshFrame, 300); }
}

// a stage's result (the plan's records: bench/plans.py), in words
function recordText(key, v) {
  if (key === "exposure_ms") return `exposure ${fmt(v, 3)} ms (auto-exposure)`;
  if (key === "centre_px") return v ? `centre (normal incidence) at ${spotText(v[0], v[1])}` : "centre: none found";
  if (key === "tilt_stage") {
    return v ? `tilt stage: mean offset ${fmt(v.mean_offset_deg, 3)}°, tilt x ${fmt(v.tilt_x_deg, 3)}°, `
      + `tilt y ${fmt(v.tilt_y_deg, 3)}°` : "tilt stage: too few azimuths to fit a tilt";
  }
  if (key === "physical_design") {
    return `design: ${v.fit_directions_deg?.length ?? "–"} fit and ${v.check_directions_deg?.length ?? "–"} check `
      + `directions in ${v.batches?.length ?? "–"} batch(es)`;
  }
  if (key.startsWith("physical_batch_")) {
    return `batch ${key.slice("physical_batch_".length)}: ${v.stop ? "targets met" : "go on"}, check RMS `
      + `${fmt(v.check_rms_deg, 4)}°`;
  }
  if (key === "physical_stop") return `stopped: ${v.reason}`;
  const text = JSON.stringify(v);
  return `${key} = ${text.length > 120 ? `${text.slice(0, 120)} …` : text}`;
}

// the run whose history (points, log, stage results recorded before the page joined) is on the page: a run seen
// from its "run-started" event has none to read
let historyOf = null;

// the stage results recorded before the page joined, as log entries: each after the last point of its stage
// (the exposure before the first point; the physical plan's own log lines already say its batches)
const STAGE_OF = { centre_px: "centre", tilt_stage: "tilt" };

function recordedResults(values, points) {
  const times = points.map((p) => [new Date(p.completed_utc), p.stage]);
  const first = times.length ? new Date(times[0][0] - 1) : new Date();
  const last = (stage) => times.filter(([, s]) => s === stage).map(([t]) => t).at(-1);
  return Object.entries(values).filter(([key]) => !key.startsWith("physical_"))
    .map(([key, value]) => [key === "exposure_ms" ? first : last(STAGE_OF[key]) ?? times.at(-1)?.[0] ?? first, "result",
      recordText(key, value)]);
}

// what the bench is doing now, and the points already recorded (joining a run midway)
async function catchUp() {
  let status;
  try { status = await api("/api/status"); } catch (err) { report(err); return; }
  const e = status.engine;
  if (status.sensor?.width_px && !detector) { detector = status.sensor; draw(); }
  showMount(status.mount);
  followState(e.state);
  offerResume(e.state);
  progress(e.index, e.total, e.eta_s);
  if (e.ended_unsafe && (!runId || e.run_id === runId)) showUnsafe(e.run_id, e.ended_unsafe);
  if (e.run_id && e.run_id !== historyOf) {
    const id = e.run_id;
    if (runId !== id) { // a point event may have named the run first: its spots stay
      setRun(id, e.sensor_id);
      resetSpots();
    }
    historyOf = id;
    if (e.ended_unsafe) showUnsafe(id, e.ended_unsafe);
    let points, runLog, values;
    try {
      [points, runLog, values] = await Promise.all([api(`/api/runs/${id}/points`), api(`/api/runs/${id}/log`),
        api(`/api/runs/${id}/values`)]);
    } catch (err) { report(err); return; }
    if (runId !== id) return; // another run started while these were on their way: its events own the page
    // points that arrived as events meanwhile are on the map already
    const earlier = points.data.filter((p) => !seenKeys.has(p.key));
    if (earlier.some((p) => p.summary && "currents_a" in p.summary)) showReading("currents");
    if (earlier.some((p) => isHorizon(p.summary))) { nameForHorizon(); showReading("currents"); }
    points.data.forEach((p, i) => {
      if (seenKeys.has(p.key)) return;
      if (p.summary && "currents_a" in p.summary) addCurrents(i + 1, p.summary.currents_a, `${p.key} (${p.stage})`);
      else if (isHorizon(p.summary)) addChords(i + 1, p.summary, `${p.key} (${p.stage})`);
      else if (!(p.summary && "signals" in p.summary)) addSpot(p.x_px, p.y_px, p.zenith_stage_deg, p.key, Boolean(p.excluded));
    });
    draw();
    // a photodiode's latest currents, until the next point's event says newer ones
    const last = points.data.at(-1);
    if (last?.summary && ("currents_a" in last.summary || isHorizon(last.summary)) && !seenKeys.size) {
      showPoint({ ...last, ...last.summary, index: points.data.length, total: e.total });
    }
    // what happened before the page joined, below what it saw live (the list is newest first)
    const list = $("#log");
    const live = [...list.children];
    list.replaceChildren();
    const entries = [...runLog.data.map((entry) => [new Date(entry.t_utc), entry.kind, entry.message]),
      ...earlier.map((p) => [new Date(p.completed_utc), "point", `${p.key} (${p.stage}): table azimuth `
        + `${fmt(p.azimuth_deg, 1)}°, zenith stage ${fmt(p.zenith_stage_deg, 2)}° → `
        + (p.summary && "currents_a" in p.summary ? currentsText(p.summary.currents_a)
          : isHorizon(p.summary) ? phasesText(p.summary)
          : p.summary && "signals" in p.summary ? signalsText(p.summary.signals)
            : p.x_px === null ? "no spot" : spotText(p.x_px, p.y_px) + (p.excluded ? ` (${p.excluded})` : ""))])];
    entries.push(...recordedResults(values.values, points.data));
    entries.sort((a, b) => a[0] - b[0]);
    for (const [when, kind, message] of entries) {
      if (kind === "result") logResult(message, when);
      else log(kind, message, when);
    }
    list.prepend(...live);
    refreshFrame();
    if (e.state === "idle") finishedLink(id);
  } else if (e.run_id && e.state === "idle" && !shown.ended) {
    readRun(e.run_id); // it ended while the stream was away: its record says how
  } else if (!e.run_id && !runId) {
    showLastRun(); // none since the server started (a restart): the last one recorded
  }
}

// after a restart the engine knows no run: the page links the last one (or ?run=N), and says how it ended
async function showLastRun() {
  let runs;
  try { runs = (await api("/api/runs")).data; } catch (_) { return; }
  const run = runParam ? runs.find((r) => r.id === runParam) : runs.at(-1);
  if (!run || runId) return;
  Object.assign(shown, { plan: run.plan_name, ended: run.status });
  progress(run.n_points_recorded, run.n_points_planned, null);
  $("#run-title").textContent = `none running · last run ${run.id} · sensor ${run.sensor_id} (${run.family ?? "cmos"}) · `
    + `plan ${run.plan_name} · ${run.status}`;
  finishedLink(run.id);
  if (unsafeText(run)) showUnsafe(run.id, unsafeText(run));
}

const HANDLERS = {
  queued: (d) => log("queued", `campaign ${d.campaign_id}: ${d.upper_bound ? "at most " : ""}${d.points} points per sensor`),
  "run-started": (d) => {
    showMount(null); setRun(d.run_id, d.sensor_id); resetSpots(); progress(0, null, null);
    historyOf = d.run_id;
    log("run-started", `run ${d.run_id} on ${d.sensor_id}`);
  },
  state: (d) => { followState(d.state); offerResume(d.state); log("state", `${d.previous} → ${d.state}${d.reason ? ` (${d.reason})` : ""}`); },
  point: (d) => {
    if (d.run_id && d.run_id !== runId) setRun(d.run_id);
    progress(d.index, d.total, d.eta_s);
    seenKeys.add(d.key);
    const edge = d.spots_clipped || [];
    if ("currents_a" in d) {
      showReading("currents");
      addCurrents(d.index, d.currents_a, `${d.key} (${d.stage})`);
    } else if (isHorizon(d)) {
      nameForHorizon();
      showReading("currents");
      addChords(d.index, d, `${d.key} (${d.stage})`);
    } else {
      if ("spots" in d) showReading("spots");
      (d.spots || []).forEach(([x, y], i) => addSpot(x, y, d.zenith_stage_deg, d.key, Boolean(edge[i])));
    }
    draw();
    showPoint(d);
    log("point", `${d.index}/${d.total ?? "–"} ${pointLine("currents_a" in d || isHorizon(d) ? d : { ...d, spots: d.spots || [] }, edge)}`);
  },
  record: (d) => logResult(recordText(d.key, d.value)),
  log: (d) => log("log", d.message),
  warning: (d) => log("warning", d.message ?? JSON.stringify(d)),
  error: (d) => log("error", d.message ?? JSON.stringify(d)),
  unsafe: (d) => { showUnsafe(d.run_id ?? runId, d.message); log("error", d.message); },
  finished: (d) => {
    log("finished", `${d.status}${d.reason ? `: ${d.reason}` : ""}`);
    finishedLink(d.run_id ?? runId);
    if (!d.run_id || d.run_id === runId) { shown.ended = d.status; renderProgress(); settleCount(d.run_id ?? runId); }
    if (d.unsafe) showUnsafe(d.run_id ?? runId, d.unsafe);
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
  followState(engineState);
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
const runParam = /^\d+$/.test(query("run") ?? "") ? Number(query("run")) : null;

async function offerResume(state) {
  if (state !== "idle" || awaitedMount) { $("#resume-box").hidden = true; return; }
  let runs;
  try { runs = (await api("/api/runs")).data; } catch (err) { return; } // the status read says why already
  const id = runParam ?? runs.at(-1)?.id;
  const run = runs.find((r) => r.id === id);
  const offer = Boolean(run) && resumable(run, runs);
  $("#resume-box").hidden = !offer || Boolean(awaitedMount);
  if (!offer) return;
  $("#resume-text").textContent = `Run ${id} (sensor ${run.sensor_id}) ${run.status}`
    + `${run.exit_reason ? `: ${run.exit_reason}` : ""}. It recorded ${run.n_points_recorded} of `
    + `${stopsEarly(run.plan_name) ? "at most " : ""}${run.n_points_planned ?? "–"} points; resuming measures only `
    + "the missing ones, then the rest of its campaign.";
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
    if (closed) say(getToken() ? "token refused: the event stream refused the token pasted; paste the one in "
      + "~/.config/sunbench/token" : "no token: paste the token to follow the run", true, "token");
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

// the history (points, log, stage results) is read once the stream is open (connect's onopen): what happens
// after that comes as events, so nothing falls between the two
initTokenForm(connect);
$("#pause").onclick = () => control("pause");
$("#mount-confirm").onclick = confirmMount;
$("#resume-run").onclick = resumeRun;
$("#resume").onclick = () => control("resume");
$("#abort").onclick = () => { if (confirm("Abort the run? Its recorded points stay.")) control("abort"); };
showReading(reading);
draw();
connect();
setInterval(() => { if (!document.hidden) catchUp(); }, 10000);
