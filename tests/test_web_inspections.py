"""The map page's inspections in a real browser (headless Chromium via Playwright): the service over a database
holding a completed mission with its inspection records and real JPEG frames (tests/inspected_missions.py: B1 ok,
B2 off station with a burst of 50 frames, B3 not inspected, B4 light out), no flight.

The markers carry each verdict (a badge: symbol and colour), the panel lists each buoy's findings in words with
their figures and links the exports, and a click on a buoy shows its best frame large and its burst as a strip
of at most 40 lazy thumbnails. A mission under way shows the buoys not judged yet as pending, and a record stored
meanwhile turns up on the page by itself. Screenshots go to test-artifacts/.
"""

import pytest
from inspected_missions import BURST, CAMERA, NOT_INSPECTED_REASON, inspection_record, store_inspected_mission
from playwright.sync_api import Page, expect, sync_playwright
from service_process import serving
from test_web_browser import ARTIFACTS, open_page

from gcs.domain.status import MissionStatus
from gcs.storage import open_storage

pytestmark = [pytest.mark.browser, pytest.mark.integration, pytest.mark.slow]

MARKERS = ".leaflet-marker-pane"
EXPORTS = [  # file, the link's test id, media type
    ("inspections.csv", "inspections-csv", "text/csv"),
    ("inspections.geojson", "inspections-geojson", "application/geo+json"),
]
LARGE_LOADED = """() => {
    const image = document.querySelector("#gallery-large");
    return !image.hidden && image.complete && image.naturalWidth > 0 ? image.getAttribute("src") : null;
}"""


def badge(page: Page, buoy_id: str):
    """The verdict badge on buoy `buoy_id`'s marker (its title is the buoy's id)."""
    return page.locator(f"{MARKERS} .leaflet-marker-icon[title='{buoy_id}'] .verdict-badge")


def large_frame_loaded(page: Page) -> str:
    """Waits until the gallery's large image has loaded (naturalWidth > 0); returns its src."""
    return page.wait_for_function(LARGE_LOADED, timeout=10_000).json_value()


@pytest.fixture
def service_with_an_inspected_mission(tmp_path):
    """`python -m gcs serve` (no vehicle) over a database holding the completed inspected mission; yields (url, the
    database's path, the mission)."""
    storage = open_storage(tmp_path / "gcs.sqlite")
    mission = store_inspected_mission(storage)
    storage.close()
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log") as url:
        yield url, tmp_path / "gcs.sqlite", mission


def test_the_page_shows_each_verdict_the_findings_and_the_frames_of_a_buoy(service_with_an_inspected_mission):
    url, db, mission = service_with_an_inspected_mission
    records = {r.buoy_id: r for r in mission.records}
    frames = {buoy_id: [f"/missions/{mission.id}/frames/{i}" for i in r.frame_ids] for buoy_id, r in records.items()}
    best = {buoy_id: f"/missions/{mission.id}/frames/{r.best_frame}" for buoy_id, r in records.items() if r.frame_ids}
    errors: list[str] = []
    with sync_playwright() as p:
        browser, page = open_page(p, errors)
        page.on("console", lambda m: errors.append(m.text) if "Content Security" in m.text else None)
        asked: list[str] = []
        page.on("request", lambda r: asked.append(r.url) if r.url.endswith("/inspections") else None)
        page.goto(url)

        # the markers: each buoy's verdict by its symbol (and data-verdict), all three verdicts there
        expect(page.locator(".buoy-icon")).to_have_count(4, timeout=30_000)
        for buoy_id, verdict, symbol in (("B1", "ok", "✓"), ("B2", "defect", "✗"), ("B3", "not_inspected", "?"),
                                         ("B4", "defect", "✗")):  # fmt: skip
            expect(badge(page, buoy_id)).to_have_attribute("data-verdict", verdict)
            expect(badge(page, buoy_id)).to_have_text(symbol)
        expect(page.locator(f"{MARKERS} .verdict-badge")).to_have_count(4)

        # the list: a row per buoy in visiting order, the findings in words with their figures, the reason
        expect(page.get_by_test_id("inspection-counts")).to_have_text("1 ok, 2 defect, 1 not inspected")
        expect(page.get_by_test_id("inspection-camera")).to_have_text(f"camera: {CAMERA}")
        rows = page.get_by_test_id("inspection-row")
        expect(rows).to_have_count(4)
        expect(rows.locator(".inspection-buoy")).to_have_text(
            ["✓1 B1: ok", "✗2 B2: defect", "?3 B3: not inspected", "✗4 B4: defect"]
        )
        expect(rows.nth(1).locator(".findings li")).to_have_text(
            [
                "off station: 7.3 m from its charted position, bearing 45° (swing radius 3.0 m)",
                "light: charted Fl G 5s, read flashing . G 5.0s",
                "seen 7.3 m from its charted position",
            ]
        )
        expect(rows.nth(2).locator(".findings li")).to_have_text([f"why: {NOT_INSPECTED_REASON}"])
        expect(rows.nth(3).locator(".findings li").first).to_have_text("light out: charted Fl(2)G.6s, seen dark")
        # the exports: links to the routes, which answer
        for name, test_id, media in EXPORTS:
            link = page.get_by_test_id(test_id)
            expect(link).to_have_attribute("href", f"/missions/{mission.id}/{name}")
            answer = page.request.get(url + link.get_attribute("href"))
            assert answer.status == 200 and answer.headers["content-type"].startswith(media), name

        # B2's marker clicked: its best frame large (loaded), its burst as 40 thumbnails spread over the 50 frames
        page.locator(f"{MARKERS} .leaflet-marker-icon[title='B2']").click()
        gallery = page.get_by_test_id("gallery")
        expect(gallery).to_be_visible()
        expect(page.get_by_test_id("gallery-title")).to_have_text("✗ 2 B2: defect")
        assert large_frame_loaded(page) == best["B2"]
        expect(page.get_by_test_id("gallery-caption")).to_have_text(f"frame {BURST // 2 + 1} of {BURST} (the best)")
        thumbnails = page.get_by_test_id("gallery-strip").locator("img")
        expect(thumbnails).to_have_count(40)
        more = f"{BURST} frames: 40 shown, {BURST - 40} more not shown"
        expect(page.get_by_test_id("gallery-more")).to_have_text(more)
        sources = [thumbnails.nth(k).get_attribute("src") for k in range(40)]
        assert sources[0] == frames["B2"][0] and sources[-1] == frames["B2"][-1]
        assert len(set(sources)) == 40 and set(sources) <= set(frames["B2"])
        assert sources == sorted(sources, key=frames["B2"].index)  # in capture order
        assert all(thumbnails.nth(k).get_attribute("loading") == "lazy" for k in range(40))
        page.screenshot(path=str(ARTIFACTS / "web_inspection_gallery.png"))
        # a thumbnail clicked shows large
        page.get_by_test_id("gallery-strip").locator("button").nth(2).click()
        page.wait_for_function(f"() => ({LARGE_LOADED})() === {sources[2]!r}", timeout=10_000)
        position = frames["B2"].index(sources[2]) + 1
        expect(page.get_by_test_id("gallery-caption")).to_have_text(f"frame {position} of {BURST}")
        expect(page.locator(".thumbnail.selected")).to_have_count(1)

        # a row clicked: B4's four frames, all shown; B3's none
        rows.nth(3).locator(".inspection-buoy").click()
        expect(page.get_by_test_id("gallery-title")).to_have_text("✗ 4 B4: defect")
        assert large_frame_loaded(page) == best["B4"]
        expect(thumbnails).to_have_count(4)
        expect(page.get_by_test_id("gallery-more")).to_have_text("4 frames")
        rows.nth(2).locator(".inspection-buoy").click()
        expect(page.get_by_test_id("gallery-title")).to_have_text("? 3 B3: not inspected")
        expect(page.get_by_test_id("gallery-more")).to_have_text("no frame of this buoy was stored")
        expect(page.get_by_test_id("gallery-large")).to_be_hidden()
        expect(thumbnails).to_have_count(0)
        page.get_by_role("button", name="close the frames").click()
        expect(gallery).to_be_hidden()
        # a stored mission that has ended: its records fetched once, not polled
        assert len(asked) == 1, asked

        # a mission under way (between sorties) with B1 judged: the others pending, and B2's record, stored while
        # the page watches, turns up by itself
        storage = open_storage(db)
        waiting = store_inspected_mission(storage, recorded=(0,), status=MissionStatus.WAITING_FOR_BATTERY)
        page.get_by_role("button", name="Refresh").click()
        page.locator("#history-rows tr", has_text="waiting_for_battery").get_by_role("button", name="show").click()
        expect(page.get_by_test_id("mission-status")).to_contain_text(f"#{waiting.id}: waiting_for_battery")
        expect(page.get_by_test_id("inspection-counts")).to_have_text("1 ok, 3 pending")
        for buoy_id in ("B2", "B3", "B4"):
            expect(badge(page, buoy_id)).to_have_attribute("data-verdict", "pending")
            expect(badge(page, buoy_id)).to_have_text("…")
        page.screenshot(path=str(ARTIFACTS / "web_inspection_pending.png"))
        storage.set_inspection(waiting.id, inspection_record(storage, waiting.id, waiting.plan, 1, "", {}))
        storage.close()
        expect(badge(page, "B2")).to_have_attribute("data-verdict", "defect", timeout=10_000)
        expect(page.get_by_test_id("inspection-counts")).to_have_text("1 ok, 1 defect, 2 pending")
        browser.close()
    assert errors == []
