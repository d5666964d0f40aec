// A figure over the image plane: hi-DPI canvas, pixel axes, a colour bar with its unit,
// and hover tooltips. Each plot module draws its data through ``ImagePlot``.
import { el } from "../format.js";

const M = { left: 50, right: 92, top: 10, bottom: 36 };
const WIDTH = 620;   // logical canvas width (CSS scales it to the column)

/** A <figure> with a caption (and optional controls) holding one canvas. */
export function figure(title, { note, controls = [], label } = {}) {
  const canvas = el("canvas", { role: "img", "aria-label": label || title });
  const zoom = el("button", { type: "button", class: "zoom", "aria-pressed": "false", title: "show this figure across the page" },
    "Enlarge");
  const fig = el("figure", { class: "plot" },
    el("figcaption", {}, el("span", {}, title), ...controls, zoom), canvas, note ? el("p", { class: "note" }, note) : null);
  zoom.addEventListener("click", () => {
    const wide = fig.classList.toggle("wide");
    zoom.textContent = wide ? "Smaller" : "Enlarge";
    zoom.setAttribute("aria-pressed", String(wide));
  });
  return { fig, canvas };
}

export function select(label, options, onChange) {
  const id = `sel-${Math.random().toString(36).slice(2, 8)}`;
  const s = el("select", { id, "aria-label": label }, options.map(([v, text]) => el("option", { value: v }, text)));
  s.addEventListener("change", () => onChange(s.value));
  return s;
}

export class ImagePlot {
  /** domain: [u0, u1, v0, v1] in pixels (v down); colorbar: {map, min, max, label} or null. */
  constructor(canvas, domain, colorbar) {
    this.canvas = canvas; this.domain = domain; this.colorbar = colorbar;
    const [u0, u1, v0, v1] = domain;
    this.pw = WIDTH - M.left - M.right;
    this.ph = Math.round(this.pw * (v1 - v0) / (u1 - u0));
    // twice the screen's density: the figure stays sharp when enlarged to the page's width
    const dpr = 2 * Math.max(1, window.devicePixelRatio || 1);
    canvas.width = WIDTH * dpr; canvas.height = (this.ph + M.top + M.bottom) * dpr;
    canvas.style.aspectRatio = `${WIDTH} / ${this.ph + M.top + M.bottom}`;
    this.ctx = canvas.getContext("2d");
    this.ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    this.ctx.clearRect(0, 0, WIDTH, this.ph + M.top + M.bottom);
    this.ctx.font = "13px system-ui, sans-serif";
    this.hover = null;
    canvas.addEventListener("mousemove", (e) => this.#move(e));
    canvas.addEventListener("mouseleave", () => tooltip(null));
  }
  x(u) { const [u0, u1] = this.domain; return M.left + (u - u0) / (u1 - u0) * this.pw; }
  y(v) { const [, , v0, v1] = this.domain; return M.top + (v - v0) / (v1 - v0) * this.ph; }
  /** Scale of one pixel of the image on the canvas. */
  get k() { return this.pw / (this.domain[1] - this.domain[0]); }

  clip(fn) { const c = this.ctx; c.save(); c.beginPath(); c.rect(M.left, M.top, this.pw, this.ph); c.clip(); fn(c); c.restore(); }

  axes(unit = "px") {
    const c = this.ctx, [u0, u1, v0, v1] = this.domain;
    c.strokeStyle = "#555"; c.lineWidth = 1; c.strokeRect(M.left, M.top, this.pw, this.ph);
    c.fillStyle = "#333"; c.textAlign = "center"; c.textBaseline = "top";
    for (const u of ticks(u0, u1)) { c.fillText(String(u), this.x(u), M.top + this.ph + 4); }
    c.fillText(`x [${unit}]`, M.left + this.pw / 2, M.top + this.ph + 18);
    c.textAlign = "right"; c.textBaseline = "middle";
    for (const v of ticks(v0, v1)) { c.fillText(String(v), M.left - 4, this.y(v)); }
    c.save(); c.translate(11, M.top + this.ph / 2); c.rotate(-Math.PI / 2); c.textAlign = "center";
    c.fillText(`y [${unit}]`, 0, 0); c.restore();
    if (this.colorbar) this.#colorbar();
  }

  #colorbar() {
    const { map, min, max, label } = this.colorbar, c = this.ctx;
    const x = M.left + this.pw + 14, w = 14, h = this.ph;
    for (let i = 0; i < h; i++) { c.fillStyle = map(max - (max - min) * i / h); c.fillRect(x, M.top + i, w, 1.5); }
    c.strokeStyle = "#555"; c.strokeRect(x, M.top, w, h);
    c.fillStyle = "#333"; c.textAlign = "left"; c.textBaseline = "middle";
    for (const t of [max, (max + min) / 2, min]) c.fillText(fmt(t), x + w + 3, M.top + h * (max - t) / (max - min));
    c.save(); c.translate(x + w + 52, M.top + h / 2); c.rotate(-Math.PI / 2); c.textAlign = "center";
    c.fillText(label, 0, 0); c.restore();
  }

  /** A map sampled on the pixel grid u × v (cell centres): ``style(i, j)`` → [fill colour, opacity]. */
  cells(u, v, style) {
    const du = u.length > 1 ? u[1] - u[0] : this.domain[1], dv = v.length > 1 ? v[1] - v[0] : this.domain[3];
    this.clip((c) => {
      for (let j = 0; j < v.length; j++) for (let i = 0; i < u.length; i++) {
        [c.fillStyle, c.globalAlpha] = style(i, j);
        c.fillRect(this.x(u[i] - du / 2), this.y(v[j] - dv / 2), this.k * du + 0.6, this.k * dv + 0.6);
      }
    });
  }

  /** ``fn(i, j)`` → tooltip text for the cell of the grid u × v under the mouse. */
  onHoverCell(u, v, fn) {
    const du = u.length > 1 ? u[1] - u[0] : 1, dv = v.length > 1 ? v[1] - v[0] : 1;
    const at = (x, n, d, x0) => Math.max(0, Math.min(n - 1, Math.round((x - x0) / d)));
    this.onHover((x, y) => fn(at(x, u.length, du, u[0]), at(y, v.length, dv, v[0])));
  }

  /** ``fn(u, v)`` → tooltip text (or null) for the image point under the mouse. */
  onHover(fn) { this.hover = fn; }

  #move(e) {
    if (!this.hover) return;
    const r = this.canvas.getBoundingClientRect(), s = WIDTH / r.width;
    const cx = (e.clientX - r.left) * s, cy = (e.clientY - r.top) * s;
    const [u0, u1, v0, v1] = this.domain;
    const u = u0 + (cx - M.left) / this.pw * (u1 - u0), v = v0 + (cy - M.top) / this.ph * (v1 - v0);
    const inside = u >= u0 && u <= u1 && v >= v0 && v <= v1;
    tooltip(inside ? this.hover(u, v) : null, e.clientX, e.clientY);
  }
}

function ticks(a, b) {
  const span = b - a, step = [1, 2, 5].map((m) => m * 10 ** Math.floor(Math.log10(span / 4)))
    .find((s) => span / s <= 6) || 10 ** Math.ceil(Math.log10(span / 4));
  const out = [];
  for (let t = Math.ceil(a / step) * step; t <= b + 1e-9; t += step) out.push(Math.round(t * 1e6) / 1e6);
  return out;
}

function fmt(t) { return Math.abs(t) >= 100 ? t.toFixed(0) : Math.abs(t) >= 10 ? t.toFixed(1) : t.toFixed(2); }

export function tooltip(text, x, y) {
  const tip = document.getElementById("tooltip");
  if (!text) { tip.hidden = true; return; }
  tip.textContent = text; tip.hidden = false;
  const w = tip.offsetWidth;
  tip.style.left = `${x + 14 + w > window.innerWidth ? x - w - 10 : x + 14}px`;
  tip.style.top = `${y + 14}px`;
}

/** Nearest item to (u, v) within ``radius`` image pixels: items have .x, .y. */
export function nearest(items, u, v, radius) {
  let best = null, bd = radius * radius;
  for (const it of items) { const d = (it.x - u) ** 2 + (it.y - v) ** 2; if (d < bd) { bd = d; best = it; } }
  return best;
}

export function arrow(c, x0, y0, x1, y1, color, width = 1.3) {
  const a = Math.atan2(y1 - y0, x1 - x0), len = Math.hypot(x1 - x0, y1 - y0), h = Math.min(6, len * 0.4);
  c.strokeStyle = color; c.fillStyle = color; c.lineWidth = width;
  c.beginPath(); c.moveTo(x0, y0); c.lineTo(x1, y1); c.stroke();
  if (len < 2) return;
  c.beginPath(); c.moveTo(x1, y1);
  c.lineTo(x1 - h * Math.cos(a - 0.45), y1 - h * Math.sin(a - 0.45));
  c.lineTo(x1 - h * Math.cos(a + 0.45), y1 - h * Math.sin(a + 0.45)); c.closePath(); c.fill();
}
