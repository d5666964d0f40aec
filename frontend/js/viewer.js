// The 3D view: viser behind the API's /viewer proxy, in an iframe or a new tab, opened on the job on screen.
import { api, viewerUrl } from "./api.js";
import { el } from "./format.js";
import { PAIR, followSelection } from "./viewsync.js";

export async function renderViewer(job) {
  const box = document.getElementById("viewer3d");
  box.replaceChildren();
  const info = await api.viewer();
  if (!info.enabled) {
    box.append(el("p", { class: "muted" }, "The 3D view is off on this server (FREECAL_VIEWER=0)."));
    return;
  }
  // the job and this page's pairing key ride in the view's URL: each tab opens on this job, and
  // the view selected here (a row of the per-view table) is the one highlighted there, and back
  const url = viewerUrl(info.url, { job: job.id, pair: PAIR });
  const open = el("button", { type: "button", id: "open-3d" }, "Show in 3D");
  const link = el("a", { href: url, target: "_blank", rel: "noopener", id: "open-3d-tab" }, "open in a new tab");
  box.append(el("h3", {}, "3D view"),
    el("p", { class: "muted" }, "The camera at the origin (frustum, axes), every board pose in its own colour with " +
      "its photo's name (click one: its row is picked in the per-view table; pick a row: its board turns gold), " +
      "residual vectors and the knot grid on the ideal image plane, and the Δx, Δy surfaces under the rig. " +
      "Its panel switches job, method, surfaces and layers. ", link),
    open);
  followSelection(job.id);
  open.addEventListener("click", () => {
    const frame = el("iframe", { class: "viewer-frame", src: url, title: "3D view of this calibration" });
    open.replaceWith(frame);
  });
}
