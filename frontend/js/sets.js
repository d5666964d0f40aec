// The sets list, and one set's detection: progress, warnings, each image with its thumbnail and verdict
// (thumbs.js), the set's corners drawn over the thumbnails once the detection has ended.
import { api } from "./api.js";
import { etaText, observe, remaining } from "./eta.js";
import { el } from "./format.js";
import { shortNames, when } from "./names.js";
import { showCorners, thumbItem } from "./thumbs.js";

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

/** No set shown (the one shown was deleted). */
export function hideSet() {
  shown = "";
  document.getElementById("set-detail").hidden = true;
}

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
  // one line each (a class, not a style attribute: the page's CSP refuses those)
  warn.replaceChildren(...set.warnings.map((w) => el("span", { class: "line" }, w)));
  const images = set.images || [];
  const labels = shortNames(images.map((im) => im.name), 20);
  const cornersOf = (name) => (corners.key === cornersKey(set) && corners.byName ? corners.byName.get(name) || null : null);
  document.getElementById("images").replaceChildren(
    ...images.map((im) => thumbItem(set.id, im, labels.get(im.name), cornersOf)));
  loadCorners(set);
}

// The set's corners (its observations), fetched once per detection and drawn on every thumbnail.
let corners = { key: "", byName: null, imageSize: null };

function cornersKey(set) {
  return `${set.id} ${JSON.stringify((set.images || []).map((im) => [im.name, im.status, im.n_corners]))}`;
}

async function loadCorners(set) {
  if (set.state !== "ready" || !set.n_views) return;   // the corners file is written when the detection ends
  const key = cornersKey(set);
  if (corners.key !== key) {
    corners = { key, byName: null, imageSize: null };
    let obs;
    try { obs = await api.observations(set.id); } catch { return; }   // no corners file: the thumbnails stay plain
    if (corners.key !== key) return;   // another set (or detection) was shown meanwhile
    corners = { key, byName: new Map(obs.views.map((v) => [v.name, v.image_points])), imageSize: obs.image_size };
  }
  if (!corners.byName) return;
  for (const li of document.querySelectorAll("#images li[data-name]")) {
    showCorners(li, corners.byName.get(li.dataset.name) || null, corners.imageSize);
  }
}

function boardText(b) {
  if (b.type === "chessboard") return `chessboard ${b.cols}×${b.rows} inner corners, ${b.square_size} ${b.units}`;
  return `ChArUco ${b.squares_x}×${b.squares_y} squares, ${b.square_size} ${b.units}`;
}
