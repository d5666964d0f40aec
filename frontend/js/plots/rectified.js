// One photo before and after rectification by the job's calibration: straight board
// lines in the right-hand image are what a good calibration buys.
import { api, thumbUrl } from "../api.js";
import { el } from "../format.js";
import { select } from "./canvas.js";

export function rectifiedFigure({ job, set }) {
  const names = (set.images || []).filter((im) => im.status === "used").map((im) => im.name);
  const before = el("img", { alt: "photo as taken", class: "rectified-photo" });
  const after = el("img", { alt: "photo rectified by the calibration", class: "rectified-photo", id: "rectified-after" });
  const show = (name) => { before.src = thumbUrl(set.id, name, 640); after.src = api.rectifiedUrl(job.id, name); };
  const fig = el("figure", { class: "plot", id: "fig-rectified" },
    el("figcaption", {}, el("span", {}, "Rectified photo"),
      select("photo to rectify", names.map((n) => [n, n]), show)),
    el("div", { class: "before-after" },
      el("div", {}, el("p", { class: "note" }, "as taken"), before),
      el("div", {}, el("p", { class: "note" }, "rectified (valid pixels only)"), after)),
    el("p", { class: "note" }, "The right-hand image is the ideal pinhole view the calibration implies: board lines " +
      "should be straight. Undistortion maps for cv2.remap: download maps.npz."));
  if (names.length) show(names[0]);
  return fig;
}
