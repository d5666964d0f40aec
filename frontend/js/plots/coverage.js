// Where the set's corners fall in the image: the detection's coverage histogram.
import { ImagePlot, figure } from "./canvas.js";
import { sequential } from "./colormap.js";

export function coverageFigure({ coverage, imageSize }) {
  const [gx, gy] = coverage.grid, [w, h] = imageSize, cw = w / gx, ch = h / gy;
  const nmax = Math.max(1, ...coverage.counts.flat());
  const empty = coverage.empty_regions.length ? `Empty: ${coverage.empty_regions.join(", ")}.` : "No empty edge or corner.";
  const { fig, canvas } = figure("Coverage of the image", {
    label: "coverage map of detected corners",
    note: `Detected corners per image cell, all views; ${(coverage.fraction_covered * 100).toFixed(0)} % of cells covered. ${empty}`,
  });
  fig.id = "fig-coverage";
  const p = new ImagePlot(canvas, [0, w, 0, h], { map: (v) => sequential(v, nmax), min: 0, max: nmax, label: "corners per cell" });
  p.clip((c) => {
    c.font = "12px system-ui, sans-serif"; c.textAlign = "center"; c.textBaseline = "middle";
    for (let j = 0; j < gy; j++) for (let i = 0; i < gx; i++) {
      const n = coverage.counts[j][i];
      c.fillStyle = n ? sequential(n, nmax) : "#fbeaea";
      c.fillRect(p.x(i * cw), p.y(j * ch), p.k * cw + 0.5, p.k * ch + 0.5);
      c.fillStyle = n > nmax * 0.6 ? "#222" : n ? "#fff" : "#b3261e";
      c.fillText(String(n), p.x((i + 0.5) * cw), p.y((j + 0.5) * ch));
    }
  });
  p.axes();
  p.onHover((u, v) => {
    const i = Math.min(gx - 1, Math.floor(u / cw)), j = Math.min(gy - 1, Math.floor(v / ch));
    return `cell x ${(i * cw).toFixed(0)}–${((i + 1) * cw).toFixed(0)} px, y ${(j * ch).toFixed(0)}–${((j + 1) * ch).toFixed(0)} px\n` +
      `${coverage.counts[j][i]} corner(s)`;
  });
  return fig;
}
