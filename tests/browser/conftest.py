"""What every page test shares: Debian's Chromium under Playwright (one per module), a
`freecal serve` for the module's pages, and a fresh folder for its screenshots."""
from __future__ import annotations

import os
import shutil

import pytest

from ..conftest import ROOT
from ..service.harness import FAST, Service, wait_for

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


@pytest.fixture(scope="module")
def browser():
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is in the test extra: make test")
    if not os.access(CHROMIUM, os.X_OK):
        pytest.skip(f"{CHROMIUM} is missing: `make test` installs Debian's chromium (apt-get, as root)")
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        yield b
        b.close()


def page_service(name: str, **env: str):
    """A module fixture: `freecal serve` (API, worker; the 3D view as ``env`` says) in a subprocess."""
    @pytest.fixture(scope="module")
    def service(tmp_path_factory):
        root = tmp_path_factory.mktemp(name)
        svc = Service(root / "data", root, {**FAST, **env}).start()
        yield svc
        svc.stop()

    return service


def screenshots(name: str):
    """A module fixture: test-artifacts/NAME, emptied, for the module's screenshots."""
    @pytest.fixture(scope="module")
    def shots():
        folder = ROOT / "test-artifacts" / name
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        return folder

    return shots


def origin(page) -> str:
    """The page's server, for API requests beside it (its address also holds what it shows: #set=…&job=…)."""
    return page.url.split("#")[0].rstrip("/")


def wait_until(page, expression: str, timeout: float) -> None:
    """Poll a JS expression until true. Not page.wait_for_function: Playwright compiles its predicate
    with eval inside the page, which the page's Content-Security-Policy (rightly) forbids."""
    wait_for(lambda: page.evaluate(expression), timeout / 1000, expression, every=0.2)


def open_page(browser, service, ready: str = "#method option[value=auto]", viewport: dict | None = None,
              **options) -> tuple:
    """The page in a new tab, once ``ready`` (a selector) is there, and the list its script errors go to."""
    page = browser.new_page(viewport=viewport or {"width": 1366, "height": 768}, **options)
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"http://127.0.0.1:{service.port}/")
    page.wait_for_selector(ready, state="attached")
    return page, errors



def hover_figure(page, figure: str, x: float, y: float) -> str:
    """The tooltip's text with the mouse at (x, y), fractions of ``figure``'s canvas, once every result is
    drawn: tables and figures that arrive later move the ones below them, and a mouse placed before would
    end up elsewhere."""
    page.wait_for_selector("#results[aria-busy=false]", timeout=60_000)
    canvas = page.locator(f"{figure} canvas")
    box = canvas.bounding_box()
    canvas.hover(position={"x": box["width"] * x, "y": box["height"] * y})   # waits for the canvas to stand still
    page.wait_for_selector("#tooltip:not([hidden])")
    return page.text_content("#tooltip")
