// Drag and drop (or choose) images, a zip or an observations JSON; submit them with the board.
import { boardSpec } from "./board.js";
import { chosenSettings } from "./settings.js";

let chosen = [];

function summarise() {
  const total = chosen.reduce((s, f) => s + f.size, 0);
  document.getElementById("file-summary").textContent = chosen.length
    ? `${chosen.length} file(s), ${(total / 1e6).toFixed(1)} MB: ${chosen.slice(0, 3).map((f) => f.name).join(", ")}` +
      (chosen.length > 3 ? ", …" : "")
    : "no files chosen";
}

/** Wire the drop zone and the form; ``onSubmit({form, method, settings})`` does the rest. */
export function initUpload(onSubmit) {
  const drop = document.getElementById("drop"), input = document.getElementById("files");
  input.addEventListener("change", () => { chosen = [...input.files]; summarise(); });
  drop.addEventListener("keydown", (e) => { if (e.key === "Enter" || e.key === " ") { e.preventDefault(); input.click(); } });
  for (const ev of ["dragenter", "dragover"]) drop.addEventListener(ev, (e) => { e.preventDefault(); drop.classList.add("over"); });
  for (const ev of ["dragleave", "drop"]) drop.addEventListener(ev, () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    chosen = [...e.dataTransfer.files];
    summarise();
  });
  document.getElementById("upload-form").addEventListener("submit", async (e) => {
    e.preventDefault();
    const button = document.getElementById("submit");
    button.disabled = true;
    try { await onSubmit(uploadRequest(chosen)); }
    finally { button.disabled = false; }
  });
}

/** What the upload sends for ``files`` (Files or named Blobs): them, the board, the set name, the method and
 * its settings. Dropped photos and camera shots (capture.js) go up through this one path. */
export function uploadRequest(files) {
  const form = new FormData();
  for (const f of files) form.append("files", f, f.name);
  form.append("board", boardSpec());
  const name = document.getElementById("set-name").value.trim();
  if (name) form.append("name", name);
  return { form, ...chosenSettings() };
}
