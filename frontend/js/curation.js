// Curation: every view of a calibration with its figures and flags (sortable), views ticked off to
// leave them out, and a re-run on the same set (the method and settings of card 1, no new upload).
import { api } from "./api.js";
import { clearError, showError } from "./errors.js";
import { el, num, px } from "./format.js";
import { chosenSettings } from "./settings.js";

const FLAG_WORDS = { outliers: "many outliers", rmse: "rmse far above the rest", structure: "residual pattern" };
const COLUMNS = [
  { key: "use", label: "use", sort: (r) => (r.excluded ? 1 : 0) },
  { key: "view", label: "view", sort: (r) => r.view },
  { key: "corners", label: "corners kept / found", sort: (r) => (r.n_kept ?? -1) / Math.max(1, r.n_detected ?? 1) },
  { key: "rmse", label: "rmse [px]", sort: (r) => r.rmse ?? -1 },
  { key: "max", label: "max error [px]", sort: (r) => r.max_error ?? -1 },
  { key: "flags", label: "flags", sort: (r) => (r.flags || []).length },
];
const sorting = { key: "view", dir: 1 };

/** The per-view table of ``job`` (its view_residuals.json rows ``views``) with the re-run bar. */
export function curationTable(views, job, title) {
  const excluded = job.exclude || [];
  const rows = views.map((v) => ({ ...v, excluded: false }))
    .concat(excluded.map((name) => ({ view: name, excluded: true, flags: [] })));
  const box = el("div", { id: "curation", class: "curation" });
  const leaveOut = new Set(excluded);
  const bar = rerunBar(job, leaveOut, rows);
  const draw = () => box.replaceChildren(table(rows, leaveOut, title, draw, bar.update), bar.node);
  draw();
  bar.update();
  return box;
}

function table(rows, leaveOut, title, redraw, changed) {
  const col = COLUMNS.find((c) => c.key === sorting.key);
  const sorted = [...rows].sort((a, b) => {
    const x = col.sort(a), y = col.sort(b);
    return (x < y ? -1 : x > y ? 1 : 0) * sorting.dir;
  });
  const flagged = rows.filter((r) => (r.flags || []).length).length;
  const head = el("tr", {}, COLUMNS.map((c) => el("th", { scope: "col", "aria-sort": c.key === sorting.key
    ? (sorting.dir > 0 ? "ascending" : "descending") : "none" },
  el("button", { type: "button", class: "sort", "data-sort": c.key, onclick: () => {
    sorting.dir = sorting.key === c.key ? -sorting.dir : (c.key === "flags" || c.key === "rmse" || c.key === "max" ? -1 : 1);
    sorting.key = c.key;
    redraw();
  } }, c.label, c.key === sorting.key ? (sorting.dir > 0 ? " ▲" : " ▼") : ""))));
  const body = sorted.map((r) => {
    const box = el("input", { type: "checkbox", "aria-label": `use ${r.view}`, checked: !leaveOut.has(r.view) });
    box.addEventListener("change", () => { if (box.checked) leaveOut.delete(r.view); else leaveOut.add(r.view); changed(); });
    const flags = r.excluded ? el("span", { class: "muted" }, "left out of this calibration")
      : (r.flags || []).map((f) => el("span", { class: `flag ${f.code}`, title: f.text }, FLAG_WORDS[f.code] || f.code));
    return el("tr", { class: [r.excluded ? "excluded" : "", (r.flags || []).length ? "flagged" : ""].join(" ").trim(),
      "data-view": r.view },
    el("td", {}, box), el("th", { scope: "row" }, r.view),
    el("td", {}, r.excluded ? "–" : `${num(r.n_kept ?? r.n_points)} / ${num(r.n_detected ?? r.n_points)}`),
    el("td", {}, r.excluded ? "–" : px(r.rmse)), el("td", {}, r.excluded ? "–" : px(r.max_error)),
    el("td", { class: "flags" }, flags));
  });
  const caption = `${title}: ${rows.length} views` + (flagged ? `, ${flagged} flagged (hover a flag for why)` : ", none flagged");
  const details = rows.filter((r) => (r.flags || []).length).map((r) =>
    el("li", {}, el("strong", {}, r.view), ": ", r.flags.map((f) => f.text).join("; ")));
  return el("div", {}, el("div", { class: "table-wrap scroll-y" }, el("table", { id: "metrics-views" },
    el("caption", {}, caption), el("thead", {}, head), el("tbody", {}, body))),
  details.length ? el("ul", { id: "flag-details", class: "flag-details" }, details) : "");
}

function rerunBar(job, leaveOut, rows) {
  const count = el("span", { id: "rerun-count" });
  const button = el("button", { type: "button", id: "rerun", class: "primary-inline" }, "Re-run on this set");
  const flaggedButton = el("button", { type: "button", id: "untick-flagged" }, "Untick the flagged views");
  flaggedButton.addEventListener("click", () => {
    for (const r of rows) if ((r.flags || []).length) leaveOut.add(r.view);
    for (const box of document.querySelectorAll("#curation tbody tr.flagged input")) box.checked = false;
    update();
  });
  button.addEventListener("click", async () => {
    clearError();
    button.disabled = true;
    try {
      const { method, settings } = chosenSettings();
      const created = await api.createJob({ set_id: job.set_id, method, settings, exclude: [...leaveOut] });
      document.dispatchEvent(new CustomEvent("freecal:job-created", { detail: { id: created.id } }));
    } catch (e) { showError(e); }
    finally { button.disabled = false; }
  });
  function update() {
    if (!job.set_id) return;
    const { method } = chosenSettings();
    count.textContent = ` with ${method} and the settings of card 1` +
      (leaveOut.size ? `, without ${leaveOut.size} view${leaveOut.size > 1 ? "s" : ""} (unticked)` : ", every view");
    flaggedButton.hidden = !rows.some((r) => (r.flags || []).length);
  }
  const node = el("div", { class: "rerun-bar" }, button, count, flaggedButton,
    el("p", { class: "muted" }, "Untick views to leave them out; choose another method or settings in card 1; " +
      "the photos are not uploaded again."));
  if (!job.set_id) { button.disabled = true; count.textContent = " (corners sent inline: upload them as a set to re-run)"; }
  return { node, update };
}
