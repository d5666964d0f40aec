// The 3D view: viser behind the API's /viewer proxy, in an iframe or a new tab, opened on the job on screen
// (a calibration in the Results card, a rig in the Rig card).
import { api, viewerUrl } from "./api.js";
import { el } from "./format.js";
import { PAIR, followSelection } from "./viewsync.js";

export async function renderViewer(job) {
  const box = document.getElementById("viewer3d");
  // the job and this page's pairing key ride in the view's URL: each tab opens on this job, and
  // the view selected here (a row of the per-view table) is the one highlighted there, and back
  const ok = await openers(box, { job: job.id, pair: PAIR }, { id: "open-3d", title: "3D view of this calibration",
    what: "The camera at the origin (frustum, axes), every board pose in its own colour with " +
      "its photo's name (click one: its row is picked in the per-view table; pick a row: its board turns gold), " +
      "residual vectors and the knot grid on the ideal image plane, and the Δx, Δy surfaces under the rig. " +
      "Its panel switches job, method, surfaces and layers. " });
  if (ok) followSelection(job.id);
}

/** The 3D view of a done rig job, in ``box``: its cameras and the board at its frames (no pairing: a rig
 * has no per-view table). */
export async function renderRigViewer(job, box) {
  await openers(box, { job: job.id }, { id: "rig-open-3d", title: "3D view of this rig",
    what: "Every camera of the rig as a frustum in its own colour with its name, placed from the reference " +
      "camera (at the origin, with its axes), and the board at every frame the rig used, one colour per frame. " +
      "Its panel switches to other jobs. " });
}

/** "Show in 3D" (embeds the view in ``box``) and "open in a new tab" for the view opened with ``params``;
 * false when the 3D view is off on this server (said in ``box``). */
async function openers(box, params, { id, title, what }) {
  box.replaceChildren();
  const info = await api.viewer();
  if (!info.enabled) {
    box.append(el("p", { class: "muted" }, "The 3D view is off on this server (FREECAL_VIEWER=0)."));
    return false;
  }
  const url = viewerUrl(info.url, params);
  const open = el("button", { type: "button", id }, "Show in 3D");
  const link = el("a", { href: url, target: "_blank", rel: "noopener", id: `${id}-tab` }, "open in a new tab");
  box.append(el("h3", {}, "3D view"), el("p", { class: "muted" }, what, link), open);
  open.addEventListener("click", () => {
    const frame = el("iframe", { class: "viewer-frame", src: url, title });
    open.replaceWith(frame);
  });
  return true;
}
