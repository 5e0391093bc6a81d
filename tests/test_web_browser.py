"""The map page in a real browser (headless Chromium via Playwright) against the real service and vehicle.

Place four buoys by clicking the map, plan (the route and its length appear), fly against the SITL vehicle
(`python -m sitl_quad --lockstep`) until the mission completes, and check the live track and the history.
Then hostile text: a vehicle (the ArduCopter double, real MAVLink over UDP) whose STATUSTEXTs and a buoy file
whose ids carry markup and script, shown literally on the page and in the report, where nothing of it runs.
Screenshots go to test-artifacts/.
"""

import json
import re
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from ardupilot_double import ArduCopterDouble
from playwright.sync_api import Browser, Page, Playwright, expect, sync_playwright
from service_process import serving

from bench.long_mission import store_long_mission
from gcs.storage import open_storage
from uavcore.geodesy import DEFAULT_HOME
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.browser, pytest.mark.integration, pytest.mark.slow]

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
ARTIFACTS = Path(__file__).resolve().parent.parent / "test-artifacts"
HOSTILE = "<img src=x onerror=window.injected=1>"
STATUS_PROBE = """async () => {
    const { MissionStatus } = await import("/web/status.js");
    let unknown = null;
    try { MissionStatus.no_such_status; } catch (error) { unknown = error.message; }
    return { flying: MissionStatus.flying, unknown };
}"""


def csv_file(text: str) -> dict:
    """A file for <input type=file> (Playwright's set_input_files payload)."""
    return {"name": "buoys.csv", "mimeType": "text/csv", "buffer": text.encode()}


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def stop(process: subprocess.Popen) -> None:
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


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


@pytest.fixture
def stack(tmp_path):
    """The vehicle (lockstep) and `python -m gcs serve` on free ports; yields the page's URL."""
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    logs = open(tmp_path / "stack.log", "w")  # noqa: SIM115 - closed below
    vehicle = subprocess.Popen(
        [sys.executable, "-m", "sitl_quad", "--port", str(udp), "--lockstep"], stdout=logs, stderr=subprocess.STDOUT
    )
    gcs = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "gcs",
            "serve",
            "--vehicle",
            f"udpout:127.0.0.1:{udp}",
            "--port",
            str(http),
            "--db",
            str(tmp_path / "gcs.sqlite"),
        ],
        stdout=logs,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{http}"
    wait_until_connected(url, tmp_path / "stack.log")
    yield url
    stop(gcs)
    stop(vehicle)
    logs.close()


def open_page(p: Playwright, errors: list[str]) -> tuple[Browser, Page]:
    """Headless Chromium with one desktop-sized page; the page's uncaught errors go to `errors`."""
    ARTIFACTS.mkdir(exist_ok=True)
    browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.on("pageerror", lambda error: errors.append(str(error)))
    return browser, page


def test_place_plan_and_fly_in_the_browser(stack):
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        page.goto(stack)
        expect(page.get_by_test_id("link-status")).to_contain_text("disarmed", timeout=10_000)
        # the mission states come from the service's OpenAPI enum; a name it does not define throws
        statuses = page.evaluate(STATUS_PROBE)
        assert statuses == {"flying": "flying", "unknown": "unknown MissionStatus.no_such_status"}

        box = page.locator("#map").bounding_box()
        centre_x, centre_y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        for dx, dy in ((-120, -60), (90, -90), (140, 60), (-60, 100)):
            page.mouse.click(centre_x + dx, centre_y + dy)
        expect(page.locator("#buoy-count")).to_have_text("4 buoys")
        expect(page.locator(".buoy-icon")).to_have_count(4)

        page.get_by_role("button", name="Plan").click()
        summary = page.get_by_test_id("plan-summary")
        expect(summary).to_contain_text("km", timeout=10_000)
        expect(summary).to_contain_text("% shorter")
        # the planned route is drawn: a dashed polyline in Leaflet's overlay pane
        expect(page.locator(".leaflet-overlay-pane path[stroke-dasharray]")).to_have_count(1)
        page.screenshot(path=str(ARTIFACTS / "web_planned.png"))

        page.get_by_role("button", name="Fly").click()
        status = page.get_by_test_id("mission-status")
        expect(status).to_contain_text("flying", timeout=30_000)
        expect(page.locator(".vehicle-icon")).to_have_count(1)
        expect(status).to_contain_text("completed", timeout=180_000)
        # the flown track (solid polyline) lies over the route, the history lists the mission with its files
        assert page.locator(".leaflet-overlay-pane path:not([stroke-dasharray])").count() >= 1
        expect(page.locator(".buoy-icon.visited")).to_have_count(4)
        expect(page.locator("#figures")).to_contain_text("buoys reached 4 / 4")
        expect(page.locator("#history-rows tr")).to_have_count(1, timeout=5_000)
        expect(page.locator("#history-rows")).to_contain_text("completed")
        expect(page.locator("#history-rows a", has_text=".waypoints")).to_have_count(1)
        page.screenshot(path=str(ARTIFACTS / "web_flown.png"), full_page=True)

        page.set_viewport_size({"width": 390, "height": 844})  # a phone: the panel stacks over the map
        page.screenshot(path=str(ARTIFACTS / "web_narrow.png"), full_page=True)
        assert page.locator("#map").bounding_box()["width"] <= 390

        # text from a file (a buoy's name, the service's error quoting it) is shown as text, never as markup
        with urllib.request.urlopen(f"{stack}/vehicle", timeout=5) as answer:
            depot = json.load(answer)["depot"]
        lat, lon = depot["lat"], depot["lon"]
        page.locator("#import").set_input_files(csv_file(f"lat,lon,id\n{lat},{lon},{HOSTILE}\n"))
        expect(page.get_by_title(HOSTILE)).to_have_count(1)
        page.locator("#import").set_input_files(csv_file(f"lat,lon\n{HOSTILE},{lon}\n"))
        expect(page.locator("#message")).to_contain_text(HOSTILE)
        assert page.locator("#panel img, .leaflet-marker-pane img").count() == 0
        assert page.evaluate("window.injected") is None

        # "show" in the history draws the stored mission again in place of the imported buoy
        page.locator("#history-rows button", has_text="show").click()
        expect(page.locator(".buoy-icon.visited")).to_have_count(4)
        expect(page.locator(".buoy-icon")).to_have_count(4)
        browser.close()
    assert errors == []


# Each would set window.injected (or log "injected") if the page ever let it become markup and run it.
IMG_TEXT = "<img src=x onerror=window.injected=1>"
SCRIPT_TEXT = "<script>window.injected=2;console.log('injected')</script>"
TOKEN = "page-token-0123456789"


@pytest.fixture
def double_and_service(tmp_path):
    """`python -m gcs serve --token ...` listening (udpin) for the ArduCopter double; yields (url, double)."""
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    logs = open(tmp_path / "service.log", "w")  # noqa: SIM115 - closed below
    argv = [sys.executable, "-m", "gcs", "serve", "--vehicle", f"udpin://127.0.0.1:{udp}", "--port", str(http)]
    argv += ["--db", str(tmp_path / "gcs.sqlite"), "--token", TOKEN, "--vehicle-wait", "60"]
    gcs = subprocess.Popen(argv, stdout=logs, stderr=subprocess.STDOUT)
    double = ArduCopterDouble(udp).start()
    url = f"http://127.0.0.1:{http}"
    wait_until_connected(url, tmp_path / "service.log")
    yield url, double
    double.stop()
    stop(gcs)
    logs.close()


def test_text_from_the_vehicle_and_from_files_shows_literally_and_never_runs(double_and_service):
    url, double = double_and_service
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        # page errors, a Content-Security-Policy violation (Chromium logs each), anything "injected"; not the
        # other console errors of a machine offline (the OpenStreetMap probe, the favicon)
        problems: list[str] = []
        page.on("pageerror", lambda error: problems.append(str(error)))
        page.on(
            "console", lambda m: problems.append(m.text) if re.search("Content Security|injected", m.text) else None
        )
        page.goto(url)
        # the service has a token: the live stream opens once the page has it (offered as a subprotocol)
        page.locator("#token").fill(TOKEN)
        expect(page.get_by_test_id("link-status")).to_contain_text("disarmed", timeout=15_000)

        # the vehicle's own words, from MAVLink STATUSTEXT over UDP to the service and /ws to the page
        vehicle_text = page.get_by_test_id("vehicle-text")
        for text in (IMG_TEXT, SCRIPT_TEXT[:50]):  # a STATUSTEXT carries at most 50 characters
            double.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_WARNING, text.encode()))
            expect(vehicle_text).to_have_text(text, timeout=10_000)
        assert page.locator("header img, header script").count() == 0

        # buoy ids from a file: shown as the markers' titles, flown, and named in the report
        lat, lon, _ = DEFAULT_HOME
        rows = f"lat,lon,id\n{lat + 0.0004},{lon},{IMG_TEXT}\n{lat},{lon + 0.0005},{SCRIPT_TEXT}\n"
        page.locator("#import").set_input_files(csv_file(rows))
        # the markers' titles, exactly (the header's STATUSTEXT line has the vehicle's texts as its title too)
        markers = page.locator(".leaflet-marker-pane")
        expect(markers.get_by_title(IMG_TEXT, exact=True)).to_have_count(1)
        expect(markers.get_by_title(SCRIPT_TEXT, exact=True)).to_have_count(1)
        page.get_by_role("button", name="Fly").click()
        expect(page.get_by_test_id("mission-status")).to_contain_text("completed", timeout=120_000)
        assert page.locator("#panel img, .leaflet-marker-pane img, #panel script").count() == 0
        assert page.evaluate("window.injected") is None
        page.screenshot(path=str(ARTIFACTS / "web_hostile_text.png"))

        mission_id = page.evaluate("fetch('/missions?limit=1').then(r => r.json()).then(m => m[0].id)")
        page.goto(f"{url}/missions/{mission_id}/report/index.html")
        buoy_table = page.locator("table").nth(1)
        expect(buoy_table).to_contain_text(IMG_TEXT)
        expect(buoy_table).to_contain_text(SCRIPT_TEXT)
        assert page.locator("img[src=x], body script").count() == 0
        assert page.evaluate("window.injected") is None
        browser.close()
    assert problems == []


@pytest.fixture
def service_with_a_long_mission(tmp_path):
    """`python -m gcs serve` (no vehicle) over a database holding a completed 2-hour mission (72 000 samples);
    yields (url, mission id)."""
    storage = open_storage(tmp_path / "gcs.sqlite")
    mission_id = store_long_mission(storage)
    storage.close()
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url:
        yield url, mission_id


FLOWN_TRACK = ".leaflet-overlay-pane path[stroke='#c2185b']"  # map.js: the flown track's colour
TRACK_VERTICES = f"""() => {{
    const path = document.querySelector("{FLOWN_TRACK}");
    return path ? (path.getAttribute("d").match(/L/g) || []).length : 0;
}}"""


def test_a_two_hour_mission_opens_with_its_track_drawn(service_with_a_long_mission):
    url, mission_id = service_with_a_long_mission
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        asked: list[str] = []
        page.on("request", lambda request: asked.append(urlsplit(request.url).path))
        page.goto(url)
        # the page opens on the latest mission: its buoys, and the flown track from the display track endpoint
        expect(page.locator(".buoy-icon")).to_have_count(13, timeout=30_000)
        expect(page.locator(FLOWN_TRACK)).to_have_count(1, timeout=30_000)
        page.wait_for_function(f"() => ({TRACK_VERTICES})() > 100", timeout=60_000)
        assert f"/missions/{mission_id}/track" in asked
        assert f"/missions/{mission_id}/telemetry" not in asked  # never the 72 000 samples
        page.screenshot(path=str(ARTIFACTS / "web_two_hour_track.png"))
        browser.close()
    assert errors == []
