"""What the browser tests of the map page share: headless Chromium, the artifacts directory, a page opened on it,
the wait for the service to hear its vehicle, and the token the ArduCopter double's service asks for (the
`double_and_service` fixture is in conftest.py)."""

from __future__ import annotations

import json
import time
import urllib.request
from pathlib import Path

from playwright.sync_api import Browser, Page, Playwright

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
REPO = Path(__file__).resolve().parent.parent
ARTIFACTS = REPO / "test-artifacts"
TOKEN = "page-token-0123456789"


def wait_until_connected(url: str, log: Path) -> None:
    """Until the service at url has heard its vehicle (a 120 s backstop for a loaded machine, then the log says
    why not)."""
    deadline = time.monotonic() + 120
    while True:
        try:
            with urllib.request.urlopen(f"{url}/vehicle", timeout=1) as answer:
                if json.load(answer)["connected"]:
                    return
        except OSError:
            pass
        if time.monotonic() > deadline:
            raise AssertionError("the service or the vehicle did not come up: " + log.read_text())
        time.sleep(0.2)


def open_page(p: Playwright, errors: list[str], viewport: dict[str, int] | None = None) -> tuple[Browser, Page]:
    """Headless Chromium with one desktop-sized page (1280x800 unless `viewport` says); the page's uncaught errors go
    to `errors`."""
    ARTIFACTS.mkdir(exist_ok=True)
    browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
    page = browser.new_page(viewport=viewport or {"width": 1280, "height": 800})
    page.on("pageerror", lambda error: errors.append(str(error)))
    return browser, page


def fly(page: Page) -> None:
    """Fly, as an operator does: the control bar's Fly, then the confirmation dialog's button (controls.js)."""
    page.get_by_test_id("fly").click()
    page.get_by_test_id("confirm-ok").click()
