// The projection difference between two calibrations of one camera (`freecal diff`): for each pixel,
// how far the other calibration puts the direction this one sees there, once the rotation between
// their camera frames is taken out. Pale cells: outside what both calibrations' corners covered.
import { el, px } from "../format.js";
import { ImagePlot, figure } from "./canvas.js";
import { percentile, sequential } from "./colormap.js";

const REGION = { covered: "over the region both calibrations' corners covered", centre: "over the image centre",
  none: "not fitted: the two camera frames are taken as the same" };

export function diffFigure({ diff, a, b }) {
  const [w, h] = diff.image_size, u = diff.u, v = diff.v, mag = diff.magnitude;
  const covered = diff.covered_mask;
  const { fig, canvas } = figure(`Projection difference: ${a} → ${b}`, {
    label: "projection difference map",
    note: "Where the second calibration puts each direction the first one sees at a pixel, in pixels. " +
      "Pale: outside what both calibrations' corners covered, where each extrapolates. Hover for values.",
  });
  fig.id = "fig-diff";
  const inside = mag.flat().filter((x, i) => x != null && (!covered || covered.flat()[i]));
  const vmax = Math.max(1e-6, percentile(inside, 98));
  fig.dataset.scale = String(vmax);
  const p = new ImagePlot(canvas, [0, w, 0, h], { map: (x) => sequential(x, vmax), min: 0, max: vmax, label: "difference [px]" });
  p.cells(u, v, (i, j) => [mag[j][i] == null ? "#e6e6e6" : sequential(mag[j][i], vmax), !covered || covered[j][i] ? 1 : 0.35]);
  p.axes();
  p.onHoverCell(u, v, (i, j) => {
    const m = mag[j][i];
    return m == null ? "no value: a calibration cannot map this pixel"
      : `at (${u[i].toFixed(0)}, ${v[j].toFixed(0)}) px\ndifference ${m.toFixed(3)} px ` +
        `(${diff.dx[j][i].toFixed(3)}, ${diff.dy[j][i].toFixed(3)})` + (!covered || covered[j][i] ? "" : "\noutside the covered region");
  });
  return fig;
}

/** The figures in words: median, 95th percentile and maximum, where it matters and over the image. */
export function diffSummary(diff) {
  const row = (name, s) => s && s.n ? el("tr", { "data-region": name }, el("th", { scope: "row" }, name),
    el("td", { class: "median" }, px(s.median)), el("td", {}, px(s.p95)), el("td", {}, px(s.max))) : null;
  const [region, why] = diff.fitted_on.split(/ (.*)/s);
  const rotation = region === "none" ? `Rotation between the camera frames ${REGION.none}.`
    : `Rotation between the camera frames: ${diff.rotation_deg.toFixed(4)}°, fitted ${REGION[region]}${why ? ` ${why}` : ""}.`;
  return el("div", { id: "diff-summary" },
    el("table", {}, el("caption", {}, "Projection difference"),
      el("thead", {}, el("tr", {}, ["region", "median", "95 %", "max"].map((t) => el("th", { scope: "col" }, t)))),
      el("tbody", {}, row("covered by both", diff.covered), row("whole image", diff.image))),
    el("p", { class: "note" }, rotation));
}
