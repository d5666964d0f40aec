// The calibration judged in one line, above everything else: the model chosen in words,
// why, and the verdict ("0.26 px rms, 0.03 px projection uncertainty over the covered image: good; …").
import { el } from "./format.js";
import { fieldLine, fovLine, matrixBlock, parametersTable } from "./params.js";

const GRADE_WORDS = { fair: "usable, could be better", poor: "not to be trusted yet" };

export function verdictBox(camera) {
  const v = camera.verdict || {};
  const u = camera.projection_uncertainty;
  const spread = u ? el("p", { class: "muted" }, `Projection uncertainty: ${u.median_px.toFixed(3)} px median, ` +
    `${u.p95_px.toFixed(3)} px at the 95th percentile, over the ${(u.covered_share * 100).toFixed(0)} % of the image ` +
    "with a corner nearby (worst direction: how far a direction's pixel would move if the photos were taken again).")
    : el("p", { class: "muted" }, camera.uncertainty_error || "No projection uncertainty for this calibration.");
  return el("div", { id: "verdict", class: `verdict ${v.grade || ""}`, "data-grade": v.grade || "" },
    el("p", { class: "verdict-line" }, el("strong", { id: "verdict-text" }, v.text || ""),
      GRADE_WORDS[v.grade] ? el("span", { class: "muted" }, ` (${GRADE_WORDS[v.grade]})`) : ""),
    spread);
}

/** The whole camera card: model in words, verdict, parameters ± σ, field, field of view, K to copy. */
export function cameraCard(calibration) {
  const camera = (calibration.diagnostics || {}).camera;
  if (!camera) {
    return el("section", { id: "camera", class: "camera" }, el("h3", {}, "Camera"),
      el("p", { class: "muted" }, "This calibration was written without its parameter report (an older file): " +
        "the intrinsics are in the calibration JSON."), matrixBlock(calibration));
  }
  return el("section", { id: "camera", class: "camera", "aria-labelledby": "camera-model" },
    el("h3", { id: "camera-model" }, `Camera: ${camera.model}`),
    el("p", { id: "camera-chosen", class: "muted" }, capitalise(camera.chosen) + "."),
    verdictBox(camera), parametersTable(camera), fieldLine(camera), fovLine(camera), matrixBlock(calibration));
}

const capitalise = (s) => (s ? s[0].toUpperCase() + s.slice(1) : "");
