// Bench page: cached status, manual commands, the latest frame with its spot marked (a sensor that takes frames;
// a photodiode's currents are in the status instead).
import { $, amps, api, drawLatestFrame, fmt, initTokenForm, report, say } from "./common.js";

const FRAMES = document.body.dataset.frames !== "false";  // the bench's sensor takes frames (web/routes/pages.py)

// the sensor's state in words: its temperature, and its exposure (a camera) or its currents (a photodiode)
function sensorText(sensor) {
  if (!sensor) return "–";
  const what = sensor.currents_a ? `currents ${sensor.currents_a.map((c) => amps(c)).join(", ")}`
    : `exposure ${fmt(sensor.exposure_ms, 2)} ms`;
  return `${sensor.family ? `${sensor.family}: ` : ""}${fmt(sensor.temperature_c, 1)} °C, ${what}`;
}

let status = null;

async function refreshStatus() {
  try {
    status = await api("/api/status");
  } catch (err) {
    report(err);
    return;
  }
  const { engine, table, source, sensor } = status;
  const last = engine.state === "idle" ? "last run" : "run";
  $("#s-engine").textContent = engine.state + (engine.run_id ? ` (${last} ${engine.run_id}, ${engine.index ?? 0}/${engine.total ?? "–"})` : "");
  $("#s-az").textContent = table ? `${fmt(table.azimuth_deg, 3)}°` : "–";
  $("#s-zen").textContent = table ? `${fmt(table.zenith_deg, 3)}°` : "–";
  $("#s-moving").textContent = table ? (table.moving ? "moving" : "still") : "–";
  $("#s-lamp").textContent = source ? `${source.lamp_on ? "on" : "off"}${source.lamp_on && !source.warm ? " (warming up)" : ""}${source.fault ? " FAULT" : ""}` : "–";
  $("#s-shutter").textContent = source ? (source.shutter_open ? "open" : "closed") : "–";
  $("#s-sensor").textContent = sensorText(sensor);
  $("#s-updated").textContent = (status.error ? `ERROR ${status.error} · ` : "") + (status.updated_utc ?? "–");
  followState(engine);
  const form = $("#jog-form");
  if (table && document.activeElement?.form !== form) {
    form.azimuth_deg.value = fmt(table.azimuth_deg, 3);
    form.zenith_deg.value = fmt(table.zenith_deg, 3);
  }
}

// the buttons follow the engine: moves and lights only while no run owns the bench and no e-stop is latched;
// closing the shutter and standby (they make the bench safer) also while latched; the e-stop always
function followState(engine) {
  const latched = engine.state === "estop", free = engine.state === "idle";
  $("#estop-box").hidden = !latched;
  $("#estop-ack").disabled = !latched;
  for (const b of document.querySelectorAll("#lamp-on, #shutter-open, #jog-form button, [data-jog]")) b.disabled = !free;
  for (const b of document.querySelectorAll("#lamp-off, #shutter-close")) b.disabled = !(free || latched);
  const unsafe = engine.ended_unsafe;
  $("#unsafe-box").hidden = !unsafe;
  $("#unsafe-box").textContent = unsafe ? `Run ${engine.run_id} ${unsafe}: see to the bench before the next run.` : "";
}

async function command(path, body, done) {
  try {
    status = await api(path, { method: "POST", body });
    say(done);
  } catch (err) {
    report(err);
  }
  refreshStatus();
}

function jog(azimuth_deg, zenith_deg) {
  say(`moving to azimuth ${fmt(azimuth_deg)}°, zenith ${fmt(zenith_deg)}° …`);
  return command("/api/table/jog", { azimuth_deg, zenith_deg }, `table at azimuth ${fmt(azimuth_deg)}°, zenith ${fmt(zenith_deg)}°`);
}

async function refreshFrame() {
  if (!FRAMES) return;
  try {
    await drawLatestFrame($("#frame"), $("#spot-text"));
  } catch (err) {
    report(err);
  }
}

function init() {
  $("#frame-section").hidden = !FRAMES;
  initTokenForm(() => { refreshStatus(); refreshFrame(); });
  $("#lamp-on").onclick = () => command("/api/source/lamp", { on: true }, "lamp on");
  $("#lamp-off").onclick = () => command("/api/source/lamp", { on: false }, "lamp to standby");
  $("#shutter-open").onclick = () => command("/api/source/shutter", { open: true }, "shutter open");
  $("#shutter-close").onclick = () => command("/api/source/shutter", { open: false }, "shutter closed");
  $("#stop").onclick = async () => {
    try { say((await api("/api/stop", { method: "POST" })).message, true); } catch (err) { report(err); }
    refreshStatus();
  };
  $("#estop-ack").onclick = async () => {
    try { say((await api("/api/stop/acknowledge", { method: "POST" })).message); } catch (err) { report(err); }
    refreshStatus();
  };
  $("#jog-form").addEventListener("submit", (e) => {
    e.preventDefault();
    const f = e.target;
    jog(Number(f.azimuth_deg.value), Number(f.zenith_deg.value));
  });
  for (const button of document.querySelectorAll("[data-jog]")) {
    button.addEventListener("click", () => {
      if (!status?.table) return say("no table position yet", true);
      const [axis, sign] = button.dataset.jog.split(":");
      const step = Number($("#jog-step").value) * Number(sign);
      const { azimuth_deg, zenith_deg } = status.table;
      jog(axis === "az" ? azimuth_deg + step : azimuth_deg, axis === "zen" ? zenith_deg + step : zenith_deg);
    });
  }
  refreshStatus();
  refreshFrame();
  setInterval(refreshStatus, 1000);
  setInterval(() => { if ($("#frame-live").checked && !document.hidden) refreshFrame(); }, 2000);
}

init();
