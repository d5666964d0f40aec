// The 3D view: viser behind the API's /viewer proxy, embedded in an iframe that opens on this job.
import { api, viewerUrl } from "./api.js";
import { showError } from "./errors.js";
import { el } from "./format.js";

export async function renderViewer(job) {
  const box = document.getElementById("viewer3d");
  box.replaceChildren();
  const info = await api.viewer();
  if (!info.enabled) {
    box.append(el("p", { class: "muted" }, "The 3D view is off on this server (FREECAL_VIEWER=0)."));
    return;
  }
  const open = el("button", { type: "button", id: "open-3d" }, "Show in 3D");
  const link = el("a", { href: viewerUrl(info.url), target: "_blank", rel: "noopener" }, "open in a new tab");
  box.append(el("h3", {}, "3D view"),
    el("p", { class: "muted" }, "Camera, every board pose (corners coloured by residual), the knot grid on the ideal " +
      "image plane, residual vectors and the Δx, Δy surfaces. Its panel switches job, method and surfaces. ", link),
    open);
  open.addEventListener("click", async () => {
    // the view opens on the job asked for last (viser cannot read it from the URL)
    try { await api.openViewer(job.id); } catch (e) { showError(e); return; }
    const frame = el("iframe", { class: "viewer-frame", src: viewerUrl(info.url, { job: job.id }), title: `3D view of job ${job.id}` });
    open.replaceWith(frame);
  });
}
