// The lens's distortion over the image, in the views distortion_field.json holds (calib_core/report/distortion.py):
// against the pinhole (Δx, Δy px), the field's own part over its core (px), and the lens as angles (θ, and
// θ − r/f against the equidistant lens, in degrees: what reads on a wide lens). The map opens on the view that
// reads on this lens; its colour scale is the file's, the one the 3D view's surfaces use.
import { ImagePlot, arrow, figure, select } from "./canvas.js";
import { diverging, percentile, sequential } from "./colormap.js";

const COMPONENTS = {
  pinhole: [["dx", "Δx against the pinhole"], ["dy", "Δy against the pinhole"]],
  field: [["dx", "Δx, the field's own part"], ["dy", "Δy, the field's own part"]],
  angle: [["dtheta", "θ − r/f, against the equidistant lens"], ["theta", "θ, angle off axis"]],
};
const NOTES = {
  pinhole: "Observed pixel minus its ideal pinhole pixel.",
  field: "Observed pixel minus the core's pixel: what the field adds to its parametric core.",
  angle: "Each pixel's angle off axis θ; θ − r/f is its departure from the equidistant lens (r: pixels from the " +
    "principal point, f: focal length), which stays a few degrees where a pinhole view runs to hundreds of pixels.",
};

/** distortion_field.json → {maps, default}; files written before maps existed hold the pinhole view alone. */
function mapsOf(field) {
  if (field.maps) return { maps: field.maps, def: field.default };
  const vals = [...field.dx, ...field.dy].filter((x) => x != null).map(Math.abs);
  return { maps: { pinhole: { label: "against the pinhole", unit: "px", dx: field.dx, dy: field.dy, scale: percentile(vals, 98) } },
    def: "pinhole" };
}

function cellIndex(field, u, v) {
  const [nu, nv] = field.grid, [w, h] = field.image_size;
  const i = Math.round(u / ((w - 1) / (nu - 1))), j = Math.round(v / ((h - 1) / (nv - 1)));
  return Math.min(nv - 1, Math.max(0, j)) * nu + Math.min(nu - 1, Math.max(0, i));
}

export function fieldMapFigure({ field }) {
  const [w, h] = field.image_size, [nu, nv] = field.grid;
  const { maps, def } = mapsOf(field);
  const options = Object.keys(COMPONENTS).filter((k) => maps[k])
    .flatMap((k) => COMPONENTS[k].map(([c, text]) => [`${k}:${c}`, text]));
  const first = `${def}:${COMPONENTS[def][0][0]}`;
  const control = select("distortion view", options, (key) => draw(key));
  control.value = first;
  const title = document.createElement("span");
  const { fig, canvas } = figure("Distortion", { label: "map of the lens's distortion", controls: [control], note: " " });
  fig.querySelector("figcaption span").replaceWith(title);
  fig.id = "fig-field";
  const note = fig.querySelector(".note");
  const cw = (w - 1) / (nu - 1), ch = (h - 1) / (nv - 1);
  function draw(key) {
    const [name, comp] = key.split(":"), m = maps[name];
    const values = m[comp];
    const unit = m.unit, angle = name === "angle";
    const reach = angle && m.reach_deg != null ? m.reach_deg : Infinity;
    const absolute = comp === "theta";
    const top = absolute ? Math.max(1, Math.min(m.theta_max || 90, Number.isFinite(reach) ? reach : 180)) : m.scale;
    const colour = (x) => (absolute ? sequential(x, top) : diverging(x, top));
    title.textContent = `Distortion: ${m.label}`;
    fig.dataset.view = key;
    fig.dataset.unit = unit;
    fig.dataset.scale = String(top);
    const label = `${options.find(([k]) => k === key)[1].split(",")[0]} [${unit}]`;
    const p = new ImagePlot(canvas, [0, w, 0, h], absolute ? { map: colour, min: 0, max: top, label }
      : { map: colour, min: -top, max: top, label });
    p.clip((c) => {
      for (let k = 0; k < field.u.length; k++) {
        const val = values[k];
        const beyond = angle && m.theta[k] != null && m.theta[k] > reach;
        c.globalAlpha = beyond ? 0.35 : 1;
        c.fillStyle = val == null ? "#e6e6e6" : colour(val);
        c.fillRect(p.x(field.u[k] - cw / 2), p.y(field.v[k] - ch / 2), p.k * cw + 0.6, p.k * ch + 0.6);
      }
      c.globalAlpha = 1;
    });
    p.axes();
    const scale = absolute ? `0–${top.toFixed(0)}°` : `±${top < 10 ? top.toFixed(2) : top.toFixed(1)} ${unit}`;
    note.textContent = `${NOTES[name]} Colour scale ${scale}` + (absolute ? "." : " (98th percentile; larger values saturate).") +
      (angle && Number.isFinite(reach) ? ` Pale: past the corners' farthest angle (${reach.toFixed(0)}°), where the model extrapolates.` : "") +
      " Hover for values.";
    p.onHover((u, v) => {
      const k = cellIndex(field, u, v);
      if (values[k] == null) return "no value here (no ray: past the model's reach)";
      const at = `at (${field.u[k].toFixed(0)}, ${field.v[k].toFixed(0)}) px`;
      if (angle) {
        return `${at}\nθ ${m.theta[k].toFixed(2)}° off axis\nθ − r/f ${m.dtheta[k].toFixed(2)}° against the equidistant lens` +
          (m.theta[k] > reach ? "\npast the corners' reach: extrapolated" : "");
      }
      return `${at}\nΔx ${m.dx[k].toFixed(2)} px, Δy ${m.dy[k].toFixed(2)} px (${m.label})`;
    });
  }
  draw(first);
  return fig;
}

/** Arrows of the pixel view the lens reads on: the field's own part, or the pinhole's when that is the default;
 * none for a wide lens without a field (its pinhole offsets run to hundreds of pixels: the angle map says it). */
export function fieldVectorsFigure({ field }) {
  const { maps, def } = mapsOf(field);
  const name = maps.field ? "field" : def === "pinhole" ? "pinhole" : null;
  if (!name) return null;
  const m = maps[name];
  const [w, h] = field.image_size, [nu] = field.grid;
  const pts = [];
  for (let i = 0; i < field.u.length; i++) {
    if (m.dx[i] != null && m.dy[i] != null) pts.push({ x: field.u[i], y: field.v[i], dx: m.dx[i], dy: m.dy[i] });
  }
  const vmax = Math.max(1e-6, percentile(pts.map((s) => Math.hypot(s.dx, s.dy)), 95));
  const spacing = (w - 1) / (nu - 1);
  const gain = 0.9 * spacing / vmax;   // the longest arrow spans one grid step
  const { fig, canvas } = figure(`Distortion vectors: ${m.label}`, {
    label: "vector plot of the distortion",
    note: `${NOTES[name]} Arrows ×${gain.toFixed(2)}, capped at ${vmax.toFixed(2)} px (95th percentile); colour = |Δ|. Hover for values.`,
  });
  fig.id = "fig-field-vectors";
  const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => diverging(v, vmax), min: 0, max: vmax, label: "|Δ| [px]" });
  p.clip((c) => {
    c.fillStyle = "#fafafa"; c.fillRect(p.x(0), p.y(0), p.pw, p.ph);
    for (const s0 of pts) {
      // arrows longer than the 95th percentile are shortened to it (their colour saturates)
      const mag = Math.hypot(s0.dx, s0.dy), f = mag > vmax ? vmax / mag : 1;
      const s = { ...s0, dx: s0.dx * f, dy: s0.dy * f };
      arrow(c, p.x(s.x - gain * s.dx), p.y(s.y - gain * s.dy), p.x(s.x), p.y(s.y), diverging(Math.hypot(s.dx, s.dy), vmax), 1.4);
    }
  });
  p.axes();
  p.onHover((u, v) => {
    const k = cellIndex(field, u, v);
    if (m.dx[k] == null) return null;
    return `at (${field.u[k].toFixed(0)}, ${field.v[k].toFixed(0)}) px\n|Δ| ${Math.hypot(m.dx[k], m.dy[k]).toFixed(2)} px` +
      `\nΔx ${m.dx[k].toFixed(2)} px, Δy ${m.dy[k].toFixed(2)} px`;
  });
  return fig;
}
