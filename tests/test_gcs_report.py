"""The mission report: series from samples, the drawn folder, its cache, the CLI and the HTTP route.

The flight here is synthetic (a vehicle flying the planned legs with a known lateral offset and a known lag
behind its reference), so every figure in the table has a value the test can compute by hand. A mission planned
in sorties for a battery (through the service, as a client asks for it) gets the per-sortie table and the chart
of predicted against used energy, the used energies being the ones stored in its progress.
"""

import math
import re
import sqlite3

import numpy as np
import pytest
from fastapi.testclient import TestClient
from stored_missions import SORTIES_FLOWN

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.cli import main
from gcs.domain.planning import FIRST_BUOY_SEQ, FlightParams, leg_of_seq, make_plan
from gcs.domain.records import MissionProgress
from gcs.missions.results import flight_results
from gcs.reports.report import ENERGY_FIGURE, FIGURES, cached_report, report_series, summary_rows, write_report
from gcs.settings import Settings
from gcs.storage import SqliteStorage, Storage
from stack.demo import reference_request
from stack.options import UpOptions
from uavcore.geodesy import DEFAULT_HOME

OFFSET_M = 0.3  # the synthetic vehicle flies this far to the left of every leg
LAG_M = 0.5  # and this far behind its reference point
FLIGHT = FlightParams(altitude_m=5.0, speed_m_s=10.0, dwell_s=1.0, acceptance_radius_m=2.0)


def synthetic_mission(storage: Storage) -> int:
    """A 3-buoy mission flown along its legs, offset and lagging by known amounts, stored with results."""
    depot = DEFAULT_HOME[:2]
    plan = make_plan(
        depot,
        [(depot[0] + 0.0005, depot[1]), (depot[0] + 0.0005, depot[1] + 0.0008), (depot[0] - 0.0003, depot[1] + 0.0004)],
        ["A", "B", "C"],
        "exact",
    )
    route = plan.route_local()
    samples, t = [], 10.0
    for leg in range(len(route) - 1):
        start, end = route[leg], route[leg + 1]
        direction = (end - start) / np.linalg.norm(end - start)
        left = np.array([-direction[1], direction[0]])
        for fraction in np.linspace(0.1, 0.9, 20):
            east, north = start + fraction * (end - start) + OFFSET_M * left
            ref_east, ref_north = (east, north) + LAG_M * direction - OFFSET_M * left
            lat, lon, _ = plan.frame.from_ned(north, east, -5.0)
            samples.append(
                {
                    "t_s": t,
                    "lat": lat,
                    "lon": lon,
                    "alt_m": 5.0,
                    "north": north,
                    "east": east,
                    "down": -4.9,
                    "ref_north": ref_north,
                    "ref_east": ref_east,
                    "ref_down": -5.0,
                    "yaw": 0.1,
                    "ref_yaw": 0.12,
                    "landed_state": 2,
                    "armed": True,
                    "mission_seq": FIRST_BUOY_SEQ + leg,
                    "cross_track_m": OFFSET_M,
                    "eso": {"ESO_Z3": [0.1, -0.2, 0.05 * leg]},
                }
            )
            t += 0.1
    assert [leg_of_seq(s["mission_seq"], 3) for s in samples[::20]] == [0, 1, 2, 3]
    # the buoys themselves are passed over (reached) while dwelling, between legs
    for index in plan.order:
        east, north = plan.buoys_local[index]
        lat, lon, _ = plan.frame.from_ned(north, east, -5.0)
        samples.append(
            {
                **samples[-1],
                "t_s": t,
                "lat": lat,
                "lon": lon,
                "north": north,
                "east": east,
                "mission_seq": None,
                "cross_track_m": None,
            }
        )
        t += 0.1
    mission_id = storage.create_mission(FLIGHT, plan)
    storage.add_telemetry(mission_id, samples)
    storage.set_results(mission_id, flight_results(plan, FLIGHT, storage.telemetry(mission_id), MissionProgress()))
    storage.set_status(mission_id, "completed")
    return mission_id


@pytest.fixture
def stored(tmp_path):
    storage = SqliteStorage(tmp_path / "gcs.sqlite")
    mission_id = synthetic_mission(storage)
    yield storage, mission_id
    storage.close()


def test_series_and_figures_table_have_the_flown_errors(stored):
    storage, mission_id = stored
    record = storage.get_mission(mission_id)
    series = report_series(storage.telemetry(mission_id))
    on_legs = series.position_error_m[: 4 * 20]
    # the reference is LAG_M ahead and OFFSET_M to the side horizontally, 0.1 m up
    assert on_legs == pytest.approx(math.sqrt(LAG_M**2 + OFFSET_M**2 + 0.1**2), abs=1e-6)
    assert series.altitude == pytest.approx(4.9) and series.ref_altitude == pytest.approx(5.0)
    assert series.eso["ESO_Z3"].shape == (len(series.t_s), 3)
    rows = dict(summary_rows(record, series))
    assert rows["status"] == "completed"
    assert rows["buoys reached"] == "3 of 3"
    assert rows["altitude error RMS (on legs)"] == "0.100 m"
    assert rows["yaw error RMS (on legs)"] == f"{math.degrees(0.02):.2f}°"
    assert float(rows["cross-track RMS"].split()[0]) == pytest.approx(OFFSET_M, abs=0.01)


def test_write_report_draws_every_figure_and_the_page_shows_them(stored, tmp_path):
    storage, mission_id = stored
    index = write_report(storage.get_mission(mission_id), storage.telemetry(mission_id), tmp_path / "out")
    page = index.read_text()
    for name in FIGURES:
        png = index.parent / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000, name
        assert f'src="{name}"' in page
    assert "cross-track RMS" in page and "Mission 1 report" in page


def test_cached_report_is_redrawn_only_after_the_mission_changed(stored, tmp_path):
    storage, mission_id = stored
    index = cached_report(storage, mission_id, tmp_path / "cache")
    first = index.stat().st_mtime_ns
    assert cached_report(storage, mission_id, tmp_path / "cache").stat().st_mtime_ns == first
    storage.set_status(mission_id, "completed", "re-examined")
    again = cached_report(storage, mission_id, tmp_path / "cache")
    assert again.stat().st_mtime_ns != first and "re-examined" in again.read_text()


def test_cli_writes_the_report_and_refuses_bad_input(stored, tmp_path, capsys):
    storage, mission_id = stored
    out = tmp_path / "cli"
    assert main(["report", str(mission_id), "--db", str(storage.path), "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out / "index.html")
    assert all((out / name).is_file() for name in FIGURES)

    assert main(["report", "999", "--db", str(storage.path)]) == 2
    assert "no mission 999" in capsys.readouterr().err
    assert main(["report", "1", "--db", str(tmp_path / "missing.sqlite")]) == 2
    assert "no database at" in capsys.readouterr().err
    assert not (tmp_path / "missing.sqlite").exists()  # the check must not create an empty database
    not_sqlite = tmp_path / "notes.txt"
    not_sqlite.write_text("not a database " * 100)
    assert main(["report", "1", "--db", str(not_sqlite)]) == 2
    assert "--db" in capsys.readouterr().err


def settings_without_vehicle(db_path) -> Settings:
    """The service's settings over db_path, its vehicle a UDP port nobody holds."""
    return Settings(db_path=db_path, vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")


def test_report_route_serves_the_page_and_its_figures(stored, tmp_path):
    storage, mission_id = stored
    settings = settings_without_vehicle(storage.path)
    with TestClient(create_app(settings)) as client:
        response = client.get(f"/missions/{mission_id}/report")
        assert response.status_code == 200 and response.url.path.endswith("/report/index.html")
        assert "Mission 1 report" in response.text
        for name in FIGURES:
            figure = client.get(f"/missions/{mission_id}/report/{name}")
            assert figure.status_code == 200 and figure.headers["content-type"] == "image/png"
        assert client.get(f"/missions/{mission_id}/report/secrets.txt").status_code == 404
        assert client.get(f"/missions/{mission_id}/report/{ENERGY_FIGURE}").status_code == 404  # no energy planned
        assert client.get(f"/missions/{mission_id}/report/..%2Fgcs.sqlite").status_code == 404
        assert client.get("/missions/42/report").status_code == 404
        assert client.get("/missions/42/report/index.html").status_code == 404
    assert (settings.reports_dir / f"mission-{mission_id}" / "index.html").is_file()
    with sqlite3.connect(storage.path) as db:  # the route read, never wrote, the mission
        assert db.execute("SELECT status FROM missions WHERE id = ?", (mission_id,)).fetchone()[0] == "completed"


def test_a_mission_that_never_flew_still_gets_a_report(tmp_path):
    storage = SqliteStorage(tmp_path / "gcs.sqlite")
    depot = DEFAULT_HOME[:2]
    plan = make_plan(depot, [(depot[0] + 0.0005, depot[1])], ["A"], "exact")
    mission_id = storage.create_mission(FLIGHT, plan)
    storage.set_status(mission_id, "failed", "no vehicle")
    index = write_report(storage.get_mission(mission_id), storage.telemetry(mission_id), tmp_path / "out")
    page = index.read_text()
    assert "failed (no vehicle)" in page and "<th>samples</th><td>0</td>" in page
    assert all((index.parent / name).stat().st_size > 0 for name in FIGURES)
    storage.close()


def test_a_mission_in_sorties_gets_its_sortie_table_and_energy_chart(tmp_path):
    settings = settings_without_vehicle(tmp_path / "gcs.sqlite")
    request = {**reference_request(UpOptions()), "battery": {"capacity_mah": 1000}, "start": False}
    with TestClient(create_app(settings)) as client:
        created = client.post("/missions", json=request)
        assert created.status_code == 201, created.text
        mission = created.json()
        sorties = mission["sorties"]
        assert len(sorties) == 3  # the energy model's pack at 1000 mAh (no vehicle to ask)
        storage = SqliteStorage(settings.db_path)
        storage.set_progress(mission["id"], MissionProgress(sortie=2, sorties=3, sorties_flown=SORTIES_FLOWN))
        storage.set_status(mission["id"], "aborted", "battery critical in sortie 3 of 3")
        storage.close()
        chart = client.get(f"/missions/{mission['id']}/report/{ENERGY_FIGURE}")
        assert chart.status_code == 200 and chart.headers["content-type"] == "image/png"
        page = client.get(f"/missions/{mission['id']}/report/index.html").text

    assert f'src="{ENERGY_FIGURE}"' in page
    assert "<tr><th>sorties</th><td>3</td></tr>" in page
    assert "1000 mAh pack (energy model), reserve 15 % (energy model), margin 5 %" in page
    table = page[page.index('<table data-testid="sorties">') :]
    rows = re.findall(r"<tr><td>.*?</tr>", table[: table.index("</table>")])
    assert len(rows) == 3
    ids = [b["id"] for b in mission["buoys"]]
    for k, (row, sortie) in enumerate(zip(rows, sorties, strict=True)):
        flown = SORTIES_FLOWN[k] if k < len(SORTIES_FLOWN) else None
        assert f'<span class="swatch sortie-{k}"></span>{k + 1}</td>' in row
        assert f"<td>{', '.join(ids[b] for b in sortie['order'])}</td>" in row
        assert f"<td>{sortie['predicted_energy_wh']:.2f}</td>" in row
        # used, error, landing predicted and measured, warning: the row's last cells
        landing = f"<td>{sortie['predicted_landing_charge_pct']:.0f}</td>"
        if flown is None:
            assert row.endswith(f"<td>–</td><td>–</td>{landing}<td>–</td><td>–</td></tr>")
            continue
        used = flown.used_energy_wh
        error = 100 * (used - sortie["predicted_energy_wh"]) / used  # (used - predicted) / used
        measured = f"<td>{flown.landing_charge_pct:.0f}</td><td>{flown.battery_warning or 'none'}</td>"
        assert row.endswith(f"<td>{used:.2f}</td><td>{error:.1f}</td>{landing}{measured}</tr>")
    report_dir = settings.reports_dir / f"mission-{mission['id']}"
    for name in (*FIGURES, ENERGY_FIGURE):
        png = report_dir / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000, name
