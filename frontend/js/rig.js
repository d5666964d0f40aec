// The rig panel: several ready sets, one per camera, calibrated together (POST /api/jobs with
// "kind": "rig"); the rig jobs listed, the chosen one's progress (cancellable), then its summary
// (each camera's model and rms in the rig and alone, the rig's rms, frames, warnings), downloads and
// its 3D view (the cameras at their poses, the board at every frame: viewer.js).
// The service checks the request: a refusal is shown here, in page words, and no job is made.
import { api, apiUrl } from "./api.js";
import { el, px, seconds } from "./format.js";
import { when } from "./names.js";
import { settingsForm } from "./settings.js";
import { renderRigViewer } from "./viewer.js";
import { pageWords } from "./words.js";

const LABELS = { "rig.json": "Rig (freecal JSON)", "camchain.yaml": "Kalibr camchain (YAML)",
  "stereo.yaml": "OpenCV stereo (YAML, a pair)" };

const rig = { jobId: null, setsSig: null, shown: "", onChange: () => {}, settings: () => ({ method: "auto", settings: {} }) };

/** Wire the form; ``methods`` as GET /api/methods gives them, ``onChange`` redraws the page (a job was made). */
export function initRig(methods, onChange) {
  rig.onChange = onChange;
  const select = document.getElementById("rig-method");
  // the calibration's choices, less "compare" (a rig calibrates each camera with one method)
  select.replaceChildren(...methods.methods.map((m) => el("option", { value: m, selected: m === "auto" }, m)));
  rig.settings = settingsForm(select, document.getElementById("rig-settings-fields"), "rig-setting");
  document.getElementById("rig-form").addEventListener("submit", (e) => { e.preventDefault(); submit(); });
  document.getElementById("rig-cameras").addEventListener("input", referenceOptions);
}

/** The camera name a set suggests: its name less the extension, in the letters a camera name may use. */
export function cameraName(setName, k) {
  const stem = setName.replace(/\.[^.]*$/, "").replace(/[^A-Za-z0-9_.-]+/g, "-").replace(/^[^A-Za-z0-9]+/, "").slice(0, 64);
  return stem || `cam${k}`;
}

function rows() {
  return [...document.querySelectorAll("#rig-cameras tbody tr[data-set]")].map((tr) => ({
    setId: tr.dataset.set, use: tr.querySelector("input[type=checkbox]").checked,
    name: tr.querySelector("input[type=text]").value.trim(),
  }));
}

/** The ready sets, oldest first (upload order: left, then right), each with a tick and a camera name. */
function renderCameras(sets) {
  const ready = sets.filter((s) => s.state === "ready").sort((a, b) => a.created_at.localeCompare(b.created_at));
  const sig = JSON.stringify(ready.map((s) => [s.id, s.name]));
  const waiting = sets.length - ready.length;
  document.getElementById("rig-waiting").textContent = waiting
    ? `${waiting} set(s) not ready yet (detecting, or failed): a set appears here once its corners are known.` : "";
  if (sig === rig.setsSig) return;
  rig.setsSig = sig;
  const before = new Map(rows().map((r) => [r.setId, r]));   // what the user ticked and typed stays
  const body = document.querySelector("#rig-cameras tbody");
  body.replaceChildren(...ready.map((s, k) => {
    const was = before.get(s.id);
    const tick = `rig-use-${s.id}`, name = `rig-name-${s.id}`;
    return el("tr", { "data-set": s.id },
      el("td", {}, el("input", { type: "checkbox", id: tick, checked: was ? was.use : false })),
      el("th", { scope: "row" }, el("label", { for: tick }, `${s.name}`), el("span", { class: "muted" }, ` ${s.n_views} views · ${when(s.created_at)}`)),
      el("td", {}, el("input", { type: "text", id: name, value: was ? was.name : cameraName(s.name, k),
        "aria-label": `camera name for set ${s.name}`, maxlength: "64", spellcheck: "false" })));
  }));
  if (!ready.length) body.append(el("tr", {}, el("td", { colspan: "3", class: "muted" }, "no ready sets yet: upload each camera's photos or corners above")));
  referenceOptions();
}

/** The reference choices: the ticked cameras by name, the choice kept when it is still ticked. */
function referenceOptions() {
  const select = document.getElementById("rig-reference");
  const kept = select.value;
  const picked = rows().filter((r) => r.use);
  select.replaceChildren(...picked.map((r) => el("option", { value: r.setId, selected: r.setId === kept }, r.name || "(no name)")));
  if (!picked.length) select.append(el("option", { value: "" }, "tick the cameras first"));
}

async function submit() {
  const picked = rows().filter((r) => r.use);
  const reference = picked.find((r) => r.setId === document.getElementById("rig-reference").value);
  const body = { kind: "rig", set_ids: picked.map((r) => r.setId), names: picked.map((r) => r.name),
    ...rig.settings(),
    hold_models: document.getElementById("rig-hold").checked };
  if (reference) body.reference = reference.name;
  const button = document.getElementById("rig-submit");
  button.disabled = true;
  say("");
  try {
    const job = await api.createJob(body);
    select(job.id);
  } catch (e) { say(pageWords(e.message || String(e))); }   // a refusal: what to change, in the panel
  finally { button.disabled = false; }
}

function say(message) {
  const box = document.getElementById("rig-message");
  box.textContent = message;
  box.hidden = !message;
}

function select(id) { rig.jobId = id; rig.shown = ""; rig.onChange(); }

/** Called by the page's poll loop with every set and the rig jobs (GET /api/jobs?kind=rig). */
export function renderRig(sets, jobs) {
  renderCameras(sets);
  const ul = document.getElementById("rig-jobs");
  ul.replaceChildren(...jobs.map((j) => {
    const name = rigName(j);
    const rmse = j.summary && j.summary.metrics ? j.summary.metrics.rmse : null;
    return el("li", { class: j.id === rig.jobId ? "selected" : "" },
      el("button", { type: "button", onclick: () => select(j.id), "aria-label": `rig job: ${name}`, "data-job": j.id, title: name },
        el("span", { class: "grow" }, name),
        el("span", { class: "muted" }, rmse != null ? `rmse ${px(rmse)}` : j.state === "running" ? `${j.progress.toFixed(0)} %` : ""),
        el("span", { class: `state ${j.state}` }, j.state)));
  }));
  if (!jobs.length) ul.append(el("li", { class: "muted" }, el("span", {}, "\u00a0 no rig jobs yet")));
  const job = jobs.find((j) => j.id === rig.jobId);
  if (job) renderRigJob(job);
}

function cameras(job) { return job.rig ? job.rig.names : []; }

/** "left + right · zhang · 14:05" */
function rigName(job) {
  return [cameras(job).join(" + "), job.method, when(job.created_at)].filter(Boolean).join(" · ");
}

function renderRigJob(job) {
  document.getElementById("rig-detail").hidden = false;
  document.getElementById("rig-detail-title").textContent = `Rig ${cameras(job).join(" + ")} (method ${job.method}` +
    (job.rig && job.rig.hold_models ? ", models held" : "") + ")";
  document.getElementById("rig-progress").value = job.progress;
  // the live line says the state and stage (read out when they change); the numbers beside it are not
  let live = job.state;
  if (job.state === "running" && job.stage) live += ` · stage: ${job.stage}`;
  else if (job.state === "queued") live += " · waiting for a worker";
  if (job.error) live += ` · ${job.error}`;
  const label = document.getElementById("rig-progress-label");
  if (label.textContent !== live) label.textContent = live;
  const t = job.timings || {};
  document.getElementById("rig-progress-numbers").textContent = ["running", "done"].includes(job.state)
    ? `${job.progress.toFixed(0)} % · ${seconds(t.run_seconds)}` : "";
  const cancel = document.getElementById("rig-cancel");
  cancel.hidden = !["queued", "running"].includes(job.state);
  cancel.onclick = async () => {
    try { await api.cancelJob(job.id); rig.onChange(); } catch (e) { say(pageWords(e.message || String(e))); }
  };
  const sig = JSON.stringify([job.id, job.state, job.summary, job.downloads]);
  if (sig === rig.shown) return;   // the poll loop comes every second: redraw the result only when it changed
  rig.shown = sig;
  const out = document.getElementById("rig-result");
  out.replaceChildren();
  if (job.state !== "done") return;
  const view = el("div", { id: "rig-viewer3d" });
  out.append(downloads(job), summaryTable(job.summary || {}), notes(job.summary || {}), view);
  renderRigViewer(job, view).catch((e) => view.replaceChildren(el("p", { class: "muted" }, `3D view: ${pageWords(e.message || String(e))}`)));
}

function downloads(job) {
  const files = job.downloads || {};
  const order = Object.keys(LABELS).filter((n) => n in files).concat(Object.keys(files).filter((n) => !(n in LABELS)));
  return el("div", { class: "downloads", id: "rig-downloads", "aria-label": "rig downloads" }, el("strong", {}, "Download:"),
    ...order.map((n) => el("a", { href: apiUrl(files[n]), download: "", "data-file": n }, LABELS[n] || n)));
}

// A camera's place: its distance from the reference camera and its rotation from it; x, y, z on hover.
function place(c, units) {
  if (c.distance == null || c.rotation_deg == null) return el("td", {}, "–");
  const short = /^[a-zA-Zµ]{1,3}$/.test(units || "") ? ` ${units}` : "";  // "mm", "m", "in"; else the board's units
  const xyz = (c.centre || []).map((v) => v.toFixed(1)).join(", ");
  return el("td", { class: "place", title: `optical centre (x, y, z) = (${xyz})${short || " in the board's units"}` },
    `${c.distance.toFixed(1)}${short} · ${c.rotation_deg.toFixed(2)}°`);
}

function summaryTable(s) {
  const m = s.metrics || {};
  const rowsOf = (s.cameras || []).map((c) => el("tr", { "data-camera": c.name, class: c.name === s.reference ? "reference" : "" },
    el("th", { scope: "row" }, c.name === s.reference ? `${c.name} (reference)` : c.name),
    el("td", { class: "model" }, c.model || "–"), place(c, s.units), el("td", {}, px(c.rmse)), el("td", {}, px(c.rmse_alone)),
    el("td", {}, c.n_frames != null ? String(c.n_frames) : "–")));
  return el("div", { class: "table-wrap" }, el("table", { id: "rig-summary" },
    el("caption", {}, `The rig: ${(s.cameras || []).length} cameras placed from ${s.reference}` +
      (s.models_refined ? ", models refined together" : ", models as calibrated alone")),
    el("thead", {}, el("tr", {}, ["camera", "model", "from the reference", "rms in the rig", "rms alone", "frames"].map((h) => el("th", { scope: "col" }, h)))),
    el("tbody", {}, rowsOf),
    el("tfoot", {}, el("tr", { id: "rig-total" }, el("th", { scope: "row" }, "the rig"),
      el("td", {}, m.n_points != null ? `${m.n_points} corners` : ""), el("td", {}, ""),
      el("td", { title: m.rmse_axis != null ? `per axis ${px(m.rmse_axis)}` : null }, px(m.rmse)), el("td", {}, ""),
      el("td", {}, s.n_frames != null ? `${s.n_frames} used` : "–")))));
}

function notes(s) {
  const box = el("div", { id: "rig-notes" });
  const warnings = s.warnings || [];
  if (warnings.length) box.append(el("p", { class: "warning" }, ...warnings.map((w) => el("span", { class: "line" }, w))));
  for (const [file, why] of Object.entries(s.exports_unavailable || {})) {
    box.append(el("p", { class: "muted" }, `${LABELS[file] || file} not made: ${why}`));
  }
  return box;
}
