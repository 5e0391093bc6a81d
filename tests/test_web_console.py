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
from playwright.sync_api import Browser, Page, Route, expect, sync_playwright
from service_process import serving
from test_web_browser import post_json
from web_page import ARTIFACTS, TOKEN, fly, open_page

from gcs.storage import open_storage
from uavcore.geodesy import DEFAULT_HOME
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.browser, pytest.mark.integration, pytest.mark.slow]

SMALL = {"width": 1366, "height": 768}
LARGE = {"width": 1440, "height": 900}
BAR = ["console-status", "console-vehicle", "fly", "hold", "resume", "return", "land", "abort", "sound"]
HOSTILE = "<img src=x onerror=window.injected=1>"


# 600 events into the page's log (its module, as app.js imports it): what it shows of them
EVENTS_KEPT_PROBE = """async () => {
    const { EventLog, EVENTS_KEPT } = await import("/web/alerts.js");
    const log = new EventLog();
    for (let k = 0; k < 600; k += 1) log.add({ severity: 6, text: `event ${k}` });
    const items = [...document.querySelectorAll("#event-list [data-testid=event-text]")];
    return { kept: EVENTS_KEPT, shown: items.length, first: items[0].textContent, last: items.at(-1).textContent };
}"""


# The altitude chart's legend: each line's label, its marker's border style and colour.
LEGEND_MARKERS = """() => [...document.querySelectorAll("#chart-alt .u-legend .u-series")]
    .filter((row) => row.querySelector(".u-marker"))
    .map((row) => {
        const style = getComputedStyle(row.querySelector(".u-marker"));
        return [row.querySelector(".u-label").textContent, style.borderTopStyle, style.borderTopColor];
    })"""


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
            lambda r: (
                missions_posted.append(r.url) if r.method == "POST" and urlsplit(r.url).path == "/missions" else None
            ),
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
        fly_button = page.get_by_test_id("fly")
        expect(fly_button).to_be_enabled()
        dialog = page.get_by_test_id("confirm-dialog")
        # Cancel: nothing launched
        fly_button.click()
        expect(dialog).to_be_visible()
        expect(page.get_by_test_id("confirm-text")).to_contain_text("arms and takes off at once to visit 2 buoys")
        expect(page.get_by_test_id("confirm-cancel")).to_be_focused()  # a stray Enter cancels
        page.get_by_test_id("confirm-cancel").click()
        expect(dialog).to_be_hidden()
        # Escape: nothing launched either
        fly_button.click()
        expect(dialog).to_be_visible()
        page.keyboard.press("Escape")
        expect(dialog).to_be_hidden()
        expect(page.get_by_test_id("console-message")).to_have_text("fly: cancelled")
        page.wait_for_timeout(500)
        assert missions_posted == []

        # the panel scrolled away, Fly still in reach; confirmed, it flies
        page.locator("#panel").evaluate("p => { p.scrollTop = p.scrollHeight; }")
        assert_bar_in_view(page)
        fly_button.click()
        expect(dialog).to_be_visible()
        page.screenshot(path=str(ARTIFACTS / "console_fly_confirm_1366x768.png"))
        page.get_by_test_id("confirm-ok").click()
        expect(dialog).to_be_hidden()
        expect(page.get_by_test_id("console-status")).to_contain_text(re.compile(r"^Mission \d+: "), timeout=30_000)
        assert len(missions_posted) == 1
        events = page.get_by_test_id("event-list")
        expect(events).to_contain_text("created and started")
        # with no vehicle to fly it, the mission fails: a critical status change, in the log and the banner
        expect(page.get_by_test_id("console-status")).to_contain_text("failed", timeout=60_000)
        expect(page.get_by_test_id("banner-text")).to_have_text(re.compile(r"^Mission \d+: failed"))
        failed = page.get_by_test_id("event").filter(has_text="failed")
        expect(failed).to_have_count(1)
        expect(failed).to_have_attribute("data-severity", "critical")
        page.screenshot(path=str(ARTIFACTS / "console_1366x768.png"))
        page.set_viewport_size(LARGE)
        assert_bar_in_view(page)
        scroll_everything(page)
        assert_bar_in_view(page)
        page.evaluate("() => window.scrollTo(0, 0)")
        page.screenshot(path=str(ARTIFACTS / "console_1440x900.png"))

        # the log keeps at least the last 200 events, newest first, and drops the oldest beyond what it keeps
        kept = page.evaluate(EVENTS_KEPT_PROBE)
        assert kept["shown"] == kept["kept"] >= 200, kept
        assert kept["first"].endswith("event 599") and kept["last"].endswith(f"event {600 - kept['kept']}"), kept
        browser.close()
    assert errors == []


def csv_file(rows: list[tuple[float, float, str]]) -> dict:
    text = "lat,lon,id\n" + "".join(f"{lat},{lon},{name}\n" for lat, lon, name in rows)
    return {"name": "buoys.csv", "mimeType": "text/csv", "buffer": text.encode()}


def open_console(p, errors: list[str], url: str) -> tuple[Browser, Page]:
    """The page at 1366x768 on the double's service, the token given (clicked into: the user gesture after which
    the page may sound), the vehicle heard."""
    browser, page = open_page(p, errors, SMALL)
    page.on("console", lambda m: errors.append(m.text) if re.search("Content Security|injected", m.text) else None)
    page.goto(url)
    page.locator("#token").click()
    page.locator("#token").fill(TOKEN)
    expect(page.get_by_test_id("link-status")).to_contain_text("disarmed", timeout=15_000)
    expect(page.get_by_test_id("vehicle-name")).to_have_text("vehicle 1 (ARDUPILOTMEGA QUADROTOR)")
    return browser, page


def event(page: Page, text: str):
    return page.get_by_test_id("event").filter(has_text=text)


def test_a_critical_statustext_raises_the_banner_and_the_log_keeps_every_event_as_text(double_and_service):
    url, double = double_and_service
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_console(p, errors, url)
        banner = page.get_by_test_id("banner")
        # a warning: logged with its severity, no banner
        double.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_WARNING, b"Low battery: 25% remaining"))
        warning = event(page, "Low battery: 25% remaining")
        expect(warning).to_have_count(1, timeout=10_000)
        expect(warning).to_have_attribute("data-severity", "warning")
        expect(warning.get_by_test_id("event-time")).to_have_text(re.compile(r"^\d\d:\d\d:\d\d$"))
        expect(banner).to_be_hidden()

        # a critical one, made of markup: the banner in plain words, the MAVLink detail a click away, all as text
        double.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_CRITICAL, HOSTILE.encode()))
        expect(banner).to_be_visible(timeout=10_000)
        expect(page.get_by_test_id("banner-severity")).to_have_text("critical")
        expect(page.get_by_test_id("banner-text")).to_have_text(f"vehicle 1 reports: {HOSTILE}")
        detail = page.get_by_test_id("banner-detail")
        expect(detail).to_be_hidden()
        page.locator("#banner-details summary").click()
        expect(detail).to_have_text("STATUSTEXT, MAV_SEVERITY_CRITICAL (2)")
        critical = event(page, HOSTILE)
        expect(critical).to_have_count(1)
        expect(critical).to_have_attribute("data-severity", "critical")
        expect(critical.get_by_test_id("event-text")).to_have_text(f"vehicle 1 reports: {HOSTILE}")
        expect(page.get_by_test_id("event").first).to_have_attribute("data-severity", "critical")  # newest first
        # the beep (WebAudio, after the click into the token field): counted on the sound toggle
        expect(page.get_by_test_id("sound")).to_have_attribute("data-beeps", "1")
        assert page.locator("#top img, #event-list img, script:not([src])").count() == 0
        assert page.evaluate("window.injected") is None
        page.screenshot(path=str(ARTIFACTS / "console_critical_banner_1366x768.png"))

        # the same words again are a new event (the count of STATUSTEXTs heard rises); Dismiss hides the banner
        double.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_CRITICAL, HOSTILE.encode()))
        expect(critical).to_have_count(2, timeout=10_000)
        expect(page.get_by_test_id("banner-more")).to_have_text("(+1 earlier: see Events)")
        page.get_by_test_id("banner-dismiss").click()
        expect(banner).to_be_hidden()
        # muted: a critical event still shows, without a beep
        page.get_by_test_id("sound").click()
        expect(page.get_by_test_id("sound")).to_have_text("Sound off")
        double.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_EMERGENCY, b"Motor 3 failure"))
        expect(banner).to_be_visible(timeout=10_000)
        expect(page.get_by_test_id("banner-severity")).to_have_text("emergency")
        expect(page.get_by_test_id("sound")).to_have_attribute("data-beeps", "2")
        page.get_by_test_id("banner-dismiss").click()

        # a mission flown: its status changes and the vehicle's mode changes are in the log
        lat, lon, _ = DEFAULT_HOME
        page.locator("#import").set_input_files(csv_file([(lat + 0.0004, lon, "B1"), (lat, lon + 0.0005, "B2")]))
        expect(page.locator("#buoy-count")).to_have_text("2 buoys")
        page.get_by_test_id("fly").click()
        expect(page.get_by_test_id("confirm-text")).to_contain_text("Vehicle 1 (ARDUPILOTMEGA QUADROTOR) arms")
        page.get_by_test_id("confirm-ok").click()
        status = page.get_by_test_id("console-status")
        expect(status).to_have_text(re.compile(r"^Mission \d+: completed, 2 of 2 buoys visited$"), timeout=120_000)
        expect(event(page, "created and started")).to_have_count(1)
        expect(event(page, ": flying, ")).not_to_have_count(0)
        completed = event(page, ": completed, 2 of 2 buoys visited")
        expect(completed).to_have_count(1)
        expect(completed).to_have_attribute("data-severity", "notice")
        expect(completed).to_have_attribute("title", re.compile(r"^status flying → completed"))
        expect(event(page, "vehicle 1: mode ")).not_to_have_count(0)
        # times as the operator reads them: each buoy's arrival on the wall clock (the double tells its clock by
        # SYSTEM_TIME), the exact vehicle seconds on hover; the history's date; the charts' lines named by style
        reached = page.get_by_test_id("inspection-reached")
        expect(reached).to_have_count(2, timeout=10_000)
        expect(reached.first).to_have_text(re.compile(r"^reached at \d\d:\d\d:\d\d$"))
        expect(reached.first).to_have_attribute("title", re.compile(r"^vehicle time \d+\.\d s \(since its boot\)$"))
        expect(page.get_by_test_id("history-date").first).to_have_text(re.compile(r"20\d\d"))
        markers = {label: (style, colour) for label, style, colour in page.evaluate(LEGEND_MARKERS)}
        assert markers["actual (solid)"][0] == "solid" and markers["desired (dashed)"][0] == "dashed", markers
        assert markers["actual (solid)"][1] != markers["desired (dashed)"][1], markers
        expect(page.get_by_test_id("fly")).to_be_enabled()  # the mission is over: the buoys may fly again
        expect(page.get_by_test_id("abort")).to_be_disabled()
        page.screenshot(path=str(ARTIFACTS / "console_events_1366x768.png"))
        page.screenshot(path=str(ARTIFACTS / "console_flown_full_page.png"), full_page=True)

        # a refusal to arm, its cause in the vehicle's STATUSTEXT just before (as ArduPilot's PreArm checks say it):
        # the banner says both in plain words, the MAV_RESULT one click away
        double._arm = lambda: False  # the double refuses every arming from now on
        double.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_CRITICAL, b"PreArm: Battery 0% below 7%"))
        expect(event(page, "PreArm: Battery 0% below 7%")).to_have_count(1, timeout=10_000)
        page.get_by_test_id("banner-dismiss").click()
        fly(page)
        banner_text = page.get_by_test_id("banner-text")
        expect(banner_text).to_have_text(
            re.compile(
                r'^Mission \d+: failed: the vehicle refused to arm\. The vehicle said: "PreArm: Battery 0% below 7%"\.$'
            ),
            timeout=60_000,
        )
        expect(page.get_by_test_id("banner-detail")).to_contain_text("the vehicle refused to arm (MAV_RESULT_FAILED)")
        expect(status).to_have_text(re.compile(r"^Mission \d+: failed: the vehicle refused to arm$"))
        refusal = event(page, "failed: the vehicle refused to arm.")
        expect(refusal).to_have_attribute("data-severity", "critical")
        expect(refusal).to_have_attribute(
            "title", re.compile(r"reason: the vehicle refused to arm \(MAV_RESULT_FAILED\)$")
        )
        page.screenshot(path=str(ARTIFACTS / "console_refused_to_arm_1366x768.png"))

        # the cause sent with the refusal (as PX4 does, beside its COMMAND_ACK): the service's reason carries it,
        # and the banner says it once
        def refuse_saying_why() -> bool:
            double.send(
                mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_CRITICAL, b"PreArm: Battery 0% below 7%")
            )
            return False

        double._arm = refuse_saying_why
        page.get_by_test_id("banner-dismiss").click()
        fly(page)
        expect(banner_text).to_have_text(
            re.compile(r"^Mission \d+: failed: the vehicle refused to arm: PreArm: Battery 0% below 7%\.$"),
            timeout=60_000,
        )

        # the vehicle falls silent: the link lost is critical, and the bar says so; heard again, the banner goes
        # by itself and the log keeps both
        double.silent = True
        expect(page.get_by_test_id("banner-text")).to_have_text("Lost contact with vehicle 1", timeout=30_000)
        expect(event(page, "Lost contact with vehicle 1")).to_have_attribute("data-severity", "critical")
        expect(page.get_by_test_id("console-vehicle")).to_have_text("vehicle 1: no contact")
        double.silent = False
        expect(event(page, "Contact with vehicle 1 back")).to_have_count(1, timeout=30_000)
        expect(page.get_by_test_id("banner")).to_be_hidden()
        expect(event(page, "Lost contact with vehicle 1")).to_have_count(1)
        browser.close()
    assert errors == []


def test_console_flight_commands_hold_resume_return_and_land_in_the_browser(double_and_service):
    """Needs POST /missions/{id}/hold, /resume, /return and /land (the service's operator commands, each answering
    the mission with progress.command "hold" | "return" | "land" | null)."""
    url, _ = double_and_service
    errors: list[str] = []
    commands: list[tuple[str, int]] = []
    with sync_playwright() as p:
        browser, page = open_console(p, errors, url)
        page.on(
            "response",
            lambda r: (
                commands.append((urlsplit(r.url).path.rsplit("/", 1)[-1], r.status))
                if r.request.method == "POST" and re.search(r"/missions/\d+/(hold|resume|return|land)$", r.url)
                else None
            ),
        )
        # buoys far enough apart (about 700 m) for the double at 40 m/s to be flying between them a while
        lat, lon, _ = DEFAULT_HOME
        page.locator("#import").set_input_files(csv_file([(lat + 0.006, lon, "B1"), (lat + 0.006, lon + 0.008, "B2")]))
        page.get_by_test_id("fly").click()
        page.get_by_test_id("confirm-ok").click()
        status = page.get_by_test_id("console-status")
        expect(status).to_contain_text("flying", timeout=60_000)
        buttons = {name: page.get_by_test_id(name) for name in ("fly", "hold", "resume", "return", "land", "abort")}

        def enabled(*names: str) -> None:
            for name, button in buttons.items():
                (expect(button).to_be_enabled if name in names else expect(button).to_be_disabled)()

        enabled("hold", "return", "land", "abort")
        dialog = page.get_by_test_id("confirm-dialog")
        buttons["hold"].click()  # the safe stop: not asked
        expect(status).to_contain_text("holding position", timeout=15_000)
        enabled("resume", "return", "land", "abort")
        buttons["resume"].click()
        expect(status).to_contain_text("flying, ", timeout=15_000)
        buttons["return"].click()
        expect(page.get_by_test_id("confirm-text")).to_contain_text("flies back home and lands there")
        page.get_by_test_id("confirm-ok").click()
        expect(status).to_contain_text("returning home", timeout=15_000)
        enabled("hold", "resume", "land", "abort")
        buttons["resume"].click()
        expect(status).to_contain_text("flying, ", timeout=15_000)
        buttons["land"].click()
        expect(page.get_by_test_id("confirm-warning")).to_contain_text("over water")
        page.screenshot(path=str(ARTIFACTS / "console_flight_land_confirm_1366x768.png"))
        page.keyboard.press("Escape")  # cancelled: nothing sent
        expect(dialog).to_be_hidden()
        buttons["land"].click()
        page.get_by_test_id("confirm-ok").click()
        expect(status).to_contain_text("landing where it is", timeout=15_000)
        for name in ("hold", "resume", "return", "land"):  # (Abort too, once the vehicle is down: not waited for)
            expect(buttons[name]).to_be_disabled()
        assert commands == [("hold", 200), ("resume", 200), ("return", 200), ("resume", 200), ("land", 200)]
        expect(event(page, "landing where it is")).to_have_count(1)
        browser.close()
    assert errors == []


def test_the_bar_follows_the_operator_command_in_force_as_the_contract_says(tmp_path):
    """The page's side of the flight commands, before the service has them: Playwright plays the contract (POST
    /missions/{id}/hold | resume | return | land answering the mission, whose progress.command names the command in
    force, the GET of the mission saying the same; a refusal in the project's error shape) over a mission stored
    as flying. The buttons follow the command in force, Return and Land ask first (Land warning of water), a
    refusal is said in the bar and logged."""
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url:
        lat, lon, _ = DEFAULT_HOME
        buoys = [{"id": "B1", "lat": lat + 0.001, "lon": lon}, {"id": "B2", "lat": lat, "lon": lon + 0.001}]
        mission = post_json(f"{url}/missions", {"buoys": buoys, "start": False})
        storage = open_storage(tmp_path / "gcs.sqlite")
        storage.set_status(mission["id"], "flying", None)
        storage.close()
        in_force: dict[str, str | None] = {"command": None}
        posted: list[str] = []

        def contract(route: Route) -> None:
            path = urlsplit(route.request.url).path
            match = re.fullmatch(r"/missions/(\d+)(?:/(hold|resume|return|land))?", path)
            if match is None or (match[2] is None and route.request.method != "GET"):
                route.continue_()
                return
            if match[2] is not None:
                posted.append(match[2])
                if match[2] == "land" and posted.count("land") == 1:
                    refusal = {"detail": [{"type": "conflict", "loc": [], "msg": "the vehicle is not flying"}]}
                    route.fulfill(status=409, json=refusal)
                    return
                in_force["command"] = None if match[2] == "resume" else match[2]
            answer = route.fetch(url=f"{url}/missions/{match[1]}", method="GET")
            document = answer.json()
            document["progress"] = {**(document.get("progress") or {}), "command": in_force["command"]}
            route.fulfill(response=answer, json=document)

        errors: list[str] = []
        with sync_playwright() as p:
            browser, page = open_page(p, errors, SMALL)
            page.route(re.compile(r"/missions/\d+(/(hold|resume|return|land))?$"), contract)
            page.goto(url)
            status = page.get_by_test_id("console-status")
            expect(status).to_have_text(f"Mission {mission['id']}: flying, 0 of 2 buoys visited", timeout=30_000)
            names = ("fly", "hold", "resume", "return", "land", "abort")
            buttons = {name: page.get_by_test_id(name) for name in names}

            def enabled(*wanted: str) -> None:
                for name, button in buttons.items():
                    (expect(button).to_be_enabled if name in wanted else expect(button).to_be_disabled)()

            enabled("hold", "return", "land", "abort")
            buttons["hold"].click()
            expect(status).to_have_text(f"Mission {mission['id']}: holding position (0 of 2 buoys visited)")
            enabled("resume", "return", "land", "abort")
            expect(event(page, "holding position")).to_have_count(1)
            buttons["resume"].click()
            expect(status).to_contain_text("flying, 0 of 2")
            buttons["return"].click()
            expect(page.get_by_test_id("confirm-text")).to_contain_text("flies back home and lands there")
            page.get_by_test_id("confirm-cancel").click()
            assert posted == ["hold", "resume"]
            buttons["return"].click()
            page.get_by_test_id("confirm-ok").click()
            expect(status).to_contain_text("returning home")
            enabled("hold", "resume", "land", "abort")
            buttons["land"].click()
            expect(page.get_by_test_id("confirm-warning")).to_contain_text("over water")
            page.screenshot(path=str(ARTIFACTS / "console_land_confirm_1366x768.png"))
            page.get_by_test_id("confirm-ok").click()
            # refused: said beside the buttons and logged; the command in force stays
            expect(page.get_by_test_id("console-message")).to_have_text("409: the vehicle is not flying")
            expect(event(page, "Land refused: 409: the vehicle is not flying")).to_have_attribute(
                "data-severity", "warning"
            )
            expect(status).to_contain_text("returning home")
            buttons["land"].click()
            page.get_by_test_id("confirm-ok").click()
            expect(status).to_contain_text("landing where it is")
            enabled("abort")
            assert posted == ["hold", "resume", "return", "land", "land"]
            page.screenshot(path=str(ARTIFACTS / "console_landing_1366x768.png"))
            browser.close()
    assert errors == []
