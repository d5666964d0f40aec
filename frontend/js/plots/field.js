// The distortion field: Δx and Δy maps (observed − ideal pixel) and its vectors.
import { ImagePlot, arrow, figure, select } from "./canvas.js";
import { diverging, percentile } from "./colormap.js";

function samples(field) {
  const out = [];
  for (let i = 0; i < field.u.length; i++) {
    if (field.dx[i] == null || field.dy[i] == null) continue;
    out.push({ x: field.u[i], y: field.v[i], dx: field.dx[i], dy: field.dy[i] });
  }
  return out;
}

function cellAt(field, u, v) {
  const [nu, nv] = field.grid, [w, h] = field.image_size;
  const i = Math.round(u / ((w - 1) / (nu - 1))), j = Math.round(v / ((h - 1) / (nv - 1)));
  const k = Math.min(nv - 1, Math.max(0, j)) * nu + Math.min(nu - 1, Math.max(0, i));
  return { x: field.u[k], y: field.v[k], dx: field.dx[k], dy: field.dy[k] };
}

export function fieldMapFigure({ field }) {
  const [w, h] = field.image_size, [nu, nv] = field.grid;
  const pts = samples(field);
  // 98th percentile, not the maximum: an image corner with no data can extrapolate to hundreds of px
  const vabs = Math.max(1e-6, percentile(pts.flatMap((s) => [Math.abs(s.dx), Math.abs(s.dy)]), 98));
  const { fig, canvas } = figure("Distortion field map", {
    label: "map of the distortion field component",
    controls: [select("distortion component", [["dx", "Δx"], ["dy", "Δy"]], (c) => draw(c))],
    note: `Observed pixel minus its ideal pinhole pixel; one colour scale for Δx and Δy, ±${vabs.toFixed(1)} px (98th percentile; larger values saturate). Hover for values.`,
  });
  fig.id = "fig-field";
  const cw = (w - 1) / (nu - 1), ch = (h - 1) / (nv - 1);
  function draw(comp) {
    const name = comp === "dx" ? "Δx" : "Δy";
    const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => diverging(v, vabs), min: -vabs, max: vabs, label: `${name} [px]` });
    p.clip((c) => {
      for (let k = 0; k < field.u.length; k++) {
        const val = field[comp][k];
        c.fillStyle = val == null ? "#e6e6e6" : diverging(val, vabs);
        c.fillRect(p.x(field.u[k] - cw / 2), p.y(field.v[k] - ch / 2), p.k * cw + 0.6, p.k * ch + 0.6);
      }
    });
    p.axes();
    p.onHover((u, v) => {
      const s = cellAt(field, u, v);
      return s.dx == null ? "no value (ray 90° or more off axis)"
        : `at (${s.x.toFixed(0)}, ${s.y.toFixed(0)}) px\nΔx ${s.dx.toFixed(2)} px, Δy ${s.dy.toFixed(2)} px`;
    });
  }
  draw("dx");
  return fig;
}

export function fieldVectorsFigure({ field }) {
  const [w, h] = field.image_size, [nu] = field.grid;
  const pts = samples(field);
  const mags = pts.map((s) => Math.hypot(s.dx, s.dy));
  const vmax = Math.max(1e-6, percentile(mags, 95));
  const spacing = (w - 1) / (nu - 1);
  const gain = 0.9 * spacing / vmax;   // the longest arrow spans one grid step
  const { fig, canvas } = figure("Distortion vectors", {
    label: "vector plot of the distortion field",
    note: `Arrows from the ideal towards the observed pixel, ×${gain.toFixed(2)}, capped at ${vmax.toFixed(1)} px (95th percentile); colour = |Δ|. Hover for values.`,
  });
  fig.id = "fig-field-vectors";
  const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => diverging(v, vmax), min: 0, max: vmax, label: "|Δ| [px]" });
  p.clip((c) => {
    c.fillStyle = "#fafafa"; c.fillRect(p.x(0), p.y(0), p.pw, p.ph);
    for (const s0 of pts) {
      // arrows longer than the 95th percentile are shortened to it (their colour saturates)
      const m = Math.hypot(s0.dx, s0.dy), f = m > vmax ? vmax / m : 1;
      const s = { ...s0, dx: s0.dx * f, dy: s0.dy * f };
      arrow(c, p.x(s.x - gain * s.dx), p.y(s.y - gain * s.dy), p.x(s.x), p.y(s.y), diverging(Math.hypot(s.dx, s.dy), vmax), 1.4);
    }
  });
  p.axes();
  p.onHover((u, v) => {
    const s = cellAt(field, u, v);
    return s.dx == null ? null : `at (${s.x.toFixed(0)}, ${s.y.toFixed(0)}) px\n|Δ| ${Math.hypot(s.dx, s.dy).toFixed(2)} px` +
      `\nΔx ${s.dx.toFixed(2)} px, Δy ${s.dy.toFixed(2)} px`;
  });
  return fig;
}
