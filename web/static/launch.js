// Campaign launcher: the main seed 003 fields, a dry run (preflight), then start.
import { $, api, duration, el, initTokenForm, report, say } from "./common.js";

// the campaign as the API takes it; every field not on the form keeps its default
function campaign() {
  const form = $("#campaign-form");
  const f = Object.fromEntries([...form.elements].filter((e) => e.name).map((e) => [e.name, e]));
  const list = (text) => text.split(/[,;\s]+/).map((s) => s.trim()).filter(Boolean);
  const body = {
    name: f.name.value.trim(),
    plan: "seed003",
    sensors: list(f.sensors.value),
    frames: f.frames.value,
    seed003: {
      azimuth_step_deg: Number(f.azimuth_step_deg.value),
      zenith_stage_deg: list(f.zenith_stage_deg.value).map(Number),
      repeats: Number(f.repeats.value),
      centre_repeats: Number(f.centre_repeats.value),
      tilt_stage: f.tilt_stage.checked,
    },
  };
  if (f.operator.value.trim()) body.operator = f.operator.value.trim();
  return body;
}

function showViolations(violations) {
  $("#d-nviol").textContent = violations.length ? String(violations.length) : "none";
  $("#violations").replaceChildren(...violations.map((v) => el("li", { class: "error" }, v)));
}

// a 422 of pydantic lists field errors; one of preflight lists violations
function showRefusal(err) {
  const detail = err.detail;
  if (detail && Array.isArray(detail.violations)) {
    showViolations(detail.violations);
    say("preflight refused the campaign: see the violations", true);
  } else if (Array.isArray(detail)) {
    say(`invalid campaign: ${detail.map((d) => `${(d.loc || []).slice(1).join(".")}: ${d.msg}`).join("; ")}`, true);
  } else {
    report(err);
  }
}

async function dryRun() {
  try {
    const r = await api("/api/campaigns/dry-run", { method: "POST", body: campaign() });
    $("#d-points").textContent = r.points;
    $("#d-frames").textContent = r.frames;
    $("#d-moves").textContent = r.moves;
    $("#d-duration").textContent = duration(r.duration_s);
    showViolations(r.violations);
    say(r.violations.length ? "the campaign would be refused" : "dry run ok: nothing moved", r.violations.length > 0);
    return r;
  } catch (err) {
    showRefusal(err);
    return null;
  }
}

async function start(e) {
  e.preventDefault();
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
$("#dry-run").addEventListener("click", dryRun);
$("#campaign-form").addEventListener("submit", start);
