// The knot grid with the number of corners in each knot cell (the paper's Figure 11).
import { ImagePlot, figure } from "./canvas.js";
import { sequential } from "./colormap.js";

export function knotsFigure({ knots, imageSize }) {
  const bu = knots.breaks_u, bv = knots.breaks_v;
  const [w, h] = imageSize;
  const dom = [Math.min(0, bu[0]), Math.max(w, bu[bu.length - 1]), Math.min(0, bv[0]), Math.max(h, bv[bv.length - 1])];
  const nmax = Math.max(1, ...knots.counts.flat());
  const { fig, canvas } = figure("Knot grid and corners per cell", {
    label: "B-spline knot grid with corner counts",
    note: `Knots in ${knots.positions}; dashed: the image. Numbers: corners per knot cell (few corners: the field is ` +
      "held there mostly by smoothing). Hover for the cell's range.",
  });
  fig.id = "fig-knots";
  const p = new ImagePlot(canvas, dom, { map: (v) => sequential(v, nmax), min: 0, max: nmax, label: "corners per cell" });
  p.clip((c) => {
    for (let j = 0; j < bv.length - 1; j++) for (let i = 0; i < bu.length - 1; i++) {
      const n = knots.counts[j][i];
      c.fillStyle = n ? sequential(n, nmax) : "#fbeaea";
      c.fillRect(p.x(bu[i]), p.y(bv[j]), p.x(bu[i + 1]) - p.x(bu[i]), p.y(bv[j + 1]) - p.y(bv[j]));
    }
    c.fillStyle = "rgba(255,255,255,.75)";
    for (const [x, y] of knots.corners) c.fillRect(p.x(x) - 0.8, p.y(y) - 0.8, 1.6, 1.6);
    c.strokeStyle = "#e0561b"; c.lineWidth = 1.2;
    for (const u of bu) { c.beginPath(); c.moveTo(p.x(u), p.y(bv[0])); c.lineTo(p.x(u), p.y(bv[bv.length - 1])); c.stroke(); }
    for (const v of bv) { c.beginPath(); c.moveTo(p.x(bu[0]), p.y(v)); c.lineTo(p.x(bu[bu.length - 1]), p.y(v)); c.stroke(); }
    c.setLineDash([5, 4]); c.strokeStyle = "#333"; c.strokeRect(p.x(0), p.y(0), p.x(w) - p.x(0), p.y(h) - p.y(0)); c.setLineDash([]);
    c.font = "bold 12px system-ui, sans-serif"; c.textAlign = "center"; c.textBaseline = "middle";
    for (let j = 0; j < bv.length - 1; j++) for (let i = 0; i < bu.length - 1; i++) {
      const n = knots.counts[j][i], cx = (p.x(bu[i]) + p.x(bu[i + 1])) / 2, cy = (p.y(bv[j]) + p.y(bv[j + 1])) / 2;
      c.fillStyle = n > nmax * 0.6 ? "#222" : n ? "#fff" : "#b3261e";
      c.fillText(String(n), cx, cy);
    }
  });
  p.axes();
  p.onHover((u, v) => {
    const i = bu.findIndex((b, k) => k < bu.length - 1 && u >= b && u < bu[k + 1]);
    const j = bv.findIndex((b, k) => k < bv.length - 1 && v >= b && v < bv[k + 1]);
    if (i < 0 || j < 0) return null;
    return `knot cell u ${bu[i].toFixed(0)}–${bu[i + 1].toFixed(0)} px, v ${bv[j].toFixed(0)}–${bv[j + 1].toFixed(0)} px\n` +
      `${knots.counts[j][i]} corner(s)`;
  });
  return fig;
}
