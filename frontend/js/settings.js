// Method choice and its settings. Empty fields are not sent, so the service
// uses the method's own defaults (the paper's); placeholders show them.
import { el } from "./format.js";

const BSPLINE = [
  { key: "knots", label: "Knot placement", options: ["kde", "kde-paper", "uniform"], def: "kde" },
  { key: "intervals", label: "Intervals per axis", placeholder: "auto (validation)", type: "text" },
  { key: "bandwidth", label: "KDE bandwidth", options: ["scott", "silverman"], def: "scott" },
  { key: "bandwidth_factor", label: "Bandwidth factor", placeholder: "1.0 (or auto)", type: "text" },
  { key: "time_budget", label: "Search time budget [s]", placeholder: "none", type: "number" },
  { key: "window_ratio", label: "Window ratio", placeholder: "0.05", type: "number" },
  { key: "weighting", label: "Weighting", options: ["local_std", "uniform", "magnitude", "gradient"], def: "local_std" },
  { key: "lambda_reg", label: "λ reg (L2)", placeholder: "1e-6", type: "number" },
  { key: "lambda_smooth", label: "λ smooth", placeholder: "auto (validation)", type: "text" },
  { key: "core", label: "Parametric core", options: ["none", "rational", "fisheye"], def: "none" },
  { key: "max_iterations", label: "Max iterations", placeholder: "500", type: "number" },
];
const AUTO = [{ key: "decision_views", label: "Views the choice is made on", placeholder: "20", type: "number" }];
const COMMON = [{ key: "max_iterations", label: "Max iterations", placeholder: "default", type: "number" }];
const COMPARE = [{ key: "splits", label: "Cross-validation folds", placeholder: "5", type: "number" }];

export function initMethods(methods) {
  const select = document.getElementById("method");
  select.replaceChildren();
  for (const m of methods.methods) select.append(el("option", { value: m, selected: m === "auto" }, m));
  if (methods.compare) select.append(el("option", { value: "compare" }, "compare all methods"));
  select.addEventListener("change", renderFields);
  renderFields();
}

function fieldsFor(method) {
  return { bspline: BSPLINE, compare: COMPARE, auto: AUTO }[method] || COMMON;
}

function renderFields() {
  const box = document.getElementById("settings-fields");
  box.replaceChildren();
  for (const f of fieldsFor(document.getElementById("method").value)) {
    const id = `setting-${f.key}`;
    const input = f.options
      ? el("select", { id, "data-key": f.key }, f.options.map((o) => el("option", { value: o, selected: o === f.def }, o)))
      : el("input", { id, "data-key": f.key, type: f.type, step: "any", placeholder: f.placeholder });
    box.append(el("div", {}, el("label", { for: id }, f.label), input));
  }
}

/** The settings object for POST /api/jobs: only fields the user changed from the defaults. */
export function chosenSettings() {
  const method = document.getElementById("method").value;
  const out = {};
  for (const f of fieldsFor(method)) {
    const v = document.getElementById(`setting-${f.key}`).value.trim();
    if (v === "" || v === f.def) continue;
    if (f.key === "intervals" && /^\d+x\d+$/.test(v)) out[f.key] = v.split("x").map(Number);
    else if (f.type === "number" || /^[\d.eE+-]+$/.test(v)) out[f.key] = Number(v);
    else out[f.key] = v;
  }
  return { method, settings: out };
}
