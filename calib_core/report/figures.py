"""The report's figures as PNG images, drawn with matplotlib from the same
products the page draws (``tables.py``): residuals over the image, per-view
errors, the distortion field and, for a field model, the knot grid with its
corner counts.
"""
from __future__ import annotations

import io
from typing import Any

import numpy as np

DPI = 110


def _pyplot():
    """matplotlib without a display: figures are only ever written to files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def report_figures(products: dict[str, Any]) -> dict[str, bytes]:
    """File name → PNG bytes for every figure the products support
    (``tables.report_products``; without the corners, only the calibration's own)."""
    figures = {}
    image_size = products["distortion_field.json"]["image_size"]
    if "heatmap.json" in products:
        figures["residual_heatmap.png"] = residual_heatmap(products["heatmap.json"])
    if "corner_residuals.json" in products:
        figures["residual_vectors.png"] = residual_vectors(products["corner_residuals.json"], image_size)
    figures["view_errors.png"] = view_errors(products["view_residuals.json"])
    figures["distortion_field.png"] = distortion_field(products["distortion_field.json"])
    figures["distortion_maps.png"] = distortion_maps(products["distortion_field.json"])
    if products.get("knot_cells.json") is not None:
        figures["knot_grid.png"] = knot_grid(products["knot_cells.json"])
    if products.get("uncertainty.json") is not None:
        figures["uncertainty.png"] = uncertainty_map(products["uncertainty.json"])
    if products.get("coverage.json") is not None:
        figures["coverage.png"] = coverage_map(products["coverage.json"])
    return figures


def _image_axes(plt, image_size, title: str):
    w, h = image_size
    fig, ax = plt.subplots(figsize=(7, 7 * h / w + 0.6), dpi=DPI)
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)  # image rows grow downwards
    ax.set_aspect("equal")
    ax.set_xlabel("x [px]")
    ax.set_ylabel("y [px]")
    ax.set_title(title)
    return fig, ax


def _png(plt, fig) -> bytes:
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def residual_heatmap(heatmap: dict[str, Any]) -> bytes:
    plt = _pyplot()
    fig, ax = _image_axes(plt, heatmap["image_size"], "Mean corner error per image cell")
    w, h = heatmap["image_size"]
    mean = np.array([[np.nan if x is None else x for x in row] for row in heatmap["mean_error"]], float)
    im = ax.imshow(np.ma.masked_invalid(mean), extent=(0, w, h, 0), cmap="viridis", interpolation="nearest")
    fig.colorbar(im, ax=ax, label=heatmap["metric"], shrink=0.8)
    return _png(plt, fig)


def residual_vectors(corners: list[dict[str, Any]], image_size) -> bytes:
    """Every inlier's residual as an arrow, scaled so the typical one is a few
    percent of the image; outliers as red crosses."""
    plt = _pyplot()
    fig, ax = _image_axes(plt, image_size, "Corner residuals (observed − projected)")
    inl = np.array([(c["x"], c["y"], c["dx"], c["dy"]) for c in corners
                    if not c["outlier"] and c["dx"] is not None], float).reshape(-1, 4)
    out = np.array([(c["x"], c["y"]) for c in corners if c["outlier"]], float).reshape(-1, 2)
    if len(inl):
        typical = float(np.percentile(np.hypot(inl[:, 2], inl[:, 3]), 90)) or 1.0
        scale = 0.03 * max(image_size) / typical
        ax.quiver(inl[:, 0], inl[:, 1], inl[:, 2] * scale, inl[:, 3] * scale, angles="xy", scale_units="xy",
                  scale=1, width=0.002, color="tab:blue")
        ax.text(0.01, 0.01, f"arrows ×{scale:.0f}", transform=ax.transAxes, fontsize=8)
    if len(out):
        ax.plot(out[:, 0], out[:, 1], "x", color="tab:red", markersize=4, label="outliers")
        ax.legend(loc="upper right", fontsize=8)
    return _png(plt, fig)


def view_errors(views: list[dict[str, Any]]) -> bytes:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 0.25 * len(views) + 1.5), dpi=DPI)
    names = [v["view"] for v in views]
    rmse = [np.nan if v["rmse"] is None else v["rmse"] for v in views]
    ax.barh(names, rmse, color="tab:blue")
    ax.invert_yaxis()
    ax.set_xlabel("rmse [px]")
    ax.set_title("Error per view")
    return _png(plt, fig)


def distortion_field(field: dict[str, Any]) -> bytes:
    """The map the lens reads on (``distortion.py``'s ``default``): for a wide
    lens its angles off axis against the equidistant lens (colour, with θ's
    contours), otherwise the offsets in pixels as arrows."""
    plt = _pyplot()
    maps = field.get("maps") or {"pinhole": {"label": "against the pinhole", "unit": "px", "dx": field["dx"],
                                             "dy": field["dy"]}}
    key = field.get("default", "pinhole")
    m = maps[key]
    nu, nv = field["grid"]
    u, v = (np.array([np.nan if x is None else x for x in field[k]], float) for k in ("u", "v"))
    if key == "angle":
        fig, ax = _image_axes(plt, field["image_size"], "Lens: angle off axis − the equidistant lens's [°]")
        d, theta = (np.array([np.nan if x is None else x for x in m[k]], float).reshape(nv, nu) for k in ("dtheta", "theta"))
        scale = float(m.get("scale") or np.nanmax(np.abs(d)) or 1.0)
        w, h = field["image_size"]
        im = ax.imshow(np.ma.masked_invalid(d), extent=(0, w, h, 0), cmap="RdBu_r", vmin=-scale, vmax=scale,
                       interpolation="bilinear")
        lines = ax.contour(u.reshape(nv, nu), v.reshape(nv, nu), np.ma.masked_invalid(theta),
                           levels=np.arange(15, 181, 15), colors="0.2", linewidths=0.6)
        ax.clabel(lines, fmt="%d°", fontsize=7)
        fig.colorbar(im, ax=ax, label="θ − r/f [°]", shrink=0.8)
        return _png(plt, fig)
    fig, ax = _image_axes(plt, field["image_size"], f"Distortion, {m['label']} [px]")
    a = np.array([[np.nan if x is None else x for x in arr] for arr in (field["u"], field["v"], m["dx"], m["dy"])], float)
    ok = np.all(np.isfinite(a), axis=0)
    u, v, dx, dy = a[:, ok]
    size = np.hypot(dx, dy)
    ax.quiver(u, v, dx, dy, size, angles="xy", scale_units="xy", scale=1, width=0.003, cmap="magma")
    ax.text(0.01, 0.01, f"largest offset {size.max():.1f} px" if size.size else "no finite sample",
            transform=ax.transAxes, fontsize=8)
    return _png(plt, fig)


def distortion_maps(field: dict[str, Any]) -> bytes:
    """Δx and Δy of the distortion (observed − ideal pinhole pixel) as maps on one
    colour scale, saturating at the 98th percentile (an image corner with no data
    can extrapolate to hundreds of pixels)."""
    plt = _pyplot()
    nu, nv = field["grid"]
    w, h = field["image_size"]
    comps = [np.array([np.nan if x is None else x for x in field[k]], float).reshape(nv, nu) for k in ("dx", "dy")]
    finite = np.abs(np.concatenate([c[np.isfinite(c)] for c in comps]))
    vabs = float(np.percentile(finite, 98)) if finite.size else 1.0
    fig, axes = plt.subplots(1, 2, figsize=(10, 5 * h / w + 0.8), dpi=DPI)
    for ax, comp, name in zip(axes, comps, ("Δx", "Δy"), strict=True):
        im = ax.imshow(np.ma.masked_invalid(comp), extent=(0, w, h, 0), cmap="RdBu_r", vmin=-max(vabs, 1e-9),
                       vmax=max(vabs, 1e-9), interpolation="bilinear")
        ax.set_title(f"Distortion {name} [px]")
        ax.set_xlabel("x [px]")
        ax.set_ylabel("y [px]")
    fig.colorbar(im, ax=axes, label=f"observed − ideal pinhole pixel [px] (±{vabs:.1f}, 98th percentile)", shrink=0.8)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def uncertainty_map(unc: dict[str, Any]) -> bytes:
    """The worst-direction projection standard deviation over the image; pale where no
    corner is near (the model extrapolates there), grey where it cannot invert."""
    plt = _pyplot()
    fig, ax = _image_axes(plt, unc["image_size"], f"Projection uncertainty (σ = {unc['sigma']:.3f} px per axis)")
    u, v = np.asarray(unc["u"], float), np.asarray(unc["v"], float)
    std = np.asarray(unc["std_worst"], float)
    std[std < 0] = np.nan
    covered = np.asarray(unc["covered"], bool)
    step = float(unc.get("step") or (u[1] - u[0] if len(u) > 1 else 1.0))
    extent = (u[0] - step / 2, u[-1] + step / 2, v[-1] + step / 2, v[0] - step / 2)
    inside = std[covered & np.isfinite(std)]
    vmax = float(np.percentile(inside, 98)) if inside.size else float(np.nanmax(std)) if np.isfinite(std).any() else 1.0
    ax.set_facecolor("0.85")
    im = ax.imshow(np.ma.masked_invalid(std), extent=extent, cmap="viridis", vmin=0, vmax=max(vmax, 1e-9),
                   interpolation="nearest")
    veil = np.zeros((*std.shape, 4))
    veil[~covered] = (1, 1, 1, 0.6)
    ax.imshow(veil, extent=extent, interpolation="nearest")
    fig.colorbar(im, ax=ax, label="σ of the projection, worst direction [px]", shrink=0.8)
    ax.text(0.01, 0.01, "pale: no corner nearby (extrapolated)", transform=ax.transAxes, fontsize=8)
    return _png(plt, fig)


def coverage_map(cov: dict[str, Any]) -> bytes:
    """Corners per image cell over all views; empty cells red. With a fisheye's image
    circle: the circle drawn, and the cells outside it grey, unlabelled (not counted)."""
    plt = _pyplot()
    counts = np.asarray(cov["counts"], float)
    gx, gy = cov["grid"]
    w, h = cov["image_size"]
    inside = np.asarray(cov.get("inside") or np.ones((gy, gx), bool), bool)
    fig, ax = _image_axes(plt, (w, h), f"Coverage: corners per cell, {100 * cov['fraction_covered']:.0f} % of cells covered")
    ax.imshow(np.ma.masked_equal(counts, 0), extent=(0, w, h, 0), cmap="Blues", vmin=0, interpolation="nearest")
    shade = np.zeros((gy, gx, 4))
    shade[(counts == 0) & inside] = (0.98, 0.85, 0.85, 1)
    shade[~inside] = (0.8, 0.8, 0.8, 1)
    ax.imshow(shade, extent=(0, w, h, 0), interpolation="nearest")
    cw, ch = w / gx, h / gy
    peak = max(1.0, float(counts.max()))
    for j, i in zip(*np.nonzero(inside), strict=True):  # one label per cell (a few dozen), not per point
        n = int(counts[j, i])
        ax.text((i + 0.5) * cw, (j + 0.5) * ch, str(n), ha="center", va="center", fontsize=8,
                color="#b3261e" if n == 0 else ("white" if n > 0.6 * peak else "black"))
    circle = cov.get("image_circle")
    if circle:
        ax.add_patch(plt.Circle((circle["cx"], circle["cy"]), circle["radius"], fill=False, color="0.3", lw=1.2))
    regions = cov.get("empty_regions") or []
    note = "empty: " + ", ".join(regions) if regions else "no empty edge or corner"
    if circle:
        note += "; grey: outside the lens's image circle (not counted)"
    ax.text(0.01, -0.12, note, transform=ax.transAxes, fontsize=8)
    return _png(plt, fig)


def knot_grid(cells: dict[str, Any]) -> bytes:
    """The paper's Figure 11: knot lines and the corners in each knot cell."""
    plt = _pyplot()
    bu, bv = np.asarray(cells["breaks_u"]), np.asarray(cells["breaks_v"])
    fig, ax = plt.subplots(figsize=(7, 7 * (bv[-1] - bv[0]) / (bu[-1] - bu[0]) + 0.6), dpi=DPI)
    counts = np.asarray(cells["counts"], float)
    im = ax.pcolormesh(bu, bv, np.ma.masked_equal(counts, 0), cmap="Blues", shading="flat")
    corners = np.asarray(cells["corners"], float).reshape(-1, 2)
    ax.plot(corners[:, 0], corners[:, 1], ".", markersize=1, color="0.3")
    ax.set_xticks(bu, minor=True)
    ax.set_yticks(bv, minor=True)
    ax.grid(which="minor", color="0.5", linewidth=0.5)
    ax.set_xlim(bu[0], bu[-1])
    ax.set_ylim(bv[-1], bv[0])
    ax.set_aspect("equal")
    ax.set_title(f"Knot grid {len(bu) - 1} × {len(bv) - 1}, corners per cell ({cells['positions']})", fontsize=9)
    fig.colorbar(im, ax=ax, label="corners", shrink=0.8)
    return _png(plt, fig)


def projection_diff_map(diff: dict[str, Any]) -> bytes:
    """|B(R A⁻¹(q)) − q| over the image (``evaluation.diff``), the region both
    calibrations cover outlined; grey where a calibration cannot map the pixel."""
    plt = _pyplot()
    s = diff["image"]
    title = "Projection difference, rotation fitted out" if diff["fitted_on"] != "none" else "Projection difference"
    fig, ax = _image_axes(plt, diff["image_size"], title)
    u, v = np.asarray(diff["u"], float), np.asarray(diff["v"], float)
    mag = np.array([[np.nan if x is None else x for x in row] for row in diff["magnitude"]], float)
    du, dv = (u[1] - u[0]) / 2, (v[1] - v[0]) / 2
    ax.set_facecolor("0.85")
    vmax = float(np.nanpercentile(mag, 99)) if np.isfinite(mag).any() else 1.0
    im = ax.imshow(np.ma.masked_invalid(mag), extent=(u[0] - du, u[-1] + du, v[-1] + dv, v[0] - dv), cmap="magma",
                   vmin=0, vmax=max(vmax, 1e-9), interpolation="nearest")
    fig.colorbar(im, ax=ax, label="|difference| [px]", shrink=0.8)
    if diff.get("covered_mask") is not None:
        ax.contour(u, v, np.asarray(diff["covered_mask"], float), levels=[0.5], colors="white", linewidths=1.2)
    text = (f"median {s['median']:.3g} px, p95 {s['p95']:.3g} px, max {s['max']:.3g} px over the image"
            if s["n"] else "no pixel both calibrations can map")
    if diff.get("covered_mask") is not None:
        text += "; white: covered by both"
    ax.text(0.01, 0.01, text, transform=ax.transAxes, fontsize=8, color="white",
            bbox={"facecolor": "black", "alpha": 0.5, "linewidth": 0})
    return _png(plt, fig)
