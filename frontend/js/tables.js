// The metrics tables: overall (one row per method when comparing) and per view.
import { el, num, px } from "./format.js";

const OVERALL = [
  ["rmse", "rmse [px]", px], ["rmse_axis", "rmse per axis [px]", px],
  ["rmse_center", "centre rmse [px]", px], ["rmse_edge", "edge rmse [px]", px],
  ["cv_validation_rmse", "hold-out views rmse (CV) [px]", px], ["holdout_rmse", "hold-out set rmse [px]", px],
  ["n_points", "points", num], ["n_params", "fitted parameters", num], ["seconds", "fit time [s]", (x) => num(x, 2)],
];

/** comparison.json of a single job ({rows}) or of a compare job ({methods, verdict}) → rows. */
export function comparisonRows(doc) {
  if (Array.isArray(doc.rows)) return doc.rows;
  return Object.entries(doc.methods || {}).map(([method, r]) => ({ method, ...r }));
}

export function overallTable(doc) {
  const rows = comparisonRows(doc);
  const cols = OVERALL.filter(([k]) => rows.some((r) => r[k] != null));
  const best = doc.verdict;
  const table = el("table", { id: "metrics-overall" },
    el("caption", {}, rows.length > 1 ? `All methods${best ? ` (verdict: ${best}, lowest cross-validated rmse)` : ""}`
      : "Overall"),
    el("thead", {}, el("tr", {}, el("th", { scope: "col" }, "method"), cols.map(([, label]) => el("th", { scope: "col" }, label)))),
    el("tbody", {}, rows.map((r) => el("tr", { class: r.method === best ? "best" : "" },
      el("th", { scope: "row" }, r.method),
      r.error ? el("td", { colspan: cols.length }, r.error) : cols.map(([k, , f]) => el("td", {}, f(r[k])))))));
  const note = el("p", { class: "muted" }, "rmse: per-point Euclidean RMS (OpenCV's figure); per axis: RMS of x and y " +
    "components (mrcal's). Centre: corners in the middle half of the image. CV: each view held out once, model fixed, pose refit. " +
    "Fitted parameters: those the fit moved (a field over a core holds the core's coefficients; a held field counts none).");
  return el("div", { class: "table-wrap" }, table, note);
}

/** The default method's model choice (method "auto"): each candidate's error on views left out of its fit,
 * ± one standard error, and the rule that decided. */
export function modelChoiceTable(calibration) {
  const choice = (calibration.diagnostics || {}).model_choice;
  if (!choice) return "";
  const table = el("table", { id: "metrics-model-choice" },
    el("caption", {}, `Model chosen: ${choice.summary}`),
    el("thead", {}, el("tr", {}, ["candidate", "validation rmse per axis [px]", "± one standard error of its excess",
      "parameters", ""].map((h) => el("th", { scope: "col" }, h)))),
    el("tbody", {}, choice.candidates.map((c) => el("tr", { class: c.chosen ? "best" : "" },
      el("th", { scope: "row" }, c.label),
      el("td", {}, c.validation_rmse == null ? "—" : num(c.validation_rmse, 4)),
      el("td", {}, c.standard_error_rmse == null ? "—" : `± ${num(c.standard_error_rmse, 4)}`),
      el("td", {}, c.n_params == null ? "—" : num(c.n_params)),
      el("td", {}, choiceStatus(c, choice.candidates))))));
  const note = el("p", { class: "muted" }, `How: ${choice.how}. Rule: ${choice.rule}.`);
  return el("div", { class: "table-wrap" }, table, note);
}

/** A candidate's standing in the model choice, in page words (as ``ChoiceReport.status`` words it). */
function choiceStatus(c, candidates) {
  if (c.chosen) return "chosen";
  if (c.error) return c.error;
  if (c.beaten_by) {
    const simpler = candidates.find((o) => o.name === c.beaten_by);
    return `the simpler ${simpler ? simpler.label : c.beaten_by} predicts better`;
  }
  return c.within_noise ? "within the noise" : "";
}

/** A field fit that walked to a wrong camera: why it was restarted, which fit was kept, and what to do. */
export function restartNote(calibration) {
  const r = (calibration.diagnostics || {}).restart;
  if (!r) return "";
  const kept = r.kept === "restarted" ? "the restarted fit was kept" : "the restart did no better; the first fit was kept";
  return el("p", { id: "restart-note", class: r.warning ? "warning" : "muted" },
    `The field's fit was restarted from a parametric camera: ${r.reason}; ${kept} ` +
    `(${num(r.first.rmse, 3)} px, then ${num(r.restarted.rmse, 3)} px).` + (r.warning ? ` Warning: ${r.warning}.` : ""));
}

/** A grid's score: the joint fit's error on the views left out when there is one (what chose), else the control points'. */
const mse = (c) => (c.validation != null ? c.validation : c.cv);

/** The B-spline's knot-grid and bandwidth choice: error on views left out of the field's fit (lower is better). */
export function smoothingTable(calibration) {
  const curve = (calibration.diagnostics || {}).smoothing_curve || [];
  if (!curve.length) return "";
  const settings = calibration.settings || {};
  // A candidate is the grid and the Scott factor it was placed with (older files have no factor: undefined on both sides).
  const isChosen = (c) => JSON.stringify(c.intervals) === JSON.stringify(settings.intervals_used)
    && c.bandwidth_factor === settings.bandwidth_factor_used && !c.skipped;
  const table = el("table", { id: "metrics-smoothing" },
    el("caption", {}, "Knot grid and bandwidth chosen from the data (validation over the views)"),
    el("thead", {}, el("tr", {}, ["knot grid", "bandwidth factor", "smoothing λ", "validation error [px²]", "as rms per axis [px]",
      "effective parameters", ""]
      .map((h) => el("th", { scope: "col" }, h)))),
    el("tbody", {}, curve.map((c) => el("tr", { class: isChosen(c) ? "best" : "" },
      el("th", { scope: "row" }, c.intervals.join(" × ")), el("td", {}, num(c.bandwidth_factor, 1)),
      el("td", {}, num(c.lambda_smooth, 3)), el("td", {}, num(mse(c), 4)),
      el("td", {}, mse(c) == null ? "–" : num(Math.sqrt(mse(c) / 2), 4)), el("td", {}, num(c.dof, 0)),
      el("td", {}, isChosen(c) ? "chosen" : c.skipped ? `skipped (${c.skipped})` : "")))));
  const note = el("p", { class: "muted" }, "Validation error: the mean squared error of the views left out, in px² " +
    "(squared pixels, both axes summed per corner); its rms per axis, √(px² / 2), is in pixels like every other error " +
    "here. Effective parameters: what the field costs the data once smoothed.");
  return el("div", { class: "table-wrap" }, table, note);
}

/** Straightness, spacing and orthogonality of the boards, rectified by the calibration and as photographed. */
export function qualityTable(q) {
  const rows = [["raw photos", q.raw], [`rectified by ${q.method}`, q.calibrated]];
  const table = el("table", { id: "metrics-quality" },
    el("caption", {}, "Geometric quality of the rectified boards"),
    el("thead", {}, el("tr", {}, ["", "straightness [px]", "spacing CV", "orthogonality [°]", "field smoothness [1/px]"]
      .map((h) => el("th", { scope: "col" }, h)))),
    el("tbody", {}, rows.map(([label, r]) => el("tr", {}, el("th", { scope: "row" }, label),
      el("td", {}, num(r.straightness, 3)), el("td", {}, num(r.spacing_cv, 4)), el("td", {}, num(r.orthogonality, 3)),
      el("td", {}, num(r.smoothness, 5))))));
  const note = el("p", { class: "muted" }, "Straightness: RMS distance of rectified corners from the line through " +
    "their board row or column; spacing CV: spread of neighbour distances; orthogonality: mean departure of row " +
    "and column lines from 90°. Lower is better in every column.");
  return el("div", { class: "table-wrap" }, table, note);
}
