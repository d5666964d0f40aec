// The camera the calibration found, as every peer leads with it: the model in words, each
// parameter with ± one standard deviation, the camera matrix to copy, the field of view.
// Everything comes from the calibration JSON's diagnostics.camera, shown as it holds it.
import { el, num } from "./format.js";

/** Digits that show a value to its uncertainty: two significant digits of σ (or 6 significant without one). */
export function digitsFor(value, std) {
  if (std && std > 0) return Math.max(0, Math.min(8, 1 - Math.floor(Math.log10(std))));
  const mag = Math.abs(value) > 0 ? Math.floor(Math.log10(Math.abs(value))) : 0;
  return Math.max(0, Math.min(8, 5 - mag));
}

function fixed(x, digits) {
  if (x === 0) return "0";
  // coefficients like 1e-5 keep two significant digits rather than reading 0.0000
  return Math.abs(x) > 0 && Math.abs(x) < 10 ** -digits ? x.toExponential(1) : x.toFixed(digits);
}

function parameterRow(p) {
  const d = digitsFor(p.value, p.std);
  const std = p.std == null ? "—" : `± ${fixed(p.std, Math.max(d, 0))}`;
  return el("tr", { "data-name": p.name, class: p.status === "fitted" ? "" : "muted-row" },
    el("th", { scope: "row" }, p.name),
    el("td", { class: "value", "data-value": String(p.value), title: String(p.value) }, fixed(p.value, d)),
    el("td", { class: "std", "data-std": p.std == null ? "" : String(p.std) }, std),
    el("td", {}, p.unit || ""),
    el("td", { class: "note" }, p.note || ""));
}

export function parametersTable(camera) {
  const rows = camera.parameters || [];
  const groups = [["intrinsics", "Camera matrix"], ["distortion", "Distortion coefficients"]];
  const table = el("table", { id: "camera-params" },
    el("caption", {}, "Parameters, ± one standard deviation"),
    el("thead", {}, el("tr", {}, ["", "value", "± 1 σ", "unit", ""].map((h) => el("th", { scope: "col" }, h)))),
    groups.map(([g, title]) => {
      const mine = rows.filter((p) => p.group === g);
      return mine.length ? el("tbody", { "data-group": g },
        el("tr", { class: "group" }, el("th", { colspan: 5, scope: "colgroup" }, title)), mine.map(parameterRow)) : "";
    }));
  const sigma = camera.sigma_px != null
    ? `σ from the fit's residuals: ${num(camera.sigma_px, 3)} px per axis; ${num(camera.effective_parameters, 1)} ` +
      `effective parameters (${camera.fitted_parameters} fitted). `
    : "";
  const note = el("p", { class: "muted" }, `${sigma}± is one standard deviation from the solution's covariance ` +
    "(the poses marginalised): how far each value would move if the corners were measured again. " +
    "Held or fixed values have none.");
  return el("div", { class: "table-wrap" }, table, note);
}

/** K and the distortion vector, in the order OpenCV's functions take them (when the model is OpenCV's or Kannala–Brandt). */
export function matrixBlock(calibration) {
  const k = calibration.intrinsics, d = calibration.distortion || {};
  const coeffs = d.type === "opencv" || d.type === "fisheye" ? d.coefficients : d.type === "hybrid" ? d.core.coefficients : null;
  const f = (x) => Number(x).toPrecision(10).replace(/\.?0+$/, "");
  const text = `K = [[${f(k.fx)}, ${f(k.skew || 0)}, ${f(k.cx)}],\n     [0, ${f(k.fy)}, ${f(k.cy)}],\n     [0, 0, 1]]` +
    (coeffs ? `\n${d.type === "fisheye" || (d.core && d.core.type === "fisheye") ? "D" : "dist"} = [${coeffs.map(f).join(", ")}]` : "") +
    (d.type === "hybrid" ? "\n(+ the B-spline field: in calibration.json)" : "");
  return el("details", { class: "matrix" }, el("summary", {}, "Camera matrix to copy"), el("pre", { id: "camera-matrix" }, text));
}

export function fovLine(camera) {
  const fov = camera.field_of_view_deg || {};
  const far = camera.no_ray_beyond_px || {};
  const part = (name) => fov[name] != null ? `${fov[name].toFixed(1)}° ${name}`
    : `${name}: no ray past ${far[name] != null ? `${far[name].toFixed(0)} px from the principal point` : "the model's reach"}`;
  const reach = camera.max_corner_angle_deg != null
    ? ` The corners reach ${camera.max_corner_angle_deg.toFixed(1)}° off axis.` : "";
  return el("p", { id: "camera-fov" }, el("strong", {}, "Field of view: "),
    ["horizontal", "vertical", "diagonal"].map(part).join(", ") + ".",
    el("span", { class: "muted" }, ` From the model's own rays across the image's midlines and diagonal.${reach}`));
}

export function fieldLine(camera) {
  const f = camera.field;
  if (!f) return "";
  const grid = f.knot_intervals ? `${f.knot_intervals.join(" × ")} knot intervals (${f.control_points.join(" × ")} control points), ` : "";
  const size = f.largest_offset_px != null
    ? `offsets up to ${f.largest_offset_px.toFixed(2)} px (median ${f.median_offset_px.toFixed(2)} px) over the image`
    : `${f.centres} centres`;
  return el("p", { id: "camera-field" }, el("strong", {}, `${f.type} field `), `over ${f.over}: ${grid}${size}.`);
}
