"""The report as one self-contained HTML page: the tables and figures the results
page shows (``tables.report_products``, ``figures.report_figures``), the figures
embedded as PNG data URIs, no script and nothing fetched: it opens offline, mails
as one file and prints.
"""
from __future__ import annotations

import base64
import html
from collections.abc import Iterable, Sequence
from typing import Any

from ..fit_report import ChoiceReport, grid_score

# figure file → (id, title, caption), in the order the page shows them
FIGURES = {
    "residual_vectors.png": ("fig-vectors", "Corner residuals",
                             "Every inlier's residual (observed − projected) as an arrow, scaled; outliers as crosses."),
    "residual_heatmap.png": ("fig-heatmap", "Residual heatmap", "Mean corner error per image cell (inliers)."),
    "view_errors.png": ("fig-view-errors", "Error per view", "rmse of each view's inliers."),
    "distortion_maps.png": ("fig-distortion-maps", "Distortion maps",
                            "Δx and Δy of observed pixel − ideal pinhole pixel, one colour scale."),
    "distortion_field.png": ("fig-distortion-field", "Distortion field",
                             "The same offsets as vectors (to scale)."),
    "knot_grid.png": ("fig-knots", "Knot grid", "The B-spline field's knot cells and the corners in each."),
    "uncertainty.png": ("fig-uncertainty", "Projection uncertainty",
                        "Standard deviation of a projected direction if the corners were measured again with the "
                        "same noise; pale: no corner nearby, the model extrapolates there."),
    "coverage.png": ("fig-coverage", "Coverage of the image", "Corners per image cell, all views."),
}

STYLE = """
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; color: #1d1d1f; margin: 0 auto;
       max-width: 1100px; padding: 1.5rem; }
h1 { font-size: 1.6rem; margin-bottom: .2rem; } h2 { font-size: 1.2rem; margin-top: 2rem; border-bottom: 1px solid #ddd; }
.muted { color: #666; } .warning { color: #8a4b00; }
table { border-collapse: collapse; margin: .6rem 0; font-variant-numeric: tabular-nums; }
th, td { padding: .25rem .7rem; border-bottom: 1px solid #eee; text-align: right; }
th:first-child, td:first-child { text-align: left; } thead th { border-bottom: 2px solid #ccc; }
tr.best { background: #eef6ee; font-weight: 600; }
.figures { display: grid; grid-template-columns: repeat(auto-fill, minmax(480px, 1fr)); gap: 1.2rem; }
figure { margin: 0; } figure img { width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-size: .9rem; color: #555; }
@media print { .figures { display: block; } figure { break-inside: avoid; margin-bottom: 1rem; } }
"""


def report_html(products: dict[str, Any], figures: dict[str, bytes], title: str, generator: str = "freecal",
                notes: Sequence[str] = ()) -> str:
    """The page: ``products`` (``tables.report_products``), ``figures`` (file name →
    PNG bytes), a ``title`` (e.g. the calibration's file name), who made it, and
    ``notes`` shown under the title (e.g. what is missing without the corners)."""
    cal = products["calibration.json"]
    parts = [f"<header><h1>{_e(title)}</h1><p class='muted'>Calibration report · {_e(generator)}</p>",
             *(f"<p class='warning'>{_e(n)}</p>" for n in notes), "</header>",
             _summary(cal), _parameters(products.get("parameters.json")), _model_choice(cal), _restart(cal),
             _smoothing(cal), _views(products["view_residuals.json"], cal), _figures(figures)]
    return ("<!doctype html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{_e(title)}: calibration report</title><style>{STYLE}</style></head>\n<body>\n"
            + "\n".join(p for p in parts if p) + "\n</body></html>\n")


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(x: Any, digits: int = 4) -> str:
    if x is None or (isinstance(x, float) and x != x):
        return "—"
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return _e(x)
    if isinstance(x, int):
        return f"{x:d}"
    return f"{x:.{digits}f}" if 1e-3 <= abs(x) < 1e6 or x == 0 else f"{x:.{digits}g}"


def _table(table_id: str, caption: str, headers: Sequence[str], rows: Iterable[Sequence[Any]],
           best: Sequence[bool] | None = None) -> str:
    head = "".join(f"<th scope='col'>{_e(h)}</th>" for h in headers)
    body = []
    for k, row in enumerate(rows):
        cls = " class='best'" if best is not None and best[k] else ""
        cells = "".join((f"<th scope='row'>{_e(c)}</th>" if i == 0 else f"<td>{c}</td>") for i, c in enumerate(row))
        body.append(f"<tr{cls}>{cells}</tr>")
    return (f"<table id='{table_id}'><caption class='muted'>{_e(caption)}</caption><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>")


def _summary(cal: dict[str, Any]) -> str:
    m = cal.get("metrics", {})
    w, h = cal["image_size"]
    chosen = cal.get("diagnostics", {}).get("model_choice", {}).get("summary")
    outliers = sum(len(v.get("outliers", [])) for v in cal.get("views", []))
    rows = [("method", _e(cal.get("model"))), ("model", _e(cal["distortion"]["type"] + f" on the {cal.get('base', 'pinhole')} base")),
            *((("model chosen", _e(chosen)),) if chosen else ()),
            ("image", f"{w} × {h} px"), ("views used", _num(len(cal.get("views", [])))),
            ("views dropped", _num(len(cal.get("dropped_views", [])))), ("points", _num(m.get("n_points"))),
            ("outliers", _num(outliers)), ("rmse [px]", _num(m.get("rmse"))), ("rmse per axis [px]", _num(m.get("rmse_axis"))),
            ("centre rmse [px]", _num(m.get("rmse_center"))), ("edge rmse [px]", _num(m.get("rmse_edge")))]
    return "<section id='summary'><h2>Summary</h2>" + _table("summary-table", "", ["", "value"], rows) + (
        "<p class='muted'>rmse: per-point Euclidean RMS (OpenCV's figure); per axis: RMS of the x and y components "
        "(mrcal's). Centre: corners in the middle half of the image.</p></section>")


def _parameters(doc: dict[str, Any] | None) -> str:
    """The ``diagnostics.camera`` block (``evaluation.parameters``) as the page shows it."""
    if doc is None:
        return ""
    rows = [(r["name"], _num(r["value"], 6),
             f"± {_num(r['std'], 4)}" if r["std"] is not None else _e(r.get("note", "—")), _e(r["unit"]))
            for r in doc["parameters"]]
    f = doc.get("field")
    if f and "knot_intervals" in f:
        rows.append((f"{f['type']} field over {f['over']}", f"{f['knot_intervals'][0]} × {f['knot_intervals'][1]} "
                     f"knot intervals", f"largest offset {_num(f['largest_offset_px'])}", "px"))
    fov = doc.get("field_of_view_deg") or {}
    seen = ", ".join(f"{k} {_num(v, 1)}°" for k, v in fov.items() if v is not None)
    note = (f"σ = {_num(doc['sigma_px'])} px per axis (from the residuals), {_num(doc['effective_parameters'], 1)} "
            f"effective parameters; ± is the spread if the corners were measured again with that noise."
            if doc.get("sigma_px") is not None else doc.get("uncertainty_error", ""))
    verdict = doc.get("verdict", {}).get("text", "")
    return ("<section id='parameters'><h2>Parameters</h2>"
            + f"<p>{_e(doc['model'])}, {_e(doc['chosen'])}.</p>"
            + _table("parameters-table", "fitted parameters ± one standard deviation",
                     ["parameter", "value", "± standard deviation", "units"], rows)
            + (f"<p>Field of view: {_e(seen)}.</p>" if seen else "")
            + (f"<p><strong>{_e(verdict)}</strong></p>" if verdict else "")
            + f"<p class='muted'>{_e(note)}</p></section>")


def _model_choice(cal: dict[str, Any]) -> str:
    choice = cal.get("diagnostics", {}).get("model_choice")
    if not choice:
        return ""
    report = ChoiceReport.from_json(choice)
    rows = [(c.label, _num(c.validation_rmse),
             "—" if c.standard_error_rmse is None else f"± {_num(c.standard_error_rmse)}",
             _num(c.n_params), _e(report.status(c))) for c in report.candidates]
    return ("<section id='model-choice'><h2>Model choice</h2>"
            + _table("model-choice-table", f"Model chosen: {report.summary}",
                     ["candidate", "validation rmse per axis [px]", "± one standard error of its excess",
                      "parameters", ""], rows, [c.chosen for c in report.candidates])
            + f"<p class='muted'>How: {_e(report.how)}. Rule: {_e(report.rule)}.</p></section>")


def _restart(cal: dict[str, Any]) -> str:
    r = cal.get("diagnostics", {}).get("restart")
    if not r:
        return ""
    kept = "the restarted fit was kept" if r["kept"] == "restarted" else "the restart did no better; the first fit was kept"
    warning = f" Warning: {r['warning']}." if r.get("warning") else ""
    text = (f"The field's fit was restarted from a parametric camera: {r['reason']}; {kept} "
            f"({_num(r['first']['rmse'], 3)} px, then {_num(r['restarted']['rmse'], 3)} px).{warning}")
    return f"<p id='restart-note' class='{'warning' if warning else 'muted'}'>{_e(text)}</p>"


def _smoothing(cal: dict[str, Any]) -> str:
    curve = cal.get("diagnostics", {}).get("smoothing_curve") or []
    if not curve:
        return ""
    s = cal.get("settings", {})
    chosen = [c.get("intervals") == s.get("intervals_used") and c.get("bandwidth_factor") == s.get("bandwidth_factor_used")
              and "skipped" not in c for c in curve]
    rows = [(" × ".join(map(str, c["intervals"])), _num(c.get("bandwidth_factor"), 1),
             "—" if "skipped" in c else _num(c.get("lambda_smooth"), 3), "—" if "skipped" in c else _num(grid_score(c)),
             "—" if "skipped" in c else _num(c.get("dof"), 0),
             "chosen" if ok else (f"skipped ({_e(c['skipped'])})" if "skipped" in c else ""))
            for c, ok in zip(curve, chosen, strict=True)]
    return ("<section id='smoothing'><h2>Knot grid and smoothing</h2>"
            + _table("smoothing-table", "chosen from the data (validation over the views; lower is better)",
                     ["knot grid", "bandwidth factor", "smoothing λ", "validation error [px²]", "effective parameters",
                      ""], rows, chosen) + "</section>")


def _views(views: list[dict[str, Any]], cal: dict[str, Any]) -> str:
    rows = [(v["view"], _num(v["n_points"]), _num(v["rmse"]), _num(v["rmse_axis"]), _num(v["max_error"]),
             _num(v["outliers"])) for v in views]
    dropped = "".join(f"<li>{_e(d.get('name'))}: {_e(d.get('reason'))}</li>" for d in cal.get("dropped_views", []))
    return ("<section id='views'><h2>Per view</h2>"
            + _table("views-table", f"{len(views)} views", ["view", "points", "rmse [px]", "rmse per axis [px]",
                                                             "max error [px]", "outliers"], rows)
            + (f"<p>Dropped views:</p><ul>{dropped}</ul>" if dropped else "") + "</section>")


def _figures(figures: dict[str, bytes]) -> str:
    items = []
    for name, (fig_id, title, caption) in FIGURES.items():
        if name not in figures:
            continue
        data = base64.b64encode(figures[name]).decode("ascii")
        items.append(f"<figure id='{fig_id}'><img src='data:image/png;base64,{data}' alt='{_e(title)}'>"
                     f"<figcaption><strong>{_e(title)}.</strong> {_e(caption)}</figcaption></figure>")
    return "<section id='figures'><h2>Figures</h2><div class='figures'>" + "".join(items) + "</div></section>"
