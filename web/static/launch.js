// Campaign launcher: the plan (seed 003 or physical) and its procedure's fields, a dry run (preflight), then start.
import { $, api, duration, el, initTokenForm, report, say } from "./common.js";

const form = $("#campaign-form");
const list = (text) => text.split(/[,;\s]+/).map((s) => s.trim()).filter(Boolean);
const fieldset = (plan) => form.querySelector(`fieldset[data-plan="${CSS.escape(String(plan))}"]`);
const field = (name) => form.querySelector(`:scope > label [name="${CSS.escape(name)}"]`);  // not a procedure's

// the procedure of one fieldset as the API takes it: its inputs are named after the model's fields ("a.b" for a
// key of a mapping); a blank optional field keeps the model's default, a blank required one is sent as null so
// that the refusal names it
function procedure(plan) {
  const body = {};
  for (const input of fieldset(plan).querySelectorAll("[name]")) {
    let value;
    if (input.type === "checkbox") value = input.checked;
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
    [plan]: procedure(plan),
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

function clearDryRun() {
  for (const id of ["#d-points", "#d-frames", "#d-moves", "#d-duration", "#d-warmup", "#d-nviol"]) $(id).textContent = "–";
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

// the preflight's figures; a plan with a stopping rule is expanded to its cap, so they are upper bounds
function showDryRun(r, sensors) {
  const bound = r.upper_bound ? "at most " : "";
  $("#d-points").textContent = `${bound}${r.points}`;
  $("#d-frames").textContent = `${bound}${r.frames}`;
  $("#d-moves").textContent = `${bound}${r.moves}`;
  $("#d-duration").textContent = `${bound}${duration(r.duration_s)}`;
  $("#d-warmup").textContent = r.warmup_s > 0 ? duration(r.warmup_s) : "none (the lamp needs none)";
  $("#d-summary").textContent = `${bound}${r.points} points, ${bound}${r.frames} frames, ${bound}${r.moves} moves per `
    + `sensor × ${sensors} sensor(s); ${bound || "about "}${minutes(r.duration_s)} on the bench`
    + (r.warmup_s > 0 ? ` (of which ${minutes(r.warmup_s)} lamp warm-up)` : "");
  $("#d-bound").textContent = r.upper_bound
    ? `Upper bounds, every point counted: ${r.upper_bound_reason ?? "the plan may stop early"}.` : "";
  showViolations(r.violations);
}

async function dryRun() {
  markInvalid([]);
  const body = campaign();
  try {
    const r = await api("/api/campaigns/dry-run", { method: "POST", body });
    showDryRun(r, body.sensors.length);
    say(r.violations.length ? "the campaign would be refused" : "dry run ok: nothing moved", r.violations.length > 0);
    return r;
  } catch (err) {
    showRefusal(err);
    return null;
  }
}

async function start(e) {
  e.preventDefault();
  markInvalid([]);
  try {
    const { campaign_id } = await api("/api/campaigns", { method: "POST", body: campaign() });
    say(`campaign ${campaign_id} queued`);
    $("#started").replaceChildren(`Campaign ${campaign_id} queued: follow it on `,
      el("a", { href: "/run" }, "the live run"), " or ", el("a", { href: `/fleet?campaign=${campaign_id}` }, "its fleet"), ".");
  } catch (err) {
    showRefusal(err);
  }
}

initTokenForm();
field("plan").addEventListener("change", showPlan);
showPlan();  // a browser may restore another choice than the page's on reload
$("#dry-run").addEventListener("click", dryRun);
form.addEventListener("submit", start);
