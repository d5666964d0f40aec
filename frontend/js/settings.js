// Method choice and its settings. Empty fields are not sent, so the service
// uses the method's own defaults (the paper's); placeholders show them.
import { el } from "./format.js";

const BSPLINE = [
  { key: "knots", label: "Knot placement", options: ["kde", "kde-paper", "uniform"], def: "kde",
    help: "Where the knot lines go: kde follows the corners' density, kde-paper the paper's candidates only, uniform an even grid." },
  { key: "intervals", label: "Intervals per axis", placeholder: "auto (validation)", type: "text",
    help: "Knot intervals across × down, e.g. 8x6; empty: chosen by how well the field predicts views left out." },
  { key: "bandwidth", label: "KDE bandwidth", options: ["scott", "silverman"], def: "scott",
    help: "The rule for the corner density's smoothing width when placing knots." },
  { key: "bandwidth_factor", label: "Bandwidth factor", placeholder: "1.0 (or auto)", type: "text",
    help: "Multiplies that width; auto chooses it together with the intervals." },
  { key: "time_budget", label: "Search time budget [s]", placeholder: "none", type: "number",
    help: "Seconds the search over knot grids may take; empty: no limit." },
  { key: "window_ratio", label: "Window ratio", placeholder: "0.05", type: "number",
    help: "Size of the window (share of the image) the residuals' local spread is measured in, for the weights." },
  { key: "weighting", label: "Weighting", options: ["local_std", "uniform", "magnitude", "gradient"], def: "local_std",
    help: "How corners weigh in the field's fit: by the local spread of residuals, evenly, by residual size or by its gradient." },
  { key: "lambda_reg", label: "λ reg (L2)", placeholder: "1e-6", type: "number",
    help: "Pull of every control value towards the prior field; tiny, it only keeps empty cells determined." },
  { key: "lambda_smooth", label: "λ smooth", placeholder: "auto (validation)", type: "text",
    help: "How smooth the field must be (weight of its bending energy); empty: chosen by validation over the views." },
  { key: "core", label: "Parametric core", options: ["none", "zhang", "rational", "fisheye"], def: "none",
    help: "A textbook model under the field: none (the paper's field on the pinhole), OpenCV's 5 coefficients (zhang), its rational model or Kannala–Brandt." },
  { key: "max_iterations", label: "Max iterations", placeholder: "500", type: "number",
    help: "Cap on the solver's iterations (it usually stops well before)." },
];
const AUTO = [{ key: "decision_views", label: "Views the choice is made on", placeholder: "20", type: "number",
  help: "On a larger set the model is chosen on this many views spread over it, then fitted to all of them." }];
const COMMON = [{ key: "max_iterations", label: "Max iterations", placeholder: "default", type: "number",
  help: "Cap on the solver's iterations (it usually stops well before)." }];
const COMPARE = [{ key: "splits", label: "Cross-validation folds", placeholder: "5", type: "number",
  help: "Each view is left out of one fold's fit and scored on it; 0 skips the cross-validation." }];

// one line per method, under the method's select
export const METHOD_HELP = {
  auto: "Fits OpenCV's models, Kannala–Brandt and B-spline fields, keeps the simplest that predicts views left out as well as the best.",
  bspline: "The paper's B-spline distortion field (optionally over a textbook core): settings below.",
  zhang: "OpenCV's calibrateCamera model: 5 coefficients (k1, k2, p1, p2, k3), for ordinary lenses.",
  rational: "OpenCV's rational model: 8 coefficients, for strong barrel distortion.",
  fisheye: "Kannala–Brandt (OpenCV's fisheye model): an angle polynomial, for wide and fisheye lenses.",
  mls: "OpenCV's model plus a moving-least-squares field fitted to its residuals.",
  tps: "OpenCV's model plus a thin-plate-spline field fitted to its residuals.",
  compare: "Every method on the same corners, cross-validated, with a verdict: slow (minutes).",
};

let calibrationForm = () => ({ method: "auto", settings: {} });   // settingsForm's reader, once initMethods ran

/** The calibration form's method and settings (ids ``method``, ``settings-fields``, ``setting-KEY``). */
export function initMethods(methods) {
  const select = document.getElementById("method");
  select.replaceChildren();
  for (const m of methods.methods) select.append(el("option", { value: m, selected: m === "auto" }, m));
  if (methods.compare) select.append(el("option", { value: "compare" }, "compare all methods"));
  calibrationForm = settingsForm(select, document.getElementById("settings-fields"), "setting");
}

/** The settings object for POST /api/jobs from the calibration form: only fields the user changed from the defaults. */
export function chosenSettings() {
  return calibrationForm();
}

/** A method ``select`` and the settings fields in ``box`` that follow it (ids ``PREFIX-KEY``), each with its
 * one-line help, and the method's own help under the select. Returns what POST /api/jobs takes from them:
 * ``{method, settings}``, only the fields changed from their defaults (empty ones: the method's own). */
export function settingsForm(select, box, prefix) {
  const render = () => {
    methodHelp(select);
    box.replaceChildren();
    for (const f of fieldsFor(select.value)) {
      const id = `${prefix}-${f.key}`;
      const described = { "aria-describedby": `${id}-help` };
      const input = f.options
        ? el("select", { id, "data-key": f.key, ...described }, f.options.map((o) => el("option", { value: o, selected: o === f.def }, o)))
        : el("input", { id, "data-key": f.key, type: f.type, step: "any", placeholder: f.placeholder, ...described });
      box.append(el("div", {}, el("label", { for: id }, f.label), input, el("small", { id: `${id}-help`, class: "help" }, f.help)));
    }
  };
  select.addEventListener("change", render);
  render();
  return () => {
    const method = select.value, out = {};
    for (const f of fieldsFor(method)) {
      const v = document.getElementById(`${prefix}-${f.key}`).value.trim();
      if (v === "" || v === f.def) continue;
      if (f.key === "intervals" && /^\d+x\d+$/.test(v)) out[f.key] = v.split("x").map(Number);
      else if (f.type === "number" || /^[\d.eE+-]+$/.test(v)) out[f.key] = Number(v);
      else out[f.key] = v;
    }
    return { method, settings: out };
  };
}

function methodHelp(select) {
  const id = `${select.id}-help`;
  let help = document.getElementById(id);
  if (!help) {
    help = el("small", { id, class: "help" });
    select.after(help);
    select.setAttribute("aria-describedby", id);
  }
  help.textContent = METHOD_HELP[select.value] || "";
}

function fieldsFor(method) {
  return { bspline: BSPLINE, compare: COMPARE, auto: AUTO }[method] || COMMON;
}
