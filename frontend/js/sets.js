// The sets list, and one set's detection: progress, warnings, each image with its thumbnail and verdict.
import { thumbUrl } from "./api.js";
import { etaText, observe, remaining } from "./eta.js";
import { el, num } from "./format.js";
import { when } from "./names.js";

export function renderSets(sets, selectedId, onSelect) {
  const ul = document.getElementById("sets");
  ul.replaceChildren(...sets.map((s) => el("li", { class: s.id === selectedId ? "selected" : "" },
    el("button", { type: "button", onclick: () => onSelect(s.id), "aria-label": `set ${s.name}` },
      el("span", { class: "grow" }, `${s.name} · ${when(s.created_at)}`),
      el("span", { class: "muted" }, `${s.n_views}/${s.n_images} views`),
      el("span", { class: `state ${s.state}` }, s.state)))));
  if (!sets.length) ul.append(el("li", { class: "muted" }, el("span", {}, "\u00a0 no sets yet: upload some images")));
}

let shown = "";

export function renderSet(set) {
  // the poll loop calls this every second: redraw only what changed (no thumbnail flicker)
  const sig = JSON.stringify([set.id, set.state, set.progress, set.images, set.warnings, set.error]);
  if (sig === shown) return;
  shown = sig;
  document.getElementById("set-detail").hidden = false;
  document.getElementById("set-detail-title").textContent =
    `Detection: ${set.name} (${set.board ? boardText(set.board) : "corners uploaded"})`;
  document.getElementById("set-progress").value = set.progress;
  const used = (set.images || []).filter((i) => i.status === "used").length;
  const rejected = (set.images || []).filter((i) => i.status === "rejected").length;
  if (set.state === "detecting") observe(`set:${set.id}`, set.progress);
  const eta = set.state === "detecting" ? etaText(remaining(`set:${set.id}`, set.progress, null)) : "";
  document.getElementById("set-progress-label").textContent =
    `${set.state} · ${set.progress.toFixed(0)} % · ${used} used, ${rejected} rejected` + (eta ? ` · ${eta}` : "") +
    (set.image_size ? ` · ${set.image_size[0]}×${set.image_size[1]} px` : "") + (set.error ? ` · ${set.error}` : "");
  const warn = document.getElementById("set-warnings");
  warn.hidden = !set.warnings.length;
  warn.replaceChildren(...set.warnings.map((w) => el("span", { style: "display:block" }, w)));
  const ul = document.getElementById("images");
  ul.replaceChildren(...(set.images || []).map((im) => el("li", { class: im.status },
    el("img", { src: thumbUrl(set.id, im.name), alt: `thumbnail of ${im.name}`, loading: "lazy", width: 150, height: 112 }),
    el("div", { class: "name", title: im.name }, im.name),
    el("div", { class: im.status }, im.status === "used" ? `✓ ${im.n_corners} corners`
      : im.status === "rejected" ? `✗ ${im.reason || "rejected"}` : "waiting…"),
    im.sharpness != null ? el("div", { class: "muted" }, `edge width ${num(im.sharpness, 2)} px (< 3: sharp)`) : null)));
}

function boardText(b) {
  if (b.type === "chessboard") return `chessboard ${b.cols}×${b.rows} inner corners, ${b.square_size} ${b.units}`;
  return `ChArUco ${b.squares_x}×${b.squares_y} squares, ${b.square_size} ${b.units}`;
}
