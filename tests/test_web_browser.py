"""The map page in a real browser (headless Chromium via Playwright) against the real service and vehicle.

Place four buoys by clicking the map, plan (the route and its length appear), fly against the SITL vehicle
(`python -m sitl_quad --speed 10`) until the mission completes, and check the live track and the history; the
battery gauge shows the vehicle's charge live. Then hostile text: a vehicle (the ArduCopter double, real MAVLink
over UDP) whose STATUSTEXTs and a buoy file whose ids carry markup and script, shown literally on the page and
in the report, where nothing of it runs; so are the inspection's texts (a buoy's id, the reason it was not
inspected, its findings, its light read, the camera's name), in the panel, the frames' gallery and the report.
A multi-sortie mission (the energy model's pack at 1000 mAh splits the reference buoys in three) shows each sortie
in its own colour with a legend, and its predicted against used energy per sortie. A plan's answer that arrives
after the buoys changed is dropped, and Plan and Fly wait for the request in flight. Screenshots go to
test-artifacts/.
"""

import io
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
from PIL import Image
from playwright.sync_api import Page, expect, sync_playwright
from playwright.sync_api import TimeoutError as PlaywrightTimeoutError
from service_process import serving
from sitl_process import SitlProcess
from stored_missions import SORTIES_FLOWN
from web_page import ARGS, ARTIFACTS, CHROMIUM, REPO, TOKEN, fly, open_page, wait_until_connected

from bench.long_mission import store_long_mission
from bench.processes import free_port, stop_process
from gcs.domain.inspection import Finding, StoredFrame
from gcs.domain.records import MissionProgress
from gcs.domain.schemas import PreflightCheck
from gcs.missions.fleet_missions import shares_progress
from gcs.storage import open_storage
from stack.demo import reference_request
from stack.options import UpOptions
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.browser, pytest.mark.integration, pytest.mark.slow]

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


BATTERY_PERCENT = 60  # the simulated vehicle's charge at start


@pytest.fixture
def stack(tmp_path):
    """The vehicle (10x real time, its pack at BATTERY_PERCENT) and `python -m gcs serve` on free ports; yields the
    page's URL. Paced, not lockstep: with no offboard controller a lockstep vehicle runs freely, a whole core spent
    on simulating the ground while the service starts and the page loads (the flight takes a few seconds longer)."""
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    logs = open(tmp_path / "stack.log", "w")  # noqa: SIM115 - closed below
    vehicle = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sitl_quad",
            "--port",
            str(udp),
            "--speed",
            "10",
            "--battery-percent",
            str(BATTERY_PERCENT),
        ],
        stdout=logs,
        stderr=subprocess.STDOUT,
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
    stop_process(gcs)
    stop_process(vehicle)
    logs.close()


def test_place_plan_and_fly_in_the_browser(stack):
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        page.goto(stack)
        expect(page.get_by_test_id("link-status")).to_contain_text("disarmed", timeout=10_000)
        # the mission states come from the service's OpenAPI enum; a name it does not define throws
        statuses = page.evaluate(STATUS_PROBE)
        assert statuses == {"flying": "flying", "unknown": "unknown MissionStatus.no_such_status"}
        check_battery_gauge(page, stack)

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

        fly(page)  # the control bar's Fly, confirmed
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

        # the project's example file: 13 buoys and its depot (the feature whose role is depot), planned as such
        page.get_by_role("button", name="Clear").click()
        page.locator("#import").set_input_files(str(REPO / "examples" / "reference_buoys.geojson"))
        expect(page.locator("#message")).to_contain_text("imported 13 buoys and the depot")
        expect(page.locator(".buoy-icon")).to_have_count(13)
        with page.expect_response(lambda r: r.url.endswith("/plans")) as answer:
            page.get_by_role("button", name="Plan").click()
        plan = answer.value.json()
        assert answer.value.status == 200 and len(plan["buoys"]) == 13
        assert plan["depot"] == {"lat": 38.921, "lon": 121.663}
        expect(summary).to_contain_text("% shorter")
        browser.close()
    assert errors == []


def check_battery_gauge(page: Page, url: str) -> None:
    """The gauge shows the vehicle's first battery as /vehicle reports it: the pack put in at BATTERY_PERCENT,
    standing disarmed (it may have drawn a little for the avionics since)."""
    charge = page.get_by_test_id("battery-charge")
    expect(charge).to_have_text(re.compile(r"^\d+ %$"), timeout=15_000)
    with urllib.request.urlopen(f"{url}/vehicle", timeout=5) as answer:
        vehicle = json.load(answer)
    shown = page.locator("#battery-meter").evaluate("meter => meter.value")
    assert BATTERY_PERCENT - 5 <= shown <= BATTERY_PERCENT
    assert abs(shown - vehicle["battery_remaining_pct"]) <= 2
    assert vehicle["battery_charge_state"] == 1
    expect(page.get_by_test_id("battery-state")).to_have_text("ok")
    expect(page.locator("#battery-state.charge-ok")).to_have_count(1)
    expect(page.locator("#battery-figures")).to_contain_text(re.compile(r"\d+\.\d\d V, -?\d+\.\d A, \d+\.\d\d Wh used"))


# Each would set window.injected (or log "injected") if the page ever let it become markup and run it.
IMG_TEXT = "<img src=x onerror=window.injected=1>"
SCRIPT_TEXT = "<script>window.injected=2;console.log('injected')</script>"


def hostile_inspection(db: Path, mission_id: int) -> None:
    """The first buoy's record made of markup: judged a defect whose finding, light read and reason carry IMG_TEXT
    and SCRIPT_TEXT, with a frame; and the camera named IMG_TEXT (as a camera's CAMERA_INFORMATION could)."""
    storage = open_storage(db)
    record = storage.inspections(mission_id)[0]
    jpeg = io.BytesIO()
    Image.new("RGB", (64, 36), (40, 70, 90)).save(jpeg, "JPEG")
    lat, lon = record.result.buoy.lat, record.result.buoy.lon
    frame = StoredFrame(buoy=record.buoy, image_index=0, t_s=1.0, lat=lat, lon=lon, height_m=5.0, q=(1, 0, 0, 0),
                        file_url=IMG_TEXT)  # fmt: skip
    frame_id = storage.add_frame(mission_id, frame, jpeg.getvalue(), 1_000_000)
    finding = Finding(code="wrong_character", charted=IMG_TEXT, seen=SCRIPT_TEXT)
    result = record.result.model_copy(
        update={"verdict": "defect", "findings": [finding], "light_seen": IMG_TEXT, "reason": SCRIPT_TEXT}
    )
    storage.set_inspection(mission_id, record.model_copy(update={"result": result, "frame_ids": [frame_id],
                                                                 "best_frame": frame_id}))  # fmt: skip
    progress = storage.get_mission(mission_id).progress
    storage.set_progress(mission_id, progress.model_copy(update={"camera": IMG_TEXT}))
    storage.close()


def test_text_from_the_vehicle_and_from_files_shows_literally_and_never_runs(double_and_service, tmp_path):
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
        fly(page)  # the control bar's Fly, confirmed
        expect(page.get_by_test_id("mission-status")).to_contain_text("completed", timeout=120_000)
        assert page.locator("#panel img, .leaflet-marker-pane img, #panel script").count() == 0
        assert page.evaluate("window.injected") is None
        page.screenshot(path=str(ARTIFACTS / "web_hostile_text.png"))

        # the inspections (the double has no camera: each buoy not inspected, said at upload) list the ids as text;
        # then the first buoy's record and the camera's name made of markup show as text in the list and gallery
        inspections = page.get_by_test_id("inspection-list")
        expect(inspections.get_by_test_id("inspection-row")).to_have_count(2)
        expect(inspections).to_contain_text(IMG_TEXT)
        expect(inspections).to_contain_text(SCRIPT_TEXT)
        mission_id = page.evaluate("fetch('/missions?limit=1').then(r => r.json()).then(m => m[0].id)")
        hostile_inspection(tmp_path / "gcs.sqlite", mission_id)
        expect(inspections).to_contain_text(f"why: {SCRIPT_TEXT}", timeout=10_000)
        expect(inspections).to_contain_text(f"wrong light character: charted {IMG_TEXT}, seen {SCRIPT_TEXT}")
        expect(inspections).to_contain_text(f"read {IMG_TEXT}")
        expect(page.get_by_test_id("inspection-camera")).to_have_text(f"camera: {IMG_TEXT}")
        markers.get_by_title(IMG_TEXT, exact=True).click()  # its frames
        expect(page.get_by_test_id("gallery-title")).to_have_text(re.compile(rf"^✗ \d {re.escape(IMG_TEXT)}: defect$"))
        expect(page.get_by_test_id("gallery-details")).to_contain_text(f"why: {SCRIPT_TEXT}")
        page.wait_for_function("() => document.querySelector('#gallery-large').naturalWidth > 0", timeout=10_000)
        assert page.locator("#panel img, .leaflet-marker-pane img, script:not([src]), img[src=x]").count() == 0
        assert page.evaluate("window.injected") is None
        page.screenshot(path=str(ARTIFACTS / "web_hostile_inspection.png"))

        # drawn on this first request (eight figures: a loaded machine takes longer than Playwright's 30 s default)
        page.goto(f"{url}/missions/{mission_id}/report/index.html", timeout=120_000)
        buoy_table = page.locator("table").nth(1)
        expect(buoy_table).to_contain_text(IMG_TEXT)
        expect(buoy_table).to_contain_text(SCRIPT_TEXT)
        inspection_table = page.get_by_test_id("inspections")
        for text in (IMG_TEXT, SCRIPT_TEXT, f"wrong light character: charted {IMG_TEXT}, seen {SCRIPT_TEXT}"):
            expect(inspection_table).to_contain_text(text)
        expect(page.locator("img[src='defect-0.jpg']")).to_have_count(1)  # its best frame, by the buoy's index
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


def post_json(url: str, body: dict) -> dict:
    request = urllib.request.Request(url, json.dumps(body).encode(), {"Content-Type": "application/json"})
    with urllib.request.urlopen(request, timeout=60) as answer:
        return json.load(answer)


def aborted_in_third_sortie(storage_path: Path, mission: dict) -> None:
    """Store what the recorder and the lifecycle leave of the mission after two sorties flown and a battery
    failsafe early in the third: the progress (as gcs.missions.recorder stores it) and the status."""
    first_two = [b for sortie in mission["sorties"][:2] for b in sortie["order"]]
    storage = open_storage(storage_path)
    storage.set_progress(
        mission["id"],
        MissionProgress(
            current_seq=None,
            total=None,
            mission_state=None,
            reached_seqs=[],
            visited=len(first_two),
            buoys=len(mission["order"]),
            reached_at={b: 100.0 + k for k, b in enumerate(first_two)},
            vehicle_events=[],
            sortie=2,
            sorties=3,
            visited_buoys=sorted(first_two),
            sorties_flown=SORTIES_FLOWN,
        ),
    )
    storage.set_status(mission["id"], "aborted", "battery critical in sortie 3 of 3")
    storage.close()


@pytest.fixture
def service_with_a_multi_sortie_mission(tmp_path):
    """`python -m gcs serve` (no vehicle: the energy model's pack stands in) with the reference buoys planned in
    sorties of a 1000 mAh pack, two of them flown; yields (url, the mission as GET /missions/{id} answers)."""
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url:
        request = {**reference_request(UpOptions()), "battery": {"capacity_mah": 1000}, "start": False}
        created = post_json(f"{url}/missions", request)
        aborted_in_third_sortie(tmp_path / "gcs.sqlite", created)
        with urllib.request.urlopen(f"{url}/missions/{created['id']}", timeout=10) as answer:
            yield url, json.load(answer)


# Each buoy marker's sortie colour: the fill of one not visited, the ring of one visited (style.css .in-sortie).
MARKER_COLOURS = """() => [...document.querySelectorAll(".buoy-icon")].map((icon) => {
    const style = getComputedStyle(icon);
    const visited = icon.classList.contains("visited");
    return { label: Number(icon.textContent), visited, colour: visited ? style.borderTopColor : style.backgroundColor };
})"""


def one_decimal(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f}"


def test_a_multi_sortie_mission_shows_its_sorties_and_their_energy(service_with_a_multi_sortie_mission):
    url, mission = service_with_a_multi_sortie_mission
    sorties = mission["sorties"]
    assert len(sorties) == 3 and mission["energy"]["pack_source"] == "energy model"
    assert [s["used_energy_wh"] for s in sorties] == [10.4, 12.9, None]
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        # the sortie colours are CSSOM and SVG attributes, which the Content-Security-Policy lets through
        page.on("console", lambda m: errors.append(m.text) if "Content Security" in m.text else None)
        page.goto(url)
        expect(page.locator(".buoy-icon")).to_have_count(13, timeout=30_000)

        # each sortie's route dashed in its own colour, and the legend naming each one's buoys and energy
        routes = page.locator(".leaflet-overlay-pane path[stroke-dasharray]")
        expect(routes).to_have_count(3)
        route_colours = [routes.nth(k).get_attribute("stroke") for k in range(3)]
        assert len(set(route_colours)) == 3
        legend = page.get_by_test_id("sortie-legend").locator("li")
        expect(legend).to_have_text(
            [
                f"sortie {k + 1}: {len(s['order'])} buoys, predicted {s['predicted_energy_wh']:.1f} Wh"
                for k, s in enumerate(sorties)
            ]
        )
        swatches = [legend.nth(k).locator("line").get_attribute("stroke") for k in range(3)]
        assert swatches == route_colours

        # the markers in their sortie's colour: the two flown sorties' buoys visited (ringed), the third's filled
        flown = sum(len(s["order"]) for s in sorties[:2])
        page.wait_for_function(f"() => document.querySelectorAll('.buoy-icon.visited').length === {flown}")
        markers = page.evaluate(MARKER_COLOURS)
        sortie_of = {b: s["index"] for s in sorties for b in s["order"]}
        colour_of_sortie: dict[int, set[str]] = {}
        for marker in markers:
            buoy = mission["order"][marker["label"] - 1]
            assert marker["visited"] == (sortie_of[buoy] < 2)
            colour_of_sortie.setdefault(sortie_of[buoy], set()).add(marker["colour"])
        assert all(len(colours) == 1 for colours in colour_of_sortie.values())
        assert len({colour for colours in colour_of_sortie.values() for colour in colours}) == 3

        # predicted against used, sortie by sortie; error = (used - predicted) / used
        expect(page.get_by_test_id("sortie-progress")).to_have_text("sortie 3 of 3")
        rows = page.get_by_test_id("sortie-table").locator("tbody tr")
        expect(rows).to_have_count(3)
        warnings = ["none", "low", "–"]
        for k, s in enumerate(sorties):
            used = s["used_energy_wh"]
            error = None if used is None else 100 * (used - s["predicted_energy_wh"]) / used
            landing = "–" if s["landing_charge_pct"] is None else f"{s['landing_charge_pct']:.0f}"
            expected = [
                str(k + 1),
                str(len(s["order"])),
                one_decimal(s["predicted_energy_wh"]),
                one_decimal(used),
                one_decimal(error),
                f"{s['margin_pct']:.0f}",
                f"{s['predicted_landing_charge_pct']:.0f} / {landing}",
                warnings[k],
            ]
            expect(rows.nth(k).locator("td")).to_have_text(expected)
        # no vehicle: the gauge says so
        expect(page.get_by_test_id("battery-charge")).to_have_text("no battery report")

        # the form's battery options: a pack too small for any buoy is the service's 422, shown as its text
        page.locator("#plan-sorties").check()
        page.locator("#capacity").fill("10")
        page.get_by_role("button", name="Plan").click()
        message = page.locator("#message")
        expect(message).to_contain_text("422: buoys.0: buoy B1 cannot be reached and flown back", timeout=30_000)
        # a real pack and a forecast wind: sorties planned again, each in the legend
        page.locator("#capacity").fill("1000")
        page.locator("#wind-speed").fill("5")
        page.locator("#wind-from").fill("270")
        page.get_by_role("button", name="Plan").click()
        expect(message).to_have_text("route planned", timeout=30_000)
        summary = page.get_by_test_id("plan-summary")
        expect(summary).to_contain_text("1000 mAh pack (energy model), wind 5.0 m/s from 270°")
        planned = int(re.search(r"(\d+) sorties,", summary.inner_text()).group(1))
        assert planned >= 2  # about 30 Wh of buoys for 12.5 Wh a sortie
        expect(page.get_by_test_id("sortie-legend").locator("li")).to_have_count(planned)
        expect(page.locator(".leaflet-overlay-pane path[stroke-dasharray]")).to_have_count(planned)
        # the stored mission, still polled, leaves the new plan on the map and in the summary
        page.wait_for_timeout(2_000)
        expect(summary).to_contain_text("wind 5.0 m/s from 270°")
        expect(page.locator(".buoy-icon.visited")).to_have_count(0)  # a new plan has not flown
        page.screenshot(path=str(ARTIFACTS / "web_sorties.png"), full_page=True)
        page.locator("#panel").screenshot(path=str(ARTIFACTS / "web_sortie_table.png"))
        browser.close()
    assert errors == []


@pytest.fixture
def fleet_service(tmp_path):
    """Three vehicles (`python -m sitl_quad --sysid N`, homes 160 m apart) and `python -m gcs serve` linked to
    each; yields the service's URL once it has heard all three."""
    frame = LocalFrame(*DEFAULT_HOME)
    homes = {1: DEFAULT_HOME, 2: frame.from_ned(0.0, 160.0, 0.0), 3: frame.from_ned(160.0, 0.0, 0.0)}
    vehicles = [
        SitlProcess(speed=5.0, extra_args=("--sysid", str(n), "--home", ",".join(f"{v:.8f}" for v in home))).start()
        for n, home in homes.items()
    ]
    http = free_port(socket.SOCK_STREAM)
    argv = [sys.executable, "-m", "gcs", "serve", "--port", str(http), "--db", str(tmp_path / "gcs.sqlite")]
    for n, vehicle in zip(homes, vehicles, strict=True):
        argv += ["--vehicle", f"{n}=udpout:127.0.0.1:{vehicle.port}"]
    logs = open(tmp_path / "service.log", "w")  # noqa: SIM115 - closed below
    gcs = subprocess.Popen(argv, stdout=logs, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{http}"
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                with urllib.request.urlopen(f"{url}/vehicles", timeout=2) as answer:
                    if all(v["connected"] and v["home"] for v in json.load(answer)):
                        break
            except OSError:
                pass
            assert gcs.poll() is None and time.monotonic() < deadline, (tmp_path / "service.log").read_text()
            time.sleep(0.3)
        yield url, frame
    finally:
        stop_process(gcs)
        logs.close()
        for vehicle in vehicles:
            vehicle.cleanup()


def fleet_state(url: str, mission_id: int, log: Path) -> str:
    """What a failed wait on the fleet leaves to read: the fleet mission's and its shares' statuses, each vehicle's
    state as the service has it, and the end of the service's log."""
    with urllib.request.urlopen(f"{url}/missions/{mission_id}", timeout=10) as answer:
        fleet = json.load(answer)
    with urllib.request.urlopen(f"{url}/vehicles", timeout=10) as answer:
        vehicles = json.load(answer)
    keys = ("sysid", "connected", "armed", "mode", "alt_m", "north", "east", "active_mission", "heartbeat_age_s")
    shares = [{k: s[k] for k in ("sysid", "mission_id", "status", "visited_buoys")} for s in fleet["fleet"]["shares"]]
    return "\n".join(
        [
            f"fleet mission {mission_id}: {fleet['status']} ({fleet['reason']}); shares {shares}",
            *(str({k: v.get(k) for k in keys}) for v in vehicles),
            *log.read_text().splitlines()[-60:],
        ]
    )


def test_a_fleet_mission_shows_every_vehicle_its_route_and_the_fleets_summary(fleet_service, tmp_path):
    url, frame = fleet_service
    places = [(n, e) for n in (30.0, 90.0, 150.0) for e in (40.0, 100.0, 170.0)]
    buoys = [
        {"id": f"B{i + 1}", "lat": float(lat), "lon": float(lon)}
        for i, (lat, lon, _) in enumerate(frame.from_ned(n, e, 0.0) for n, e in places)
    ]
    # planned, and started once the page shows it: started at once, the shares (a few seconds of wall clock each at
    # 5x) could all be flown before a loaded machine's browser had drawn the vehicles, which then never moved again
    mission = post_json(f"{url}/missions", {"vehicles": "fleet", "buoys": buoys, "start": False})
    shares = mission["fleet"]["shares"]  # a fleet mission flies its shares (FleetShareOut), no tour of its own
    assert mission["sorties"] == [] and mission["route"] == []
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        page.on("console", lambda m: errors.append(m.text) if "Content Security" in m.text else None)
        polled: list[str] = []  # the page's requests for vehicle state: the live stream carries it
        vehicle_state = re.compile(r"^/vehicles(/|$)")  # GET /vehicles[/N], not the page's vehicles.js module
        page.on("request", lambda r: polled.append(r.url) if vehicle_state.match(urlsplit(r.url).path) else None)
        page.goto(url)
        # every vehicle on the map, titled by its system id, and no other vehicle marker
        for sysid in (1, 2, 3):
            expect(page.locator(f".leaflet-marker-icon[title='vehicle {sysid}']")).to_have_count(1, timeout=30_000)
        expect(page.locator(".leaflet-marker-icon.vehicle-icon")).to_have_count(3)
        # and they move as the stream says: a vehicle flying its share leaves where it was first drawn, at home
        # before the start (measured from a buoy's icon, so that the map panning meanwhile moves nothing; the view
        # is fitted to the routes once they are drawn)
        routes = page.locator(".leaflet-overlay-pane path[stroke-dasharray]")
        expect(routes).to_have_count(len(shares), timeout=30_000)
        flier = f".leaflet-marker-icon[title='vehicle {shares[0]['sysid']}']"  # a vehicle given buoys
        offset = f"""() => {{
            const vehicle = document.querySelector("{flier}").getBoundingClientRect();
            const buoy = document.querySelector(".buoy-icon").getBoundingClientRect();
            return [vehicle.x - buoy.x, vehicle.y - buoy.y];
        }}"""
        first_drawn = page.evaluate(offset)
        post_json(f"{url}/missions/{mission['id']}/start", {})
        expect(page.locator("#mission-status")).to_contain_text("flying", timeout=120_000)
        try:
            page.wait_for_function(
                f"(first) => {{ const [x, y] = ({offset})(); return Math.hypot(x - first[0], y - first[1]) > 3; }}",
                arg=first_drawn,
                timeout=120_000,
            )
        except PlaywrightTimeoutError:  # say whether the vehicles flew and the page missed it, or they never flew
            raise AssertionError(fleet_state(url, mission["id"], tmp_path / "service.log")) from None
        # each vehicle's route in its own colour, and the legend naming each one's share
        expect(routes).to_have_count(len(shares))
        assert len({routes.nth(k).get_attribute("stroke") for k in range(len(shares))}) == len(shares)
        legend = page.get_by_test_id("sortie-legend").locator("li")
        expect(legend).to_have_text(
            [f"vehicle {s['sysid']}: {len(s['buoys'])} buoys, about {round(s['predicted_time_s'])} s" for s in shares]
        )
        expect(page.get_by_test_id("sortie-progress")).to_have_text(f"{len(shares)} vehicles")
        # the fleet's table, a row per vehicle, and once every part has landed the closest approach
        rows = page.locator("#sortie-table tbody tr")
        expect(rows).to_have_count(len(shares))
        expect(page.locator("#mission-status")).to_contain_text("completed", timeout=240_000)
        expect(page.locator("#figures")).to_contain_text("closest approach")
        for k, share in enumerate(shares):
            expect(rows.nth(k).locator("td").nth(0)).to_have_text(str(share["sysid"]))
            expect(rows.nth(k).locator("td").nth(2)).to_have_text(str(len(share["buoys"])))  # all inspected
        ARTIFACTS.mkdir(exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / "fleet-mission.png"))

        # each vehicle named with its link and battery, and the choice of what Plan and Fly use: the fleet
        # (previewed by POST /plans, no depot: each flies from its home) or one of them
        vehicle_rows = page.get_by_test_id("vehicle-row")
        expect(vehicle_rows).to_have_count(3)
        for sysid in (1, 2, 3):
            expect(vehicle_rows.nth(sysid - 1)).to_contain_text(
                re.compile(rf"^vehicle {sysid}\b.*: .* · battery \d+ %$")
            )
        page.get_by_role("button", name="Clear").click()
        page.locator("#import").set_input_files(
            csv_file("lat,lon,id\n" + "".join(f"{b['lat']},{b['lon']},{b['id']}\n" for b in buoys))
        )
        expect(page.locator(".buoy-icon")).to_have_count(len(buoys))
        choice = page.get_by_test_id("vehicle-choice")
        choice.select_option("fleet")
        with page.expect_response(lambda r: r.url.endswith("/plans")) as answer:
            page.get_by_role("button", name="Plan").click()
        sent = answer.value.request.post_data_json
        assert sent["vehicles"] == "fleet" and "depot" not in sent and "vehicle" not in sent
        preview = answer.value.json()["fleet"]
        expect(page.get_by_test_id("plan-summary")).to_contain_text(f"{len(preview['shares'])} vehicles (")
        expect(legend).to_have_count(len(preview["shares"]))
        expect(routes).to_have_count(len(preview["shares"]))  # each share's route, from its vehicle's home
        page.screenshot(path=str(ARTIFACTS / "fleet-preview.png"))
        choice.select_option("2")
        expect(page.get_by_test_id("plan-summary")).to_be_empty()  # the fleet's plan is not this choice's
        with page.expect_response(lambda r: r.url.endswith("/plans")) as answer:
            page.get_by_role("button", name="Plan").click()
        sent = answer.value.request.post_data_json
        assert sent["vehicle"] == 2 and "vehicles" not in sent and answer.value.ok
        browser.close()
    assert errors == []
    assert polled == []  # one live path: the positions came from /ws alone


def test_plan_and_fly_wait_for_the_answer_and_a_superseded_plan_answer_changes_nothing(tmp_path):
    """Plan and Fly are disabled while a plan is in flight, with "planning… N s" beside them; a buoy placed
    meanwhile supersedes the request, so its late answer (held back here by intercepting POST /plans) neither
    draws a route nor fills the summary; the next plan, of the buoys now placed, does."""
    errors: list[str] = []
    held = []
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url, sync_playwright() as p:
        browser, page = open_page(p, errors)
        page.route("**/plans", lambda route: held.append(route) if not held else route.continue_())
        page.goto(url)
        plan, fly_button = page.get_by_role("button", name="Plan"), page.get_by_test_id("fly")
        # the controls are wired (app.js wireControls disables the battery fields first, then takes map clicks)
        expect(page.locator("#reserve")).to_be_disabled(timeout=30_000)
        box = page.locator("#map").bounding_box()
        centre_x, centre_y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        for dx, dy in ((-120, -60), (90, -90), (140, 60), (-60, 100)):
            page.mouse.click(centre_x + dx, centre_y + dy)
        expect(page.locator("#buoy-count")).to_have_text("4 buoys")

        plan.click()
        busy = page.get_by_test_id("busy")
        expect(busy).to_contain_text("planning…")
        expect(plan).to_be_disabled()
        expect(fly_button).to_be_disabled()
        page.wait_for_function("() => document.querySelector('#busy').textContent.includes(' 1 s')")  # counting
        page.mouse.click(centre_x + 40, centre_y - 140)  # a fifth buoy while the plan of four is in flight
        expect(page.locator("#buoy-count")).to_have_text("5 buoys")
        assert len(held) == 1
        held[0].continue_()  # the late answer, for the four buoys
        expect(plan).to_be_enabled(timeout=30_000)
        expect(fly_button).to_be_enabled()
        expect(busy).to_be_hidden()
        summary = page.get_by_test_id("plan-summary")
        expect(summary).to_have_text("")
        expect(page.locator(".leaflet-overlay-pane path[stroke-dasharray]")).to_have_count(0)

        plan.click()  # answered at once this time
        expect(page.locator("#message")).to_have_text("route planned", timeout=30_000)
        expect(summary).to_contain_text("km")
        expect(page.locator(".leaflet-overlay-pane path[stroke-dasharray]")).to_have_count(1)
        # the route the page shows is the five buoys' (each labelled with its visiting rank, 1 to 5)
        labels = sorted(int(text) for text in page.locator(".buoy-icon").all_inner_texts())
        assert labels == [1, 2, 3, 4, 5]
        browser.close()
    assert errors == []


def test_pack_swapped_on_a_fleet_mission_is_for_the_vehicle_whose_part_waits(tmp_path):
    """A fleet mission flying in sorties whose part on vehicle 2 waits for its swap (as the lifecycle and the
    coordinator store it): "Pack swapped" on the fleet mission tells vehicle 2 (POST /vehicles/2/battery-swap), not
    the service's first vehicle; the answer is shown as text (here: no vehicle to tell)."""
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log", sysids=(1, 2)) as url:
        frame = LocalFrame(*DEFAULT_HOME)
        buoys = [dict(zip(("lat", "lon"), map(float, frame.from_ned(n, e, 0.0)[:2]), strict=True))
                 for n, e in ((60, -60), (60, 60), (120, -60), (120, 60))]  # fmt: skip
        created = post_json(f"{url}/missions", {"vehicles": [2, 1], "buoys": buoys, "battery": "vehicle",
                                                "start": False, "planner": {"time_limit_s": 0.5}})  # fmt: skip
        storage = open_storage(tmp_path / "gcs.sqlite")
        parts = storage.fleet_parts(created["id"])
        waiting = next(part for part in parts if part.vehicle_sysid == 2)
        storage.set_status(waiting.id, "flying", "sortie 1 of 2")
        storage.set_status(waiting.id, "waiting_for_battery", "sortie 2 needs 60 %; the vehicle reports 20 %")
        storage.set_status(created["id"], "flying")
        fleet = storage.get_mission(created["id"])
        storage.set_progress(created["id"], shares_progress(fleet, storage.fleet_parts(created["id"])))
        storage.close()
        errors: list[str] = []
        with sync_playwright() as p:
            browser, page = open_page(p, errors)
            page.goto(url)
            expect(page.get_by_test_id("mission-status")).to_contain_text(f"#{created['id']}: flying", timeout=30_000)
            page.get_by_test_id("battery-swap").click()
            with page.expect_request(lambda request: "battery-swap" in request.url) as sent:
                page.get_by_test_id("confirm-ok").click()
            assert urlsplit(sent.value.url).path == "/vehicles/2/battery-swap"
            expect(page.locator("#message")).to_contain_text("409: ")
            browser.close()
    assert errors == []


def test_a_mission_waiting_for_a_battery_swap_asks_for_it_and_shows_its_preflight_checks(tmp_path):
    """A mission between sorties, waiting for the operator's swap (as gcs.missions.lifecycle stores it): the page opens
    on it, its status asks for attention and the pre-flight checks read as figures; "Pack swapped" asks for
    confirmation and shows the service's answer as text (here: no vehicle to tell)."""
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url:
        request = {**reference_request(UpOptions()), "battery": {"capacity_mah": 1000}, "start": False}
        created = post_json(f"{url}/missions", request)
        storage = open_storage(tmp_path / "gcs.sqlite")
        check = PreflightCheck(sortie=0, needed_pct=71.4, energy_wh=10.2, reserve_pct=15.0, remaining_pct=100.0,
                               override=False)  # fmt: skip
        storage.set_progress(created["id"], MissionProgress(sortie=1, sorties=3, visited=4, preflight=[check]))
        waiting = "sortie 2 needs 74 % (10.6 Wh predicted, landing with the 15 % reserve); the vehicle reports 16 %"
        storage.set_status(created["id"], "flying", "sortie 1 of 3")
        storage.set_status(created["id"], "waiting_for_battery", waiting)
        storage.close()
        errors: list[str] = []
        with sync_playwright() as p:
            browser, page = open_page(p, errors)
            page.goto(url)
            status = page.get_by_test_id("mission-status")
            expect(status).to_have_text(f"#{created['id']}: waiting_for_battery – {waiting}", timeout=30_000)
            expect(status).to_have_class("attention")
            # the control bar says it plainly; the mission may be aborted, nothing else applies on the ground
            expect(page.get_by_test_id("console-status")).to_have_text(
                f"Mission {created['id']}: landed, waiting for a battery swap"
            )
            expect(page.get_by_test_id("abort")).to_be_enabled()
            expect(page.get_by_test_id("hold")).to_be_disabled()
            expect(page.get_by_test_id("preflight")).to_have_text(
                "pre-flight, sortie 1: needs 71 % (10.2 Wh), the vehicle had 100 %"
            )
            page.get_by_test_id("battery-swap").click()  # asked in the page's dialog (confirm.js)
            expect(page.get_by_test_id("confirm-text")).to_contain_text("charged pack")
            page.get_by_test_id("confirm-ok").click()
            expect(page.locator("#message")).to_contain_text("409: no vehicle is connected")
            page.screenshot(path=str(ARTIFACTS / "web_waiting_for_battery.png"))
            browser.close()
    assert errors == []
