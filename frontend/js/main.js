// The page's wiring: upload → set detection → job → results (and rigs of several sets), with a poll loop that
// keeps the lists, the progress bars and the selected items current.
import { api, ApiError } from "./api.js";
import { initBoard } from "./board.js";
import { initCapture } from "./capture.js";
import { clearError, showError } from "./errors.js";
import { initHelp } from "./help.js";
import { hideJob, renderJob, renderJobs } from "./jobs.js";
import { hideResults, renderResults } from "./results.js";
import { initRig, renderRig } from "./rig.js";
import { hideSet, renderSet, renderSets } from "./sets.js";
import { renderSetNotes } from "./setnotes.js";
import { initMethods } from "./settings.js";
import { initUpload } from "./upload.js";
import { deleteSetQuestion, JOB_GONE, NO_FILES, SET_GONE } from "./words.js";

const POLL_MS = 1000;
const state = { setId: null, jobId: null, shownJob: null, sets: [] };

// true once the set and its job are created (the capture card then lets its shots go)
async function submit({ form, method, settings }) {
  clearError();
  if (!form.getAll("files").length) { showError(new Error(NO_FILES)); return false; }
  try {
    const set = await api.createSet(form);
    selectSet(set.id);
    // created at once: the job waits in the queue until the set's detection is done
    const job = await api.createJob({ set_id: set.id, method, settings });
    state.scrollTo = job.id;   // the user asked for this one: show its results when they come
    selectJob(job.id);
    return true;
  } catch (e) { showError(e); return false; }
}

// curation (re-run without some views) and the board-size suggestion create jobs too: show them
document.addEventListener("freecal:job-created", (e) => { state.scrollTo = e.detail.id; selectJob(e.detail.id); });

function selectSet(id) { state.setId = id; remember(); refresh(); }
function selectJob(id) {
  state.jobId = id;
  state.shownJob = null;
  hideResults();
  remember();
  refresh();
}

// What is shown lives in the address (#set=…&job=…): a reload shows it again, and Back goes to what was
// shown before instead of leaving the page.
function remember(replace = false) {
  const hash = new URLSearchParams();
  if (state.setId) hash.set("set", state.setId);
  if (state.jobId) hash.set("job", state.jobId);
  const next = hash.toString() ? `#${hash}` : location.pathname + location.search;
  if (next === location.hash || (!hash.toString() && !location.hash)) return;
  if (replace) history.replaceState(null, "", next); else history.pushState(null, "", next);
}

function recall() {
  const hash = new URLSearchParams(location.hash.slice(1));
  state.setId = hash.get("set");
  state.jobId = hash.get("job");
  state.shownJob = null;
  hideResults();
}
window.addEventListener("popstate", () => { recall(); refresh(); });

async function cancel(id) {
  try { await api.cancelJob(id); refresh(); } catch (e) { showError(e); }
}

// a set the user no longer needs (a wrong upload; the server's FREECAL_MAX_SETS asks for room)
async function deleteShownSet() {
  const set = state.sets.find((s) => s.id === state.setId);
  if (!set || !window.confirm(deleteSetQuestion(set.name))) return;
  clearError();
  try {
    await api.deleteSet(set.id);   // a running job first answers 409, in words: its cancellation was asked for
    if (state.jobSetId === set.id) {   // its calibration shown: gone with it
      state.jobId = null;
      state.shownJob = null;
      hideJob();
      hideResults();
    }
    state.setId = null;
    hideSet();
    remember(true);
    refresh();
  } catch (e) { showError(e); }
}

let busy = false;
async function refresh() {
  if (busy) return;
  busy = true;
  try {
    const [sets, jobs, rigs] = await Promise.all([api.sets(), api.jobs(), api.rigJobs()]);
    state.sets = sets.sets;
    renderSets(sets.sets, state.setId, selectSet);
    renderRig(sets.sets, rigs.jobs);
    renderJobs(jobs.jobs, state.jobId, selectJob, sets.sets);
    let set = null;
    if (state.setId && !sets.sets.some((s) => s.id === state.setId)) {
      // deleted elsewhere: asking for it every second would only repeat the API's 404
      state.setId = null;
      hideSet();
      remember(true);
      showError(new Error(SET_GONE));
    }
    if (!state.setId) hideSet();   // Back to a page that showed none
    if (state.setId) {
      set = await api.set(state.setId);
      renderSet(set);
      renderSetNotes(set, jobs.jobs);
    }
    if (!state.jobId) hideJob();
    if (state.jobId) {
      let job;
      try { job = await api.job(state.jobId); }
      catch (e) {
        if (!(e instanceof ApiError && e.status === 404)) throw e;
        state.jobId = null;
        state.shownJob = null;
        hideJob();
        hideResults();
        remember(true);
        showError(new Error(JOB_GONE));
        return;
      }
      // fetched after the list: where it moved on since, the list shows it as it is now (never "running" beside results)
      const listed = jobs.jobs.findIndex((j) => j.id === job.id);
      if (listed >= 0 && jobs.jobs[listed].state !== job.state) {
        jobs.jobs[listed] = job;
        renderJobs(jobs.jobs, state.jobId, selectJob, sets.sets);
      }
      state.jobSetId = job.set_id;
      renderJob(job, cancel, state.sets);
      if (job.state === "done" && state.shownJob !== job.id) {
        state.shownJob = job.id;
        if (job.set_id && job.set_id !== state.setId) {
          state.setId = job.set_id;
          remember(true);
          set = await api.set(job.set_id);
          renderSet(set);
        }
        // shown at once, scrolled to while its figures still come in
        const drawn = renderResults(job, set);
        if (state.scrollTo === job.id) document.getElementById("results").scrollIntoView({ behavior: "smooth" });
        await drawn;
      }
    }
  } catch (e) { showError(e); }
  finally { busy = false; }
}

async function health() {
  // a worker reports in a few seconds after start: keep this line current
  try {
    const h = await api.health();
    const line = document.getElementById("health");
    line.textContent = `service ${h.version} · ${h.workers} worker(s) · queue ${h.queue}`;
    // degraded: the service answers but jobs or writes do not work; say what and what to do
    if (h.status === "degraded") line.textContent += ` · degraded: ${(h.problems || []).join("; ")}`;
  } catch { document.getElementById("health").textContent = "service unreachable"; }
}

async function init() {
  initBoard();
  initHelp();
  initUpload(submit);
  initCapture(submit);
  document.getElementById("set-delete").addEventListener("click", deleteShownSet);
  try {
    const methods = await api.methods();
    initMethods(methods);
    initRig(methods, refresh);
  } catch (e) { showError(e); }
  recall();   // a reload, or a link to a set or calibration
  await refresh();
  setInterval(refresh, POLL_MS);
  health();
  setInterval(health, 5 * POLL_MS);
}

init();
