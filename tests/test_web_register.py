"""The map page's AIS AtoNs and register view in a real browser (headless Chromium via Playwright) against the
real service: `python -m gcs serve --ais udp://...` with NOAA's US4MD81M imported into its register, a mission of
two of its buoys with their inspection records (one ok, one off station: an open defect), and AtoN reports sent as
real NMEA message 21 sentences over UDP, one of them once only so that it goes stale (the service's stale setting
lowered to seconds), one named with markup. The page draws each AtoN by its flags and names it as text; the
register overlay draws the chart's buoys and a click on one shows its record and history as text.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import socket
import threading
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from inspected_missions import inspection_result
from playwright.sync_api import Page, expect, sync_playwright
from service_process import serving
from test_web_browser import ARTIFACTS, open_page

from bench.processes import free_port
from gcs.domain.inspection import InspectionRecord
from gcs.domain.register import RegisterBuoy
from gcs.storage import open_storage
from uavcore.ais import AtonReport, encode_aton_report

pytestmark = [pytest.mark.browser, pytest.mark.integration, pytest.mark.slow]

CELL = Path(__file__).parent / "data" / "enc" / "US4MD81M" / "US4MD81M.000"
STALE_S = 3.0  # the service's ais_stale_s here: a report sent once is stale seconds later
RESEND_S = 0.5  # the fresh reports, sent again and again: never older than this
# AIS text is 6-bit upper case: markup arrives as <B>X</B>, which a browser would take for a tag all the same
HOSTILE_NAME = "<B>X</B> MARK"
MMSI = 993_672_100


@dataclass(frozen=True)
class Aton:
    mmsi: int
    name: str
    lat: float
    lon: float
    off_position: bool = False
    virtual: bool = False

    def datagram(self) -> bytes:
        report = AtonReport(mmsi=self.mmsi, name=self.name, aid_type=24, lat=self.lat, lon=self.lon,
                            position_accuracy=True, off_position=self.off_position, virtual=self.virtual,
                            second=30)  # fmt: skip
        return "".join(f"{line}\r\n" for line in encode_aton_report(report)).encode()


def request(url: str, method: str = "GET", body: bytes | None = None, content_type: str = "application/json"):
    headers = {"Content-Type": content_type} if body is not None else {}
    with urllib.request.urlopen(urllib.request.Request(url, body, headers, method=method), timeout=60) as answer:
        return json.load(answer)


def metres(a: dict, b: dict) -> float:
    north = (a["lat"] - b["lat"]) * 111_320.0
    east = (a["lon"] - b["lon"]) * 111_320.0 * math.cos(math.radians(a["lat"]))
    return math.hypot(north, east)


def isolated(buoys: list[dict]) -> tuple[dict, dict]:
    """The register buoy farthest from its nearest neighbour, and that neighbour: on the map, markers no other
    covers at any zoom that shows both."""

    def nearest(buoy: dict) -> dict:
        return min((b for b in buoys if b is not buoy), key=lambda b: metres(buoy, b))

    target = max(buoys, key=lambda buoy: metres(buoy, nearest(buoy)))
    return target, nearest(target)


@dataclass(frozen=True)
class Scene:
    url: str
    target: dict  # the register buoy with the open off_station defect, its AtoN matched by MMSI
    atons: dict[str, Aton]  # by role: hostile, off, virtual, stale, matched


def send_until(stop: threading.Event, port: int, atons: list[Aton]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        while not stop.is_set():
            for aton in atons:
                sender.sendto(aton.datagram(), ("127.0.0.1", port))
            stop.wait(RESEND_S)


@pytest.fixture
def register_with_ais(tmp_path) -> Iterator[Scene]:
    ais_port = free_port(socket.SOCK_DGRAM)
    options = ("--ais", f"udp://127.0.0.1:{ais_port}")
    env = {"BUOY_GCS_AIS_STALE_S": str(STALE_S)}
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log", *options, env=env) as url:
        imported = request(f"{url}/buoys/imports?filename=US4MD81M.000", "POST", CELL.read_bytes(),
                           "application/octet-stream")  # fmt: skip
        assert len(imported["created"]) == 316
        target, neighbour = isolated(request(f"{url}/buoys"))
        # a mission of the two (the neighbour first: inspected ok; the target off station), as the inspector
        # stores their records
        depot = {"lat": (target["lat"] + neighbour["lat"]) / 2, "lon": (target["lon"] + neighbour["lon"]) / 2}
        keys = ("lat", "lon", "kind", "light", "swing_radius_m")
        buoys = [{"id": b["name"][:64], "register_id": b["id"], **{k: b[k] for k in keys}} for b in (neighbour, target)]
        body = json.dumps({"buoys": buoys, "depot": depot, "start": False}).encode()
        mission = request(f"{url}/missions", "POST", body)["id"]
        storage = open_storage(tmp_path / "gcs.sqlite")
        plan = storage.get_mission(mission).plan
        for index in (0, 1):
            record = InspectionRecord(
                buoy=index, buoy_id=plan.buoy_ids[index], result=inspection_result(plan, index, 0, "")
            )
            storage.set_inspection(mission, record)
        storage.close()
        request(f"{url}/buoys/{target['id']}", "PATCH", json.dumps({"mmsi": MMSI}).encode())

        # the AtoNs beside the line from the neighbour to the target, a fifth of it apart (and clear of the
        # route), the matched one beside the target
        def beside(fraction: float, side: float = 0.12) -> tuple[float, float]:
            d_lat, d_lon = target["lat"] - neighbour["lat"], target["lon"] - neighbour["lon"]
            return (
                neighbour["lat"] + fraction * d_lat - side * d_lon,
                neighbour["lon"] + fraction * d_lon + side * d_lat,
            )

        atons = {
            "hostile": Aton(MMSI + 1, HOSTILE_NAME, *beside(0.2)),
            "off": Aton(MMSI + 2, "OFF STATION", *beside(0.4), off_position=True),
            "virtual": Aton(MMSI + 3, "VIRTUAL WRECK", *beside(0.6), virtual=True),
            "stale": Aton(MMSI + 4, "HEARD ONCE", *beside(0.8)),
            "matched": Aton(MMSI, target["name"].upper()[:34], *beside(1.0, 0.04)),
        }
        sources = []
        deadline = time.monotonic() + 30
        while not (sources and sources[0]["connected"]):
            assert time.monotonic() < deadline, sources
            sources = request(f"{url}/ais/sources")
            time.sleep(0.1)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as once:
            once.sendto(atons["stale"].datagram(), ("127.0.0.1", ais_port))
        while atons["stale"].mmsi not in {a["mmsi"] for a in request(f"{url}/ais/atons")["atons"]}:
            assert time.monotonic() < deadline, "the service never heard the AtoN report sent once"
            time.sleep(0.1)
        stop = threading.Event()
        fresh = [aton for role, aton in atons.items() if role != "stale"]
        sender = threading.Thread(target=send_until, args=(stop, ais_port, fresh), daemon=True)
        sender.start()
        try:
            yield Scene(url, target, atons)
        finally:
            stop.set()
            sender.join()


# how much of the map's area land paths cover (their boxes clipped to the map's: a rough, sufficient measure)
LAND_IN_VIEW = """() => {
  const view = document.querySelector("#map").getBoundingClientRect();
  const inside = (b) => Math.max(0, Math.min(b.right, view.right) - Math.max(b.left, view.left))
    * Math.max(0, Math.min(b.bottom, view.bottom) - Math.max(b.top, view.top));
  const land = [...document.querySelectorAll("path.chart-land")].map((p) => inside(p.getBoundingClientRect()));
  return land.some((area) => area > 0.01 * view.width * view.height);
}"""


def aton_marker(page, aton: Aton):
    return page.locator(f"[data-testid=aton][data-mmsi='{aton.mmsi}']")


def tooltip_of(page, aton: Aton):
    """The AtoN's tooltip, hovered (the one hovered before may still be fading out)."""
    aton_marker(page, aton).hover()
    return page.get_by_test_id("aton-tooltip").filter(has_text=f"MMSI {aton.mmsi},")


@contextlib.contextmanager
def mission_page(scene: Scene) -> Iterator[Page]:
    """Chromium on the scene's page, which opens on its mission: its two buoys, the view fitted to them. Once the
    test's steps are done, the page must have thrown no error, broken no Content-Security-Policy rule and run no
    injected script."""
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        page.on("console", lambda m: errors.append(m.text) if re.search("Content Security|injected", m.text) else None)
        page.goto(scene.url)
        expect(page.locator(".buoy-icon")).to_have_count(2, timeout=30_000)
        yield page
        assert page.evaluate("window.injected") is None
        browser.close()
    assert errors == []


def test_the_page_draws_the_ais_atons_and_the_register_and_shows_a_buoys_record(register_with_ais):
    scene = register_with_ais
    atons, target = scene.atons, scene.target
    with mission_page(scene) as page:
        # every AtoN with a position, each in its look; the one heard once turns stale (hollow) at a later poll
        expect(page.get_by_test_id("aton")).to_have_count(len(atons), timeout=30_000)
        expect(aton_marker(page, atons["off"])).to_have_class(re.compile(r"\boff-position\b"))
        expect(aton_marker(page, atons["virtual"])).to_have_class(re.compile(r"\bvirtual\b"))
        expect(aton_marker(page, atons["stale"])).to_have_class(re.compile(r"\bstale\b"), timeout=30_000)
        for role in ("hostile", "off", "virtual", "matched"):
            expect(aton_marker(page, atons[role])).not_to_have_class(re.compile(r"\bstale\b"))
        # its tooltip: the name as text (markup from the air never becomes markup), MMSI, age, flags in words
        tooltip = tooltip_of(page, atons["hostile"])
        expect(tooltip.locator("b")).to_have_text(HOSTILE_NAME)
        assert tooltip.locator("b *").count() == 0
        expect(tooltip).to_contain_text(re.compile(r"heard \d+ s ago"))
        tooltip = tooltip_of(page, atons["stale"])
        expect(tooltip).to_contain_text("HEARD ONCE")
        expect(tooltip).to_contain_text("stale: no report for over 3 s")
        expect(tooltip_of(page, atons["virtual"])).to_contain_text("virtual: nothing physical is at this position")
        expect(tooltip_of(page, atons["off"])).to_contain_text("off position: it reports itself off its station")
        page.screenshot(path=str(ARTIFACTS / "web_atons.png"))

        # the offline chart (no network here: the base layer is the metric grid): the imported cell's land drawn
        # in view around the harbour, its piers, its depth contours with their depths
        page.wait_for_function(LAND_IN_VIEW, timeout=30_000)
        assert page.locator("path.chart-pier").count() > 0 and page.locator("path.chart-depth").count() > 0
        page.locator(".leaflet-control-layers").hover()
        expect(page.get_by_label("Chart (offline)")).to_be_checked()
        page.mouse.move(0, 0)

        # the register overlay, turned on in the layer control: the chart's 316 buoys, by kind, overdue dimmed
        page.locator(".leaflet-control-layers").hover()
        page.get_by_label("Register buoys").check()
        marks = page.get_by_test_id("register-buoy")
        expect(marks).to_have_count(316, timeout=30_000)
        expect(page.locator(".register-buoy.kind-port")).to_have_count(141)
        expect(page.locator(".register-buoy.kind-starboard")).to_have_count(124)
        expect(page.locator(".register-mark.overdue")).to_have_count(314)  # the two just inspected are not
        defect_mark = page.locator(f"[data-testid=register-buoy][data-id='{target['id']}']")
        expect(defect_mark).to_have_class(re.compile(r"\bhas-defects\b"))
        expect(defect_mark.locator(".defect-count")).to_have_text("1")
        page.mouse.move(0, 0)  # the layer control folds away
        page.screenshot(path=str(ARTIFACTS / "web_register.png"))

        # a click: the buoy's record and its history, newest first, as text
        defect_mark.click()
        detail = page.get_by_test_id("register-detail")
        expect(detail.locator("h3")).to_have_text(target["name"], timeout=10_000)
        kind = target["kind"].replace("_", " ")
        expect(detail).to_contain_text(f"{kind}, light {target['light']}" if target["light"] else f"{kind}, unlit")
        expect(detail).to_contain_text(
            re.compile(r"last inspection: \d{4}-\d\d-\d\d \d\d:\d\d UTC, mission \d+: defect")
        )
        expect(detail.get_by_test_id("register-defects")).to_have_text("off_station (open)")
        expect(detail.get_by_test_id("register-ais")).to_contain_text(
            re.compile(rf"AIS: .+ \(MMSI {MMSI}, matched by MMSI\), heard \d+ s ago")
        )
        history = detail.get_by_test_id("register-history").locator("li")
        expect(history).to_have_count(3)
        expect(history.nth(0)).to_contain_text("defect opened · off_station · mission")
        expect(history.nth(1)).to_contain_text(re.compile(r"inspected · mission \d+ · defect"))
        expect(history.nth(2)).to_contain_text("registered")
        page.screenshot(path=str(ARTIFACTS / "web_register_buoy.png"))

        # the overlay's filters are GET /buoys': a kind, overdue only, open defects only, each narrowing
        page.keyboard.press("Escape")  # the popup closes
        filters = page.get_by_test_id("register-filters")
        filters.get_by_test_id("register-kind").select_option("port")
        expect(marks).to_have_count(141)
        filters.get_by_test_id("register-kind").select_option("")
        filters.get_by_test_id("register-overdue").check()
        expect(marks).to_have_count(314)
        filters.get_by_test_id("register-defects-only").check()
        expect(marks).to_have_count(0)  # the one buoy with a defect was just inspected: not overdue
        filters.get_by_test_id("register-overdue").uncheck()
        expect(marks).to_have_count(1)
        expect(marks).to_have_attribute("data-id", target["id"])
        page.locator(".leaflet-control-layers").hover()
        page.get_by_label("Register buoys").uncheck()
        expect(filters).to_have_count(0)  # the filters go with the overlay


# ----- the register's off-station alarms on the page
# a register buoy named with markup (a chart's names are free text), its AtoN the one reporting itself off position
ALARM_BUOY_ID = "ALARM-MARKUP-1"
ALARM_BUOY_NAME = '<img src=x onerror="window.injected=1"><b>Bad</b> buoy & co'


@dataclass(frozen=True)
class AlarmScene:
    scene: Scene
    alarms: list[dict]  # GET /alarms' rows once every AtoN is heard
    inspection: dict  # the target's inspection alarm
    ais: dict  # the markup-named buoy's AIS alarm


@pytest.fixture
def register_with_alarms(register_with_ais, tmp_path) -> AlarmScene:
    """register_with_ais's scene (the target's inspection opened an off_station defect: an inspection alarm) and a
    register buoy charted where the off-position AtoN reports itself, with that AtoN's MMSI: an AIS alarm."""
    scene = register_with_ais
    off = scene.atons["off"]
    storage = open_storage(tmp_path / "gcs.sqlite")
    try:
        storage.upsert_buoys([RegisterBuoy(ALARM_BUOY_ID, off.lat, off.lon, name=ALARM_BUOY_NAME, kind="special")])
    finally:
        storage.close()
    request(f"{scene.url}/buoys/{ALARM_BUOY_ID}", "PATCH", json.dumps({"mmsi": off.mmsi}).encode())
    deadline = time.monotonic() + 30
    mmsis = {aton.mmsi for aton in scene.atons.values()}
    while not mmsis <= {aton["mmsi"] for aton in request(f"{scene.url}/ais/atons")["atons"]}:
        assert time.monotonic() < deadline, "the service never heard every AtoN"
        time.sleep(0.1)
    alarms = request(f"{scene.url}/alarms")
    by = {(alarm["source"], alarm["buoy"]): alarm for alarm in alarms}
    return AlarmScene(scene, alarms, by["inspection", scene.target["id"]], by["ais", ALARM_BUOY_ID])


def wait_in_map(page, element, centred: bool) -> None:
    """Waits until the element is within the map's view, centred: its centre the map's (within 2 px)."""
    page.wait_for_function(
        """([el, map, centred]) => {
            const a = el.getBoundingClientRect(), b = map.getBoundingClientRect();
            if (centred) return Math.abs(a.x + a.width / 2 - (b.x + b.width / 2)) <= 2
                && Math.abs(a.y + a.height / 2 - (b.y + b.height / 2)) <= 2;
            return b.left <= a.left && a.right <= b.right && b.top <= a.top && a.bottom <= b.bottom;
        }""",
        arg=[element.element_handle(), page.locator("#map").element_handle(), centred],
        timeout=10_000,
    )


def test_the_page_lists_the_off_station_alarms_and_a_click_shows_the_buoy(register_with_alarms):
    scene = register_with_alarms.scene
    target, off = scene.target, scene.atons["off"]
    with mission_page(scene) as page:
        # both alarms, as text, with the count in the heading
        section = page.get_by_test_id("alarms")
        count = len(register_with_alarms.alarms)  # the target's AtoN may raise one too: reported beside it
        expect(section.get_by_test_id("alarm-count")).to_have_text(str(count), timeout=30_000)
        expect(section.get_by_test_id("alarm")).to_have_count(count)
        expect(section.get_by_test_id("alarms-empty")).to_have_count(0)
        stamp = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d UTC$")

        inspection = section.locator(f"[data-testid=alarm][data-source=inspection][data-buoy='{target['id']}']")
        mission = register_with_alarms.inspection["mission_id"]
        expect(inspection.get_by_test_id("alarm-name")).to_have_text(target["name"])
        expect(inspection.get_by_test_id("alarm-source")).to_have_text(f"inspection, mission {mission}")
        expect(inspection.get_by_test_id("alarm-distance")).to_have_text(
            f"7.3 m from its charted position, swing radius {target['swing_radius_m']:.1f} m"
        )
        expect(inspection.get_by_test_id("alarm-at")).to_have_text(stamp)
        expect(inspection.get_by_test_id("alarm-why")).to_have_text(
            f"mission {mission}'s inspection saw it off station (open)"
        )

        ais = section.locator(f"[data-testid=alarm][data-source=ais][data-buoy='{ALARM_BUOY_ID}']")
        name = ais.get_by_test_id("alarm-name")
        expect(name).to_have_text(ALARM_BUOY_NAME)  # the markup as literal text
        assert name.locator("*").count() == 0
        expect(ais.get_by_test_id("alarm-source")).to_have_text(f"AIS, MMSI {off.mmsi}")
        expect(ais.get_by_test_id("alarm-distance")).to_have_text(
            f"{register_with_alarms.ais['distance_m']:.1f} m from its charted position, swing radius 5.0 m"
        )
        expect(ais.get_by_test_id("alarm-at")).to_have_text(stamp)
        expect(ais.get_by_test_id("alarm-why")).to_have_text("the AtoN reports itself off position")
        page.screenshot(path=str(ARTIFACTS / "web_alarms.png"))

        # a click with the register overlay off: the map centred on the buoy (the mission's marker of it)
        inspection.click()
        wait_in_map(page, page.get_by_title(target["name"][:64], exact=True), centred=True)
        expect(page.get_by_test_id("register-detail")).to_have_count(0)

        # with the overlay on: centred on the buoy and its popup opened, its name as text
        page.locator(".leaflet-control-layers").hover()
        page.get_by_label("Register buoys").check()
        expect(page.get_by_test_id("register-buoy")).to_have_count(317, timeout=30_000)
        page.mouse.move(0, 0)
        ais.click()
        detail = page.get_by_test_id("register-detail")
        expect(detail.locator("h3")).to_have_text(ALARM_BUOY_NAME, timeout=10_000)
        assert detail.locator("h3 *").count() == 0
        expect(detail.get_by_test_id("register-ais")).to_contain_text(f"MMSI {off.mmsi}, matched by MMSI")
        expect(detail.get_by_test_id("register-ais")).to_contain_text("off position")
        wait_in_map(page, page.locator(f"[data-testid=register-buoy][data-id='{ALARM_BUOY_ID}']"), centred=False)
        page.screenshot(path=str(ARTIFACTS / "web_alarms_buoy.png"))
