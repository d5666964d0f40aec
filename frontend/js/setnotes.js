// What the selected set says beyond its thumbnails: the files its upload skipped (and why),
// and the board size its photos show when it is not the one given, with a button that detects
// the photos again with that size and calibrates them as before (no new upload).
import { api } from "./api.js";
import { clearError, showError } from "./errors.js";
import { el } from "./format.js";

let shown = "";

/** Draw the notes of ``set`` (GET /api/sets/{id}); ``jobs``: every job, to re-run the set's last calibration. */
export function renderSetNotes(set, jobs) {
  const sig = JSON.stringify([set.id, set.state, set.skipped, set.board_suggestion]);
  if (sig === shown) return;
  shown = sig;
  const box = document.getElementById("set-notes");
  box.replaceChildren(skippedNote(set.skipped || []), suggestionNote(set, jobs));
}

function skippedNote(skipped) {
  if (!skipped.length) return "";
  const items = skipped.map((s) => el("li", {}, el("strong", {}, s.name), `: ${s.reason}`));
  const title = `${skipped.length} file${skipped.length > 1 ? "s" : ""} of the upload ${skipped.length > 1 ? "were" : "was"} ` +
    "not used; the others were:";
  return el("div", { id: "skipped-files", class: "note-box" }, el("p", {}, title),
    skipped.length > 6 ? el("details", {}, el("summary", {}, "show them"), el("ul", {}, items)) : el("ul", {}, items));
}

function suggestionNote(set, jobs) {
  const s = set.board_suggestion;
  if (!s || ["queued", "detecting"].includes(set.state)) return "";
  const given = set.board ? `${set.board.cols} × ${set.board.rows}` : "the size given";
  const button = el("button", { type: "button", id: "use-board-size", class: "primary-inline" },
    `Detect again with ${s.cols} × ${s.rows}`);
  button.addEventListener("click", () => redetect(set, s, jobs, button));
  return el("div", { id: "board-suggestion", class: "note-box suggest", role: "status" },
    el("p", {}, el("strong", {}, `Found ${s.cols} × ${s.rows} inner corners in ${s.n_photos} of ${s.n_images} photos: use that?`),
      ` The board was given as ${given} inner corners. A chessboard's size counts the inner corners ` +
      "(where four squares meet), one less than its squares each way."),
    button);
}

async function redetect(set, suggestion, jobs, button) {
  clearError();
  button.disabled = true;
  try {
    await api.detectAgain(set.id, suggestion.spec);
    syncBoardForm(suggestion);
    // the set's last calibration again, on the new corners: it waits for the detection to end
    const last = jobs.find((j) => j.kind === "calibrate" && j.set_id === set.id);
    const job = await api.createJob({ set_id: set.id, method: last ? last.method : "auto",
      settings: last ? last.settings : {} });
    document.dispatchEvent(new CustomEvent("freecal:job-created", { detail: { id: job.id } }));
  } catch (e) { showError(e); button.disabled = false; }
}

/** The board fields follow: the next upload of this camera uses the size that worked. */
function syncBoardForm(s) {
  const cols = document.getElementById("board-cols"), rows = document.getElementById("board-rows");
  if (document.getElementById("board-type").value !== "chessboard") return;
  cols.value = s.cols; rows.value = s.rows;
  cols.dispatchEvent(new Event("input"));
}
