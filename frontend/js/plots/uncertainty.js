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
  const du = u.length > 1 ? u[1] - u[0] : w, dv = v.length > 1 ? v[1] - v[0] : h;
  function draw(key) {
    const grid = unc[key];
    const vmax = Math.max(1e-6, percentile(grid.flat().filter((x, i) => x >= 0 && unc.covered.flat()[i]), 98));
    const p = new ImagePlot(canvas, [0, w, 0, h], { map: (x) => sequential(x, vmax), min: 0, max: vmax, label: "σ projection [px]" });
    p.clip((c) => {
      for (let j = 0; j < v.length; j++) for (let i = 0; i < u.length; i++) {
        const x = grid[j][i];
        c.globalAlpha = unc.covered[j][i] ? 1 : 0.35;
        c.fillStyle = x < 0 ? "#e6e6e6" : sequential(x, vmax);
        c.fillRect(p.x(u[i] - du / 2), p.y(v[j] - dv / 2), p.k * du + 0.6, p.k * dv + 0.6);
      }
      c.globalAlpha = 1;
    });
    p.axes();
    p.onHover((x, y) => {
      const i = Math.max(0, Math.min(u.length - 1, Math.round((x - u[0]) / du)));
      const j = Math.max(0, Math.min(v.length - 1, Math.round((y - v[0]) / dv)));
      const a = unc.std_worst[j][i], b = unc.std_rms[j][i];
      return a < 0 ? "no value (the model cannot invert this pixel)"
        : `at (${u[i].toFixed(0)}, ${v[j].toFixed(0)}) px\nworst direction ${a.toFixed(3)} px\nper-axis rms ${b.toFixed(3)} px` +
          (unc.covered[j][i] ? "" : "\nno corner nearby: extrapolated");
    });
  }
  draw("std_worst");
  return fig;
}
