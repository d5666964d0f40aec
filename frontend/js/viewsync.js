// The view selected on this page and in its 3D view, kept in step: a row picked in the per-view table
// is posted (its board turns gold in 3D); a board clicked in 3D comes back by polling (its row is picked).
import { api } from "./api.js";

/** This page's pairing key (random per load; crypto.getRandomValues works on plain http too). */
export const PAIR = Array.from(crypto.getRandomValues(new Uint8Array(12)), (b) => b.toString(16).padStart(2, "0")).join("");
const POLL_MS = 1500;
let state = { job: null, view: null, seq: 0, timer: null };

/** Follow the selection for ``jobId``'s per-view table (again from scratch when the job on screen changes). */
export function followSelection(jobId) {
  if (state.job === jobId) return;
  clearInterval(state.timer);
  state = { job: jobId, view: null, seq: 0, timer: setInterval(poll, POLL_MS) };
}

document.addEventListener("click", async (event) => {
  const row = event.target.closest && event.target.closest("#metrics-views tbody tr[data-view]");
  if (!row || event.target.closest("input, button, a")) return;   // the use tick-box keeps its own meaning
  state.view = row.dataset.view;
  mark();
  try { state.seq = Math.max(state.seq, (await api.selectView(PAIR, state.view)).seq); } catch { /* 3D view off: nothing to tell */ }
});

async function poll() {
  if (document.hidden || !document.querySelector("#viewer3d .viewer-frame, #open-3d-tab")) return;
  let got;
  try { got = await api.viewSelection(PAIR); } catch { return; }
  if (got.seq > state.seq) {
    state.seq = got.seq;
    state.view = got.view;
    const row = mark();
    if (row && got.source === "3d") row.scrollIntoView({ block: "nearest" });
  }
  else mark();   // the table may have been redrawn (sorted): pick the row again
}

function mark() {
  let picked = null;
  for (const row of document.querySelectorAll("#metrics-views tbody tr[data-view]")) {
    const on = row.dataset.view === state.view;
    row.classList.toggle("view-selected", on);
    if (on) { row.setAttribute("aria-selected", "true"); picked = row; } else row.removeAttribute("aria-selected");
  }
  return picked;
}
