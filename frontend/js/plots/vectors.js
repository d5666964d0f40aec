// Residual vectors drawn on each image (its 640 px preview), magnified so they can be seen.
import { thumbUrl } from "../api.js";
import { ImagePlot, arrow, figure, nearest, select } from "./canvas.js";
import { percentile, sequential } from "./colormap.js";

export function vectorsFigure({ corners, views, set, imageSize }) {
  const [w, h] = imageSize;
  const vmax = percentile(corners.filter((c) => !c.outlier).map((c) => c.error), 98);
  const gain = Math.max(1, Math.round((w / 30) / vmax));   // the 98th-percentile error spans 1/30 of the width
  const { fig, canvas } = figure("Residual vectors on the image", {
    label: "residual vectors over one image",
    controls: [select("image for the residual vectors", views.map((v) => [v.view, v.view]), (v) => draw(v))],
    note: `Arrows: observed − projected corner, magnified ×${gain}; colour = error. Hover a corner for its values.`,
  });
  fig.id = "fig-vectors";
  function draw(view) {
    const pts = corners.filter((c) => c.view === view);
    const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => sequential(v, vmax), min: 0, max: vmax, label: "error [px]" });
    const paint = (img) => {
      p.clip((c) => {
        if (img) { c.globalAlpha = 0.55; c.drawImage(img, p.x(0), p.y(0), p.pw, p.ph); c.globalAlpha = 1; }
        else { c.fillStyle = "#f4f4f4"; c.fillRect(p.x(0), p.y(0), p.pw, p.ph); }
        for (const q of pts) {
          const color = q.outlier ? "#b3261e" : sequential(q.error, vmax);
          arrow(c, p.x(q.x), p.y(q.y), p.x(q.x + gain * q.dx), p.y(q.y + gain * q.dy), color, 1.6);
          c.fillStyle = color; c.fillRect(p.x(q.x) - 1.5, p.y(q.y) - 1.5, 3, 3);
        }
      });
      p.axes();
    };
    paint(null);
    if (set && set.source === "images") {
      const img = new Image();
      img.onload = () => paint(img);
      img.src = thumbUrl(set.id, view, 640);
    }
    p.onHover((u, v) => {
      const q = nearest(pts, u, v, 14 / p.k);
      return q && `${q.view} corner ${q.id}\nerror ${q.error.toFixed(3)} px\ndx ${q.dx.toFixed(3)} px, dy ${q.dy.toFixed(3)} px`;
    });
  }
  if (views.length) draw(views[0].view);
  return fig;
}
