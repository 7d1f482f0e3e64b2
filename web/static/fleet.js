// Fleet of a campaign: one row per sensor with its run and chosen calibration.
import { $, api, el, fmt, initTokenForm, query, report, say, stopsEarly } from "./common.js";

const campaignParam = query("campaign");

async function listCampaigns() {
  $("#campaign-picker").hidden = false;
  const campaigns = (await api("/api/campaigns")).data.slice().reverse();
  $("#campaigns-table tbody").replaceChildren(...campaigns.map((c) => el("tr", {},
    el("td", {}, el("a", { href: `/fleet?campaign=${c.id}` }, `campaign ${c.id}`)), el("td", {}, c.name),
    el("td", {}, c.status), el("td", {}, String(c.n_runs)), el("td", {}, c.created_utc))));
  if (!campaigns.length) $("#campaigns-table tbody").append(el("tr", {}, el("td", { colspan: 5 }, "no campaign yet")));
}

async function showFleet(id) {
  $("#fleet-section").hidden = false;
  const fleet = await api(`/api/campaigns/${id}/fleet`);
  const done = fleet.data.filter((f) => f.status === "done").length;
  $("#fleet-heading").textContent = `Campaign ${id}: ${done} / ${fleet.count} sensors done`;
  const campaign = (await api("/api/campaigns")).data.find((c) => c.id === id);
  // a plan with a stopping rule (physical): each run's planned points are its cap
  const bound = stopsEarly(campaign?.plan) ? "at most " : "";
  const stopped = campaign && (campaign.status === "aborted" || campaign.status === "failed");
  $("#campaign-stopped").hidden = !stopped;
  if (stopped) {
    $("#campaign-stopped-text").textContent = `This campaign ${campaign.status}; `
      + `${fleet.count - done} sensor(s) not done. `
      + "Resuming goes on with them, each from its last run's points, asking for every sensor to mount. ";
  }
  $("#fleet tbody").replaceChildren(...fleet.data.map((f) => {
    const held = f.metrics?.heldout || {};  // a QD method's figures are angular errors: rms_deg, max_deg
    return el("tr", {},
      el("td", {}, String(f.position + 1)), el("td", {}, f.sensor_id), el("td", {}, f.status + (f.run_status && f.run_status !== f.status ? ` (${f.run_status})` : "")),
      el("td", {}, f.run_id ? el("a", { href: `/results?run=${f.run_id}` }, `run ${f.run_id}`) : "–"),
      el("td", {}, f.run_id ? `${f.n_points_recorded ?? 0} / ${bound}${f.n_points_planned ?? "–"}` : "–"),
      el("td", {}, f.method ?? "–"), el("td", {}, fmt(held.rms_vector_deg ?? held.rms_deg)),
      el("td", {}, fmt(held.p95_vector_deg)), el("td", {}, fmt(held.max_vector_deg ?? held.max_deg)),
      el("td", {}, f.exit_reason ?? f.metrics?.error ?? ""));
  }));
}

async function init() {
  try {
    if (campaignParam && /^\d+$/.test(campaignParam)) await showFleet(Number(campaignParam));
    else await listCampaigns();
  } catch (err) {
    report(err);
  }
}

async function resumeCampaign() {
  try {
    say((await api(`/api/campaigns/${Number(campaignParam)}/resume`, { method: "POST" })).message);
    $("#campaign-stopped").hidden = true;
  } catch (err) { report(err); }
}

$("#resume-campaign").onclick = resumeCampaign;
initTokenForm(init);
init();
if (campaignParam) setInterval(() => { if ($("#fleet-live").checked && !document.hidden) init(); }, 5000);
