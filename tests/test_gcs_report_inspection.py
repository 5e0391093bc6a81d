"""The report's inspection section, from stored records and frames (tests/inspected_missions.py: B1 ok, B2 off
station, B3 not inspected, B4 light out): the table's rows in plain words, the map by verdict, the defective buoys'
best frames copied beside index.html and served by the report route, text from the mission escaped, and a redraw
after a record changed leaving no stale frame behind."""

import re

import pytest
from fastapi.testclient import TestClient
from inspected_missions import OFF_STATION, store_inspected_mission

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.inspection import BuoyInspection
from gcs.reports.inspection_report import INSPECTION_FIGURE, describe_finding
from gcs.reports.report import cached_report, is_report_file, write_stored_report
from gcs.settings import Settings
from gcs.storage import SqliteStorage

PNG = b"\x89PNG\r\n\x1a\n"
HOSTILE_ID = "<img src=x onerror=window.injected=1>"
HOSTILE_REASON = "<script>window.injected=2</script> & more"


def settings_without_vehicle(db_path) -> Settings:
    """The service's settings over db_path, its vehicle a UDP port nobody holds."""
    return Settings(db_path=db_path, vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")


@pytest.fixture
def inspected(tmp_path):
    storage = SqliteStorage(tmp_path / "gcs.sqlite")
    mission = store_inspected_mission(storage)
    yield storage, mission
    storage.close()


def rows_of(page: str) -> list[list[str]]:
    """The inspection table's rows, cell texts (as written: escaped)."""
    table = page[page.index('<table data-testid="inspections">') :]
    body = table[: table.index("</table>")]
    return [re.findall(r"<td>(.*?)</td>", row) for row in re.findall(r"<tr class=[^>]*>(.*?)</tr>", body)]


def test_the_section_tables_each_buoy_maps_the_verdicts_and_shows_the_defects_best_frames(inspected, tmp_path):
    storage, mission = inspected
    index = write_stored_report(storage, storage.get_mission(mission.id), tmp_path / "out")
    page, folder = index.read_text(), index.parent

    assert '<p data-testid="inspection-counts">1 ok, 2 defect, 1 not inspected</p>' in page
    rows = rows_of(page)
    assert [row[:2] for row in rows] == [["B1", "ok"], ["B2", "defect"], ["B3", "not inspected"], ["B4", "defect"]]
    off_station = "off station: 7.3 m from its charted position, bearing 45° (swing radius 3.0 m)"
    assert rows[1][2] == off_station
    assert rows[3][2] == "light out: charted Fl(2)G.6s, seen dark"
    # light charted and read, offset, frames, reason
    assert rows[0][3:] == ["LFl 10s", "long-flashing - W 10.0s", "0.40", "5", ""]
    assert rows[1][3:7] == ["Fl G 5s", "flashing . G 5.0s", "7.30", "50"]
    assert rows[2][2:] == ["–", "Fl R 5s", "–", "–", "0", "the buoy&#x27;s search area was in none of the 6 frames"]

    figure = folder / INSPECTION_FIGURE
    assert figure.read_bytes()[:8] == PNG and figure.stat().st_size > 5000
    assert f'<img src="{INSPECTION_FIGURE}"' in page
    # the defective buoys' best frames (B2 is input index 1, B4 index 3), byte for byte, and only theirs
    best = {r.buoy: mission.frame_bytes[r.best_frame] for r in mission.records if r.result.verdict == "defect"}
    assert sorted(p.name for p in folder.glob("defect-*")) == ["defect-1.jpg", "defect-3.jpg"]
    for buoy, data in best.items():
        assert (folder / f"defect-{buoy}.jpg").read_bytes() == data
        assert f'<img src="defect-{buoy}.jpg"' in page
    assert f"<figcaption>B2: {off_station}</figcaption>" in page


def test_describe_finding_says_every_code_in_plain_words():
    assert describe_finding({"code": "off_station", **OFF_STATION}).startswith("off station: 7.3 m")
    assert describe_finding({"code": "wrong_period", "charted_period_s": 5, "seen_period_s": 3.2}) == (
        "wrong light period: charted 5.0 s, seen 3.2 s"
    )
    assert describe_finding({"code": "wrong_character", "charted": "Fl G 5s", "seen": "fixed G"}) == (
        "wrong light character: charted Fl G 5s, seen fixed G"
    )
    assert describe_finding({"code": "wrong_colour", "charted": "Fl G 5s", "seen": "flashing . R 5.0s"}) == (
        "wrong light colour: charted Fl G 5s, seen flashing . R 5.0s"
    )
    assert describe_finding({"code": "wrong_body_colour", "expected": ["green"], "seen": ["red", "white"]}) == (
        "wrong body colour: green expected, red/white seen"
    )
    assert describe_finding({"code": "not_found", "frames": 12, "why": "no_paint"}) == (
        "not found in any of its 12 frames (no_paint)"
    )
    assert describe_finding({"code": "new_code", "size": 3}) == "new_code: size 3"


def test_text_from_the_mission_is_escaped_in_the_section(tmp_path):
    storage = SqliteStorage(tmp_path / "gcs.sqlite")
    mission = store_inspected_mission(storage, ids=[HOSTILE_ID, "B2", "B3", "B4"], reason=HOSTILE_REASON)
    page = write_stored_report(storage, storage.get_mission(mission.id), tmp_path / "out").read_text()
    storage.close()
    assert HOSTILE_ID not in page and "<script>" not in page
    rows = rows_of(page)
    assert rows[0][0] == "&lt;img src=x onerror=window.injected=1&gt;"
    assert rows[2][-1] == "&lt;script&gt;window.injected=2&lt;/script&gt; &amp; more"


def test_the_route_serves_the_section_and_a_redraw_drops_a_frame_no_longer_defective(inspected):
    storage, mission = inspected
    settings = settings_without_vehicle(storage.path)
    with TestClient(create_app(settings)) as client:
        base = f"/missions/{mission.id}/report"
        page = client.get(f"{base}/index.html").text
        assert "1 ok, 2 defect, 1 not inspected" in page
        figure = client.get(f"{base}/{INSPECTION_FIGURE}")
        assert figure.status_code == 200 and figure.headers["content-type"] == "image/png"
        frame = client.get(f"{base}/defect-1.jpg")
        assert frame.status_code == 200 and frame.headers["content-type"] == "image/jpeg"
        b2 = mission.records[1]
        assert frame.content == mission.frame_bytes[b2.best_frame]
        for name in ("defect-0.jpg", "defect-1.jpeg", "defect-1.jpg.bak", "defect-x.jpg", "stamp.json"):
            assert client.get(f"{base}/{name}").status_code == 404, name

        # B2 judged again as ok: the report is redrawn (the record raised the mission's updated_at) without it
        ok = BuoyInspection.model_validate(
            b2.result.model_dump() | {"verdict": "ok", "findings": [], "offset_m": 0.5, "observed": None}
        )
        storage.set_inspection(mission.id, b2.model_copy(update={"result": ok}))
        page = client.get(f"{base}/index.html").text
        assert "2 ok, 1 defect, 1 not inspected" in page
        assert client.get(f"{base}/defect-1.jpg").status_code == 404
        assert client.get(f"{base}/defect-3.jpg").status_code == 200
    folder = settings.reports_dir / f"mission-{mission.id}"
    assert sorted(p.name for p in folder.glob("defect-*")) == ["defect-3.jpg"]


def test_a_mission_with_no_inspection_record_says_so_and_draws_no_map(tmp_path):
    storage = SqliteStorage(tmp_path / "gcs.sqlite")
    mission = store_inspected_mission(storage, recorded=())
    index = cached_report(storage, mission.id, tmp_path / "cache")
    storage.close()
    assert '<p data-testid="inspection-none">No inspection records.</p>' in index.read_text()
    assert not (index.parent / INSPECTION_FIGURE).exists()


@pytest.mark.parametrize(
    ("name", "served"),
    [("index.html", True), (INSPECTION_FIGURE, True), ("defect-12.jpg", True), ("defect-3.png", True),
     ("defect-.jpg", False), ("defect-1.gif", False), ("../defect-1.jpg", False), ("defect-12345.jpg", False)],
)  # fmt: skip
def test_is_report_file(name, served):
    assert is_report_file(name) == served
