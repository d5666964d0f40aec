// A done job's results: downloads, metrics tables, the 2-D figures and the 3D view.
import { api, apiUrl } from "./api.js";
import { el } from "./format.js";
import { coverageFigure } from "./plots/coverage.js";
import { fieldMapFigure, fieldVectorsFigure } from "./plots/field.js";
import { heatmapFigure } from "./plots/heatmap.js";
import { knotsFigure } from "./plots/knots.js";
import { rectifiedFigure } from "./plots/rectified.js";
import { uncertaintyFigure } from "./plots/uncertainty.js";
import { vectorsFigure } from "./plots/vectors.js";
import { curationTable } from "./curation.js";
import { renderSetJobs } from "./setjobs.js";
import { modelChoiceTable, overallTable, qualityTable, restartNote, smoothingTable } from "./tables.js";
import { cameraCard } from "./verdict.js";
import { renderViewer } from "./viewer.js";

const LABELS = {
  "calibration.json": "Calibration (JSON)", "opencv.yaml": "OpenCV YAML", "corner_residuals.csv": "Corner residuals (CSV)",
  "corner_residuals.json": "Corner residuals (JSON)", "view_residuals.csv": "Per-view residuals (CSV)",
  "view_residuals.json": "Per-view residuals (JSON)", "comparison.csv": "Comparison (CSV)", "comparison.json": "Comparison (JSON)",
  "heatmap.json": "Heatmap (JSON)", "knots.json": "Knot grid (JSON)", "distortion_field.json": "Distortion field (JSON)",
};

export async function renderResults(job, set) {
  const section = document.getElementById("results");
  section.hidden = false;
  section.dataset.job = job.id;
  // busy until the last figure is in: the tables and figures that arrive later move the ones above them
  section.setAttribute("aria-busy", "true");
  try { await drawResults(job, set); } finally { section.setAttribute("aria-busy", "false"); }
}

async function drawResults(job, set) {
  renderDownloads(job.downloads, job);
  const has = (n) => n in job.downloads;
  const [comparison, views, corners, heatmap, field, knots, calibration] = await Promise.all([
    api.file(job.id, "comparison.json"), has("view_residuals.json") ? api.file(job.id, "view_residuals.json") : [],
    has("corner_residuals.json") ? api.file(job.id, "corner_residuals.json") : [],
    has("heatmap.json") ? api.file(job.id, "heatmap.json") : null,
    has("distortion_field.json") ? api.file(job.id, "distortion_field.json") : null,
    has("knots.json") ? api.knotCells(job.id) : null,
    has("calibration.json") ? api.file(job.id, "calibration.json") : null,
  ]);
  document.getElementById("results-title").textContent = `3. Results: ${resultTitle(job, calibration)}`;
  const metrics = document.getElementById("metrics");
  const who = job.method === "compare" ? ` (${job.summary.verdict})` : "";
  const camera = calibration && (calibration.diagnostics || {}).camera;
  metrics.replaceChildren(calibration ? cameraCard(calibration) : "", overallTable(comparison), views.length ? curationTable(views, job, `Per view${who}`) : "",
    calibration ? restartNote(calibration) : "", calibration ? modelChoiceTable(calibration) : "",
    calibration ? smoothingTable(calibration) : "");
  renderSetJobs(job).catch(() => {});   // the set's other calibrations side by side (a note, never an error)
  const imageSize = heatmap ? heatmap.image_size : set && set.image_size;
  const figs = [];
  if (heatmap) figs.push(heatmapFigure({ heatmap, corners, views }));
  if (corners.length) figs.push(vectorsFigure({ corners, views, set, imageSize }));
  if (field) figs.push(fieldMapFigure({ field }), fieldVectorsFigure({ field }));
  // a knot grid only where a field was fitted (a held field, or none, has nothing to show)
  if (knots && (!camera || camera.field)) figs.push(knotsFigure({ knots, imageSize }));
  if (set && set.coverage && imageSize) figs.push(coverageFigure({ coverage: set.coverage, imageSize }));
  if (set && calibration) figs.push(rectifiedFigure({ job, set }));
  const plots = document.getElementById("plots");
  plots.replaceChildren(...figs.filter(Boolean));
  await renderViewer(job);
  if (calibration) {
    try { metrics.append(qualityTable(await api.quality(job.id))); }
    catch (e) { metrics.append(el("p", { class: "muted" }, `Geometric quality not available: ${e.message}`)); }
  }
  // computed on request (about a second): drawn last, and its failure is a note, not an error
  try { plots.append(uncertaintyFigure({ unc: await api.uncertainty(job.id) })); }
  catch (e) { plots.append(el("p", { class: "muted" }, `Uncertainty map not available: ${e.message}`)); }
}

function renderDownloads(downloads, job) {
  const box = document.getElementById("downloads");
  const order = Object.keys(LABELS).filter((n) => n in downloads).concat(Object.keys(downloads).filter((n) => !(n in LABELS)));
  const maps = "calibration.json" in downloads
    ? el("a", { href: api.mapsUrl(job.id), download: "", "data-file": "maps.npz" }, "Undistortion maps (NPZ)") : "";
  box.replaceChildren(el("strong", {}, "Download:"), ...order.map((n) =>
    el("a", { href: apiUrl(downloads[n]), download: "", "data-file": n }, LABELS[n] || n)), maps);
}

/** The heading says what was chosen, in words: "Kannala-Brandt model (k1..k4), chosen by method auto" —
 * never a method's code name for another model. */
function resultTitle(job, calibration) {
  const camera = calibration && (calibration.diagnostics || {}).camera;
  if (job.method === "compare") {
    return `every method compared` + (job.summary.verdict ? `, the best: ${camera ? camera.model : job.summary.verdict}` : "");
  }
  if (!camera) return `method ${job.method}`;
  return job.method === "auto" ? `${camera.model}, chosen by method auto` : camera.model;
}

export function hideResults() { document.getElementById("results").hidden = true; }
