// Residual heatmap over the image: mean error per cell over all views (heatmap.json),
// or one view's corners coloured by their error.
import { ImagePlot, figure, nearest, select } from "./canvas.js";
import { percentile, sequential } from "./colormap.js";

export function heatmapFigure({ heatmap, corners, views }) {
  const options = [["all", "all views"], ...views.map((v) => [v.view, v.view])];
  const { fig, canvas } = figure("Residual heatmap", {
    label: "heatmap of residual error over the image",
    controls: [select("view for the heatmap", options, (v) => draw(v))],
    note: "Mean per-point error (Euclidean, observed − projected) per image cell; grey: no corners. Hover for values.",
  });
  fig.id = "fig-heatmap";
  const [w, h] = heatmap.image_size;
  const vmax = percentile(corners.filter((c) => !c.outlier).map((c) => c.error), 98);
  function draw(view) {
    const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => sequential(v, vmax), min: 0, max: vmax, label: "error [px]" });
    if (view === "all") drawCells(p, heatmap, vmax);
    else drawCorners(p, corners.filter((c) => c.view === view), vmax);
    p.axes();
  }
  draw("all");
  return fig;
}

function drawCells(p, hm, vmax) {
  const [nx, ny] = hm.cells, [w, h] = hm.image_size, cw = w / nx, ch = h / ny;
  p.clip((c) => {
    for (let j = 0; j < ny; j++) for (let i = 0; i < nx; i++) {
      const m = hm.mean_error[j][i];
      c.fillStyle = m == null ? "#e6e6e6" : sequential(m, vmax);
      c.fillRect(p.x(i * cw), p.y(j * ch), p.k * cw + 0.5, p.k * ch + 0.5);
    }
  });
  p.onHover((u, v) => {
    const i = Math.min(nx - 1, Math.floor(u / cw)), j = Math.min(ny - 1, Math.floor(v / ch));
    const m = hm.mean_error[j][i], n = hm.count[j][i];
    return `cell x ${(i * cw).toFixed(0)}–${((i + 1) * cw).toFixed(0)} px, y ${(j * ch).toFixed(0)}–${((j + 1) * ch).toFixed(0)} px\n` +
      (m == null ? "no corners" : `mean error ${m.toFixed(3)} px over ${n} corner(s)`);
  });
}

function drawCorners(p, pts, vmax) {
  p.clip((c) => {
    c.fillStyle = "#f4f4f4"; c.fillRect(p.x(0), p.y(0), p.pw, p.ph);
    for (const q of pts) {
      c.beginPath(); c.arc(p.x(q.x), p.y(q.y), 4.5, 0, 2 * Math.PI);
      c.fillStyle = q.outlier ? "#fff" : sequential(q.error, vmax); c.fill();
      c.strokeStyle = q.outlier ? "#b3261e" : "rgba(0,0,0,.35)"; c.lineWidth = 1; c.stroke();
    }
  });
  p.onHover((u, v) => {
    const q = nearest(pts, u, v, 12 / p.k);
    return q && `${q.view} corner ${q.id}\nat (${q.x.toFixed(1)}, ${q.y.toFixed(1)}) px\n` +
      `error ${q.error.toFixed(3)} px (dx ${q.dx.toFixed(3)}, dy ${q.dy.toFixed(3)} px)${q.outlier ? "\noutlier: not fitted" : ""}`;
  });
}
