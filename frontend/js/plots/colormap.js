// The page's colour maps; the same stops as backend/viewer/colormap.py so 2-D and 3-D agree.
const SEQUENTIAL = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
const DIVERGING = [[33, 102, 172], [146, 197, 222], [247, 247, 247], [244, 165, 130], [178, 24, 43]];

function interp(stops, t) {
  if (!Number.isFinite(t)) return "rgb(220,220,220)";
  t = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(t)), f = t - i;
  const c = stops[i].map((a, k) => Math.round(a + (stops[i + 1][k] - a) * f));
  return `rgb(${c[0]},${c[1]},${c[2]})`;
}

/** 0 … vmax → dark blue … yellow (error magnitudes). */
export const sequential = (v, vmax) => interp(SEQUENTIAL, v / (vmax || 1));
/** −vabs … 0 … +vabs → blue … white … red (signed offsets). */
export const diverging = (v, vabs) => interp(DIVERGING, 0.5 + 0.5 * v / (vabs || 1));

export function percentile(values, p) {
  const a = values.filter(Number.isFinite).sort((x, y) => x - y);
  if (!a.length) return 1;
  return a[Math.min(a.length - 1, Math.floor(p / 100 * a.length))] || a[a.length - 1] || 1;
}
