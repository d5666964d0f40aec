// One photo of the set enlarged: the 640 px image with its detected corners, its full name,
// tick and sharpness, in a modal <dialog> (Escape closes it, as the Close button and a click beside it do;
// focus goes back to the thumbnail that opened it).
import { thumbUrl } from "./api.js";
import { drawCorners, overlaidImage } from "./corner_overlay.js";
import { el } from "./format.js";

const ENLARGED = 640;   // the thumbnail endpoint's larger size

let dialog = null;

function theDialog() {
  if (dialog) return dialog;
  dialog = el("dialog", { id: "image-dialog", class: "image-dialog", "aria-labelledby": "image-dialog-title" });
  // the dialog's content fills it, so a click whose target is the dialog itself fell on the backdrop
  dialog.addEventListener("click", (e) => { if (e.target === dialog) dialog.close(); });
  document.body.append(dialog);
  return dialog;
}

/** Open ``image`` (the set's report of it) of set ``setId``; ``points``: its corners or null;
 * ``notes``: elements shown under it (tick, sharpness); ``opener``: focused again on close. */
export function openImage({ setId, image, points, imageSize, notes, opener }) {
  const d = theDialog();
  const n = points ? points.length : 0;
  const img = el("img", { src: thumbUrl(setId, image.name, ENLARGED),
    alt: n ? `${image.name} with its ${n} detected corners marked` : image.name });
  const { box, canvas } = overlaidImage(img, imageSize, 2 * ENLARGED);
  if (points) drawCorners(canvas, points, imageSize);
  d.dataset.name = image.name;
  d.dataset.corners = String(n);
  const close = el("button", { type: "button", class: "close", onclick: () => d.close() }, "Close");
  d.replaceChildren(el("div", { class: "image-dialog-body" },
    el("div", { class: "image-dialog-head" }, el("h3", { id: "image-dialog-title" }, image.name), close),
    box, ...notes));
  d.onclose = () => opener && opener.focus();
  d.showModal();
  close.focus();
}
