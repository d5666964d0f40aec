// Where the set's corners fall in the image: the detection's coverage histogram. With a fisheye's
// image circle (found in the photos) the circle is drawn and the cells outside it are grey: no light
// reaches them, so they are neither counted nor named in the advice.
import { ImagePlot, figure } from "./canvas.js";
import { sequential } from "./colormap.js";

export function coverageFigure({ coverage, imageSize }) {
  const [gx, gy] = coverage.grid, [w, h] = imageSize, cw = w / gx, ch = h / gy;
  const inside = (i, j) => !coverage.inside || coverage.inside[j][i];
  const circle = coverage.image_circle;
  const nmax = Math.max(1, ...coverage.counts.flat());
  const empty = coverage.empty_regions.length ? `Empty: ${coverage.empty_regions.join(", ")}.` : "No empty edge or corner.";
  const outside = circle ? " Grey: outside the lens's image circle, not counted." : "";
  const { fig, canvas } = figure("Coverage of the image", {
    label: "coverage map of detected corners",
    note: `Detected corners per image cell, all views; ${(coverage.fraction_covered * 100).toFixed(0)} % of ` +
      `${circle ? "the cells inside the image circle" : "cells"} covered. ${empty}${outside}`,
  });
  fig.id = "fig-coverage";
  if (circle) fig.dataset.imageCircle = `${circle.cx} ${circle.cy} ${circle.radius}`;
  const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => sequential(v, nmax), min: 0, max: nmax, label: "corners per cell" });
  p.clip((c) => {
    c.font = "12px system-ui, sans-serif"; c.textAlign = "center"; c.textBaseline = "middle";
    for (let j = 0; j < gy; j++) for (let i = 0; i < gx; i++) {
      const n = coverage.counts[j][i];
      c.fillStyle = !inside(i, j) ? "#d6d6d6" : n ? sequential(n, nmax) : "#fbeaea";
      c.fillRect(p.x(i * cw), p.y(j * ch), p.k * cw + 0.5, p.k * ch + 0.5);
      if (!inside(i, j)) continue;
      c.fillStyle = n > nmax * 0.6 ? "#222" : n ? "#fff" : "#b3261e";
      c.fillText(String(n), p.x((i + 0.5) * cw), p.y((j + 0.5) * ch));
    }
    if (circle) {
      c.strokeStyle = "#444"; c.lineWidth = 1.5; c.beginPath();
      c.arc(p.x(circle.cx), p.y(circle.cy), p.k * circle.radius, 0, 2 * Math.PI); c.stroke();
    }
  });
  p.axes();
  p.onHover((u, v) => {
    const i = Math.min(gx - 1, Math.floor(u / cw)), j = Math.min(gy - 1, Math.floor(v / ch));
    return `cell x ${(i * cw).toFixed(0)}–${((i + 1) * cw).toFixed(0)} px, y ${(j * ch).toFixed(0)}–${((j + 1) * ch).toFixed(0)} px\n` +
      (inside(i, j) ? `${coverage.counts[j][i]} corner(s)` : "outside the lens's image circle: not counted");
  });
  return fig;
}
