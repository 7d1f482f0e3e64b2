// Campaign launcher: the plan (seed 003 or physical on a CMOS bench, qd-grid, qd-physical or qd-dark on a QD one,
// camera-grid on a camera one, css-sweep on a CSS head's, horizon-grid on a horizon sensor's: the plans of the bench's
// sensor family only) and its procedure's fields, a dry run (preflight), then start.
import { $, api, duration, el, initTokenForm, report, say } from "./common.js";

const form = $("#campaign-form");
const list = (text) => text.split(/[,;\s]+/).map((s) => s.trim()).filter(Boolean);
// a plan's fieldset, by the plan ("qd-grid") or by the campaign's field it fills ("qd_grid")
const fieldset = (plan) => form.querySelector(`fieldset[data-plan="${CSS.escape(String(plan))}"]`)
  || form.querySelector(`fieldset[data-field="${CSS.escape(String(plan))}"]`);
const field = (name) => form.querySelector(`:scope > label [name="${CSS.escape(name)}"]`);  // not a procedure's

// the procedure of one fieldset as the API takes it: its inputs are named after the model's fields ("a.b" for a
// key of a mapping); a blank optional field keeps the model's default (a list too, when it says data-blank="default":
// else a blank list is an empty one), a blank required one is sent as null so that the refusal names it
function procedure(plan) {
  const body = {};
  for (const input of fieldset(plan).querySelectorAll("[name]")) {
    let value;
    if (input.type === "checkbox") value = input.checked;
    else if (input.hasAttribute("data-blank") && input.value.trim() === "") continue;  // blank: the model's default
    else if (input.hasAttribute("data-list")) value = list(input.value).map(Number);
    else if (input.value.trim() === "") {
      if (!input.required) continue;
      value = null;
    } else value = input.type === "number" ? Number(input.value) : input.value.trim();
    const path = input.name.split(".");
    let target = body;
    for (const key of path.slice(0, -1)) target = target[key] ??= {};
    target[path[path.length - 1]] = value;
  }
  return body;
}

// the campaign as the API takes it; every field not on the form keeps its default
function campaign() {
  const plan = field("plan").value;
  const body = {
    name: field("name").value.trim(),
    plan,
    sensors: list(field("sensors").value),
    frames: field("frames").value,
    [fieldset(plan).dataset.field ?? plan]: procedure(plan),
  };
  if (field("operator").value.trim()) body.operator = field("operator").value.trim();
  return body;
}

// only the chosen plan's fields show, and only they are validated by the browser on Start
function showPlan() {
  for (const set of form.querySelectorAll("fieldset[data-plan]")) {
    const chosen = set.dataset.plan === field("plan").value;
    set.hidden = !chosen;
    set.disabled = !chosen;
  }
  clearDryRun();
}

const FIGURES = ["#d-points", "#d-frames", "#d-moves", "#d-sensors", "#d-duration-sensor", "#d-duration", "#d-warmup",
  "#d-wall", "#d-nviol"];

function clearDryRun() {
  for (const id of FIGURES) $(id).textContent = "–";
  for (const id of ["#d-summary", "#d-bound"]) $(id).textContent = "";
  $("#violations").replaceChildren();
}

function showViolations(violations) {
  $("#d-nviol").textContent = violations.length ? String(violations.length) : "none";
  $("#violations").replaceChildren(...violations.map((v) => el("li", { class: "error" }, v)));
}

// the input a field error of the API is about: loc is ["body", field] or ["body", plan, field, key …]
function inputAt(loc) {
  const [, first, ...rest] = loc;
  const set = fieldset(first);
  if (set) return set.querySelector(`[name="${CSS.escape(rest.join("."))}"]`) || set.querySelector(`[name="${CSS.escape(rest[0] ?? "")}"]`);
  return field(String(first));
}

function markInvalid(details) {
  for (const input of form.querySelectorAll(".invalid")) input.classList.remove("invalid");
  for (const d of details) {
    const input = inputAt(d.loc || []);
    if (input) {
      input.classList.add("invalid");
      input.closest("details")?.setAttribute("open", "");
    }
  }
}

// a 422 of pydantic lists field errors; one of preflight lists violations
function showRefusal(err) {
  const detail = err.detail;
  if (detail && Array.isArray(detail.violations)) {
    showViolations(detail.violations);
    say("preflight refused the campaign: see the violations", true);
  } else if (Array.isArray(detail)) {
    markInvalid(detail);
    say(`invalid campaign: ${detail.map((d) => `${(d.loc || []).slice(1).join(".")}: ${d.msg}`).join("; ")}`, true);
  } else {
    report(err);
  }
}

const minutes = (s) => `${(s / 60).toFixed(1)} min`;

// bench time on the wall clock, in words: the same on a real bench; bench time / time scale on a simulated one
function wallText(r, bound) {
  if (!r.simulated) return `${bound}${duration(r.wall_duration_s)} (a real bench: its wall time is its bench time)`;
  if (r.wall_duration_s === null) return "no waiting: the simulated bench skips every wait (time scale 0)";
  return `${bound}${duration(r.wall_duration_s)} on this simulated bench (bench time / time scale ${r.time_scale})`;
}

// the preflight's figures: points, frames and moves per sensor; durations per sensor and for the whole campaign,
// in bench time and on the wall clock. A plan with a stopping rule is expanded to its cap: upper bounds
function showDryRun(r) {
  const bound = r.upper_bound ? "at most " : "";
  $("#d-points").textContent = `${bound}${r.points}`;
  $("#d-frames").textContent = `${bound}${r.frames}`;
  $("#d-moves").textContent = `${bound}${r.moves}`;
  $("#d-sensors").textContent = String(r.sensors);
  $("#d-duration-sensor").textContent = `${bound}${duration(r.duration_per_sensor_s)}`;
  $("#d-duration").textContent = `${bound}${duration(r.duration_s)}`;
  $("#d-warmup").textContent = r.warmup_s > 0 ? duration(r.warmup_s) : "none (the lamp needs none)";
  $("#d-wall").textContent = wallText(r, bound);
  const wall = r.wall_duration_s === null ? "no wall time (time scale 0)"
    : `${bound || "about "}${minutes(r.wall_duration_s)} of wall time`;
  $("#d-summary").textContent = `${bound}${r.points} points, ${bound}${r.frames} ${READINGS}, ${bound}${r.moves} moves per `
    + `sensor × ${r.sensors} sensor(s); ${bound || "about "}${minutes(r.duration_s)} of bench time in all`
    + (r.warmup_s > 0 ? ` (of which ${minutes(r.warmup_s)} lamp warm-up)` : "") + `, ${wall}`;
  $("#d-bound").textContent = r.upper_bound
    ? `Upper bounds, every point counted: ${r.upper_bound_reason ?? "the plan may stop early"}.` : "";
  showViolations(r.violations);
}

async function dryRun() {
  markInvalid([]);
  const body = campaign();
  try {
    const r = await api("/api/campaigns/dry-run", { method: "POST", body });
    showDryRun(r);
    say(r.violations.length ? "the campaign would be refused" : "dry run ok: nothing moved", r.violations.length > 0);
    return r;
  } catch (err) {
    showRefusal(err);
    return null;
  }
}

// one key per Start of this form: a double click, or a click again on an unchanged form, sends the same key and
// the server queues one campaign (answering the first one's id); any change to the form makes a new key
const newKey = () => (crypto.randomUUID ? crypto.randomUUID()
  : Array.from(crypto.getRandomValues(new Uint8Array(16)), (b) => b.toString(16).padStart(2, "0")).join(""));
let startKey = newKey();

async function start(e) {
  e.preventDefault();
  const button = $("#start");
  if (button.disabled) return;
  button.disabled = true;  // until the answer: the queued campaign, or why not
  markInvalid([]);
  try {
    const { campaign_id, replayed } = await api("/api/campaigns", { method: "POST", body: campaign(),
      headers: { "Idempotency-Key": startKey } });
    say(replayed ? `campaign ${campaign_id} was queued already by this Start: nothing more was queued (change the `
      + "form to queue another)" : `campaign ${campaign_id} queued`);
    $("#started").replaceChildren(`Campaign ${campaign_id} queued: follow it on `,
      el("a", { href: "/run" }, "the live run"), " or ", el("a", { href: `/fleet?campaign=${campaign_id}` }, "its fleet"), ".");
  } catch (err) {
    showRefusal(err);
  } finally {
    button.disabled = false;
  }
}

// what one reading of the bench's sensor is: a frame (an image sensor), or a reading (a photodiode's currents)
const READINGS = document.body.dataset.frames === "false" ? "readings" : "frames";

// the plans of the bench's sensor family (the page's data-plans, web/routes/pages.py): the others are not offered
function offerFamilyPlans() {
  const offered = (document.body.dataset.plans ?? "").split(" ").filter(Boolean);
  if (!offered.length) return;  // the server did not say: every plan stays, preflight refuses a foreign one
  const select = field("plan");
  for (const option of [...select.options]) {
    if (!offered.includes(option.value)) {
      option.remove();
      fieldset(option.value)?.remove();
    }
  }
  if (!select.value && select.options.length) select.value = select.options[0].value;
  for (const label of form.querySelectorAll("label[data-frames]")) label.hidden = READINGS !== "frames";
  $("#d-frames-label").textContent = `${READINGS[0].toUpperCase()}${READINGS.slice(1)} per sensor`;
}

initTokenForm();
offerFamilyPlans();
field("plan").addEventListener("change", showPlan);
for (const event of ["input", "change"]) form.addEventListener(event, () => { startKey = newKey(); });
showPlan();  // a browser may restore another choice than the page's on reload
$("#dry-run").addEventListener("click", dryRun);
form.addEventListener("submit", start);
