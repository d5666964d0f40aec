// The calibrations of one set side by side: method, settings, views left out, rms and the error on
// views left out of the fit, so that re-runs (another method, other settings, fewer views) compare
// at a glance. A row opens that job. "Compare with…" draws the projection difference between the
// calibration shown and another of the set (`freecal diff`, computed by the service).
import { api } from "./api.js";
import { el, px } from "./format.js";
import { diffFigure, diffSummary } from "./plots/diff.js";
import { pageWords } from "./words.js";

export async function renderSetJobs(job) {
  const box = document.getElementById("set-jobs");
  box.replaceChildren();
  if (!job.set_id) return;
  const all = (await api.jobs()).jobs.filter((j) => j.kind === "calibrate" && j.set_id === job.set_id);
  if (all.length < 2) return;   // one calibration: nothing to compare it with
  const rows = [...all].reverse().map((j, k) => el("tr", { class: j.id === job.id ? "best" : "", "data-job": j.id },
    el("th", { scope: "row" }, el("button", { type: "button", class: "link", onclick: () => open(j.id) }, `#${k + 1} ${time(j)}`)),
    el("td", {}, what(j)), el("td", { class: "settings" }, settingsText(j.settings)),
    el("td", {}, views(j)), el("td", {}, figure(j, "rmse")), el("td", {}, figure(j, "rmse_axis")),
    el("td", {}, validation(j)), el("td", {}, el("span", { class: `state ${j.state}` }, j.state))));
  const table = el("table", { id: "set-jobs-table" },
    el("caption", {}, `Calibrations of this set (${all.length}), oldest first; the one shown is highlighted`),
    el("thead", {}, el("tr", {}, ["calibration", "method", "settings", "views used (left out)", "rmse [px]",
      "rmse per axis [px]", "error on views left out of the fit", ""].map((h) => el("th", { scope: "col" }, h)))),
    el("tbody", {}, rows));
  box.append(el("div", { class: "table-wrap" }, table), compareSlot(job, all));
}

function open(id) { document.dispatchEvent(new CustomEvent("freecal:job-created", { detail: { id } })); }

function time(j) { return new Date(j.created_at).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit" }); }

function what(j) {
  const s = j.summary || {};
  if (j.method === "compare") return s.verdict ? `compare → ${s.verdict}` : "compare";
  return s.model ? `${j.method}: ${s.model}` : j.method;
}

function settingsText(settings) {
  const entries = Object.entries(settings || {});
  return entries.length ? entries.map(([k, v]) => `${k} ${Array.isArray(v) ? v.join("×") : v}`).join(", ") : "defaults";
}

function views(j) {
  const s = j.summary || {};
  const out = (j.exclude || []).length;
  return s.n_views != null ? `${s.n_views}${out ? ` (${out} left out)` : ""}` : out ? `(${out} left out)` : "–";
}

function figure(j, key) { return px(((j.summary || {}).metrics || {})[key]); }

function validation(j) {
  const v = (j.summary || {}).validation;
  if (!v) return "–";
  return v.rmse_axis != null ? `${px(v.rmse_axis)} per axis` : `${Number(v.mse).toFixed(4)} px²`;
}

function compareSlot(job, all) {
  const others = all.filter((j) => j.id !== job.id && j.state === "done");
  const slot = el("div", { id: "compare-slot", hidden: job.state !== "done" || !others.length });
  if (slot.hidden) return slot;
  const label = (j) => `${what(j)} · ${time(j)}`;
  const select = el("select", { id: "compare-with", "aria-label": "compare with another calibration of this set" },
    el("option", { value: "" }, "compare with…"), others.map((j) => el("option", { value: j.id }, label(j))));
  const out = el("div", { id: "compare-out", "aria-live": "polite" });
  select.addEventListener("change", async () => {
    out.replaceChildren();
    const other = others.find((j) => j.id === select.value);
    if (!other) return;
    out.append(el("p", { class: "muted" }, "computing the projection difference…"));
    try {
      const diff = await api.diff(job.id, other.id);
      if (select.value !== other.id) return;   // another choice meanwhile
      out.replaceChildren(diffSummary(diff), diffFigure({ diff, a: label(job), b: label(other) }));
    } catch (e) {
      out.replaceChildren(el("p", { class: "error", role: "alert" }, pageWords(e.message || String(e))));
    }
  });
  slot.append(el("label", { for: "compare-with" }, "Projection difference with another calibration: "), select, out);
  return slot;
}
