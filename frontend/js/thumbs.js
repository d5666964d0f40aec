// One photo of the set as the list shows it: the thumbnail with its detected corners drawn over it,
// a name that stays distinguishable, the tick (✓ used / ✗ why not) and a sharpness note worded by
// the same limits as the verdict. A click (or Enter) opens it enlarged.
import { thumbUrl } from "./api.js";
import { drawCorners, overlaidImage } from "./corner_overlay.js";
import { el } from "./format.js";
import { openImage } from "./image_dialog.js";
import { sharpnessNote } from "./sharpness.js";

const DEFAULT_ASPECT = [4, 3];   // until the detection has read the photo's size

/** The <li> of photo ``im`` (the set's report of it) under the shown name ``label``. */
export function thumbItem(setId, im, label, cornersOf) {
  const size = photoSize(im);
  const img = el("img", { src: thumbUrl(setId, im.name), alt: `thumbnail of ${im.name}`, loading: "lazy" });
  const { box, canvas } = overlaidImage(img, size);
  const open = el("button", { type: "button", class: "thumb-open", "aria-label": `enlarge ${im.name}` }, box);
  const li = el("li", { class: im.status, "data-name": im.name },
    open,
    el("div", { class: "name", title: im.name }, label),
    ...notes(im));
  li.thumbCanvas = canvas;
  open.addEventListener("click", () => {
    const points = cornersOf(im.name);
    openImage({ setId, image: im, points, imageSize: size, notes: notes(im), opener: open });
  });
  return li;
}

/** Draw the photo's corners (``points``: [[x, y], ...] px, or null) on its thumbnail; the count goes to data-corners. */
export function showCorners(li, points, imageSize) {
  if (!points) return;
  drawCorners(li.thumbCanvas, points, imageSize);
  li.dataset.corners = String(points.length);
}

function notes(im) {
  const s = im.sharpness == null ? null : sharpnessNote(im.sharpness);
  // rejected for blur: the note under the tick says how blurry, so the tick need not say it twice
  const why = s && s.verdict === "blurry" && (im.reason || "").startsWith("too blurry") ? "too blurry" : im.reason;
  const tick = el("div", { class: `tick ${im.status}` }, im.status === "used" ? `✓ ${im.n_corners} corners`
    : im.status === "rejected" ? `✗ ${why || "rejected"}` : "waiting…");
  if (!s) return [tick];
  return [tick, el("div", { class: `sharpness ${s.verdict}`, "data-verdict": s.verdict }, s.text)];
}

function photoSize(im) {
  return im.width && im.height ? [im.width, im.height] : DEFAULT_ASPECT;
}
