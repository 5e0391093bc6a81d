"""The energy-missions benchmark's bookkeeping on fixed numbers (no flight): what a case asks the service and the
vehicle, the per-sortie error, the summary over sorties, what is kept for a look, and the figure."""

import math

import pytest

from bench.energy_missions import (
    RING_BUOYS,
    RING_RADIUS_M,
    WINDS,
    Case,
    draw,
    mission_figures,
    needs_a_look,
    summary,
)
from uavcore.geodesy import DEFAULT_HOME, LocalFrame


def sortie(index: int, predicted: float, used: float | None, warning: str | None = None) -> dict:
    """A sortie as GET /missions/{id} gives it."""
    return {
        "index": index,
        "order": [index],
        "predicted_energy_wh": predicted,
        "predicted_time_s": 100.0,
        "margin_wh": 0.5,
        "predicted_landing_charge_pct": 30.0,
        "used_energy_wh": used,
        "landing_charge_pct": None if used is None else 32.0,
        "battery_warning": warning,
    }


def mission(status: str, *sorties: dict) -> dict:
    return {
        "id": 7,
        "status": status,
        "reason": None,
        "buoys": [{"id": f"B{i}"} for i in range(len(sorties))],
        "progress": {"visited": len(sorties)},
        "buoy_results": [{"id": f"B{i}", "reached": status == "completed"} for i in range(len(sorties))],
        "energy": {"usable_wh": 6.5, "budget_wh": 6.2, "reserve_pct": 15.0, "pack_source": "vehicle"},
        "tracking": {"flight_time_s": 180.0},
        "sorties": list(sorties),
    }


def test_a_case_gives_the_vehicle_the_air_and_pack_the_request_forecasts_and_plans_for():
    case = Case("ring", 500.0, WINDS[2], seed=2, split=False)
    request, params = case.request(), case.vehicle_params()
    wind = request["wind"]
    assert (params["SIM_WIND_SPD"], params["SIM_WIND_DIR"], params["SIM_TURB_W20"]) == (
        wind["speed_m_s"],
        wind["from_deg"],
        wind["turbulence_w20_m_s"],
    )
    assert params["BAT1_CAPACITY"] == 500.0 and params["COM_LOW_BAT_ACT"] == 1
    assert request["battery"] == {"reserve_pct": "vehicle", "split": False}  # the pack is the vehicle's
    frame = LocalFrame(*DEFAULT_HOME)
    east_north = frame.project([(b["lat"], b["lon"]) for b in request["buoys"]])
    assert len(request["buoys"]) == RING_BUOYS
    assert all(math.hypot(*p[:2]) == pytest.approx(RING_RADIUS_M, abs=0.01) for p in east_north)
    reference = Case("reference", 1200.0, WINDS[0], seed=1).request()
    assert len(reference["buoys"]) == 13 and reference["dwell_s"] == 1.0


def test_sortie_errors_are_in_percent_of_the_energy_used_and_the_summary_takes_the_worst_over_all_sorties():
    ring = Case("ring", 500.0, WINDS[1], seed=1)
    first = mission_figures(ring, mission("completed", sortie(0, 5.5, 5.0), sortie(1, 4.9, 5.0)), wall_s=30.0)
    second = mission_figures(ring, mission("completed", sortie(0, 5.0, 5.0, warning="low")), wall_s=20.0)
    assert [s["error_pct"] for s in first["sorties"]] == pytest.approx([10.0, -2.0])
    assert first["predicted_flight_s"] == 200.0 and first["flight_time_error_pct"] == pytest.approx(100 * 20 / 180)
    figures = summary([first, second])
    assert figures["sorties"] == 3 and figures["completed"] == 2
    assert figures["mean_abs_energy_error_pct"] == pytest.approx(4.0)
    assert figures["worst_abs_energy_error_pct"] == pytest.approx(10.0)
    assert figures["worst_sortie"] == "ring, 3 m/s from 250, seed 1, sortie 1"
    assert figures["battery_warnings"] == ["ring, 3 m/s from 250, seed 1, sortie 1: low"]


def test_a_failed_mission_or_a_prediction_off_by_more_than_ten_percent_is_kept_for_a_look():
    ring = Case("ring", 500.0, WINDS[0], seed=1)
    assert not needs_a_look(mission_figures(ring, mission("completed", sortie(0, 5.4, 5.0)), 1.0))  # 8 %
    assert needs_a_look(mission_figures(ring, mission("completed", sortie(0, 5.6, 5.0)), 1.0))  # 12 %
    assert needs_a_look(mission_figures(ring, mission("failed", sortie(0, 5.0, 5.0)), 1.0))
    assert needs_a_look(mission_figures(ring, mission("completed", sortie(0, 5.0, None)), 1.0))  # never measured
    forced = Case("ring", 500.0, WINDS[1], seed=1, split=False)
    assert not needs_a_look(mission_figures(forced, mission("aborted", sortie(0, 11.0, 9.0)), 1.0))  # expected


def test_the_figure_is_drawn_from_the_flown_sorties(tmp_path):
    runs = [
        mission_figures(Case("ring", 500.0, WINDS[1], 1), mission("completed", sortie(0, 5.4, 5.3)), 1.0),
        mission_figures(Case("reference", 1200.0, WINDS[2], 2), mission("completed", sortie(0, 14.0, 14.3)), 1.0),
    ]
    path = tmp_path / "energy.png"
    draw(runs, path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
