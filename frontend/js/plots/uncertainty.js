// Projection uncertainty over the image: how far a direction's pixel would move if the
// corners were measured again with the same noise. Pale cells: no corner nearby (extrapolated).
import { ImagePlot, figure, select } from "./canvas.js";
import { percentile, sequential } from "./colormap.js";

export function uncertaintyFigure({ unc }) {
  const [w, h] = unc.image_size, u = unc.u, v = unc.v;
  const { fig, canvas } = figure("Projection uncertainty", {
    label: "projection uncertainty map",
    controls: [select("uncertainty measure", [["std_worst", "worst direction"], ["std_rms", "per-axis rms"]], (k) => draw(k))],
    note: `Standard deviation of a projected direction under re-measurement noise (σ = ${unc.sigma.toFixed(3)} px per ` +
      "axis, from the residuals). Pale: no corner nearby, the model extrapolates there. Hover for values.",
  });
  fig.id = "fig-uncertainty";
  function draw(key) {
    const grid = unc[key];
    const vmax = Math.max(1e-6, percentile(grid.flat().filter((x, i) => x >= 0 && unc.covered.flat()[i]), 98));
    const p = new ImagePlot(canvas, [0, w, 0, h], { map: (x) => sequential(x, vmax), min: 0, max: vmax, label: "σ projection [px]" });
    p.cells(u, v, (i, j) => [grid[j][i] < 0 ? "#e6e6e6" : sequential(grid[j][i], vmax), unc.covered[j][i] ? 1 : 0.35]);
    p.axes();
    p.onHoverCell(u, v, (i, j) => {
      const a = unc.std_worst[j][i], b = unc.std_rms[j][i];
      return a < 0 ? "no value (the model cannot invert this pixel)"
        : `at (${u[i].toFixed(0)}, ${v[j].toFixed(0)}) px\nworst direction ${a.toFixed(3)} px\nper-axis rms ${b.toFixed(3)} px` +
          (unc.covered[j][i] ? "" : "\nno corner nearby: extrapolated");
    });
  }
  draw("std_worst");
  return fig;
}
