"""freecal report CAL.json [OBS.json] -o report.html [--figures DIR]: the results
page's tables and figures as one self-contained HTML page."""
from __future__ import annotations

from pathlib import Path

from .inputs import STDIN, load_calibration, load_observations, one_stdin
from .output import claim_stdout, print_json
from .outputs import OutputFolder, Outputs


def register(sub) -> None:
    p = sub.add_parser("report", help="the results page as one self-contained HTML file (and its figures as PNG)",
                       description="Write what the results page shows about a calibration as one HTML page with its "
                                   "figures embedded: parameters with their standard deviations, the model choice, "
                                   "per-view errors, residual vectors and heatmap, distortion and uncertainty maps, "
                                   "coverage. The residuals, uncertainties and coverage need the observations the "
                                   "calibration was fitted to.")
    p.add_argument("calibration", metavar="CAL.json", help="freecal.calibration/1 JSON (- : standard input)")
    p.add_argument("observations", metavar="OBS.json", nargs="?",
                   help="the freecal.observations/1 JSON it was fitted to (- : standard input)")
    p.add_argument("-o", "--output", metavar="REPORT.html", required=True, help="the HTML page (- : standard output)")
    p.add_argument("--figures", metavar="DIR", help="also write the figures (PNG) into DIR")
    p.add_argument("--json", action="store_true", help="print what was written as JSON")
    p.set_defaults(run=run)


def run(args) -> int:
    outputs = Outputs()
    page = outputs.file(args.output, "-o", "report.html")
    folder = outputs.folder(args.figures, "--figures")
    one_stdin(args.calibration, args.observations)
    if args.json:
        claim_stdout("--json")
    cal = load_calibration(args.calibration)
    obs = load_observations(args.observations) if args.observations else None
    title = "calibration from standard input" if args.calibration == STDIN else Path(args.calibration).name
    with outputs.writing():
        assert page is not None  # -o is required
        figures = write_report_page(page, folder, cal, obs, title)
    if args.json:
        print_json({"report": str(page), "figures": [str(folder.target / n) for n in figures] if folder else []})
        return 0
    if not page.to_stdout:
        print(f"wrote {page}" + (f" and {len(figures)} figures into {folder}" if folder else ""))
    if obs is None:
        print("without the observations: no residuals, uncertainties or coverage (freecal report CAL.json OBS.json)")
    return 0


def write_report_page(page, folder: OutputFolder | None, cal, obs, title: str, products=None) -> list[str]:
    """The HTML page (and the PNG figures into ``folder``), inside ``Outputs.writing``;
    the figure names. ``products``: ``tables.report_products``, if already computed."""
    from calib_core.report import figures, html, tables

    from ..version import version

    products = products if products is not None else tables.report_products(cal, obs)
    pngs = figures.report_figures(products)
    notes = [] if obs is not None else [
        "Made from the calibration alone: the residuals, the uncertainties and the coverage need the observations "
        "it was fitted to (freecal report CAL.json OBS.json)."]
    page.write(html.report_html(products, pngs, title, f"freecal {version()}", notes))
    if folder is not None:
        for name, png in pngs.items():
            folder.file(name).write(png)
    return sorted(pngs)
