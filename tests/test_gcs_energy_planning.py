"""Energy-aware planning through the API, without a vehicle (the energy model's pack stands in for its
parameters): sorties that each fit one battery, predictions, and the 422 of a buoy no sortie can reach.

Flying the sorties (battery swaps, the failsafe) is tested on the real stack in test_e2e_stack.py."""

import pytest
from test_gcs_api import BUOYS, errors_of, make_client

from gcs.domain.schemas import PlanRequest
from gcs.missions.energy_planning import battery_plan, budget, model_pack, steady_load_w
from planner.energy import EnergyModel

MODEL = EnergyModel.load()


@pytest.fixture
def client(tmp_path):
    with make_client(tmp_path) as c:
        yield c


def plan(client, **fields):
    response = client.post("/plans", json={"buoys": BUOYS, "planner": {"seed": 1, "time_limit_s": 1.0}, **fields})
    assert response.status_code == 200, response.text
    return response.json()


def test_without_battery_options_a_plan_is_one_tour_with_no_energy_section(client):
    body = plan(client)
    assert body["energy"] is None
    assert [s["order"] for s in body["sorties"]] == [body["order"]]
    assert body["sorties"][0]["predicted_energy_wh"] is None
    assert body["route"] == body["sorties"][0]["route"]


def test_a_small_battery_splits_the_buoys_into_sorties_that_each_fit(client):
    body = plan(client, battery={"capacity_mah": 1000, "reserve_pct": 20}, wind={"speed_m_s": 4, "from_deg": 250})
    energy, sorties = body["energy"], body["sorties"]
    assert (energy["pack_source"], energy["reserve_source"], energy["reserve_pct"]) == ("energy model", "request", 20)
    assert energy["budget_wh"] == pytest.approx(energy["usable_wh"] * 0.95)
    assert len(sorties) >= 2
    assert sorted(b for s in sorties for b in s["order"]) == list(range(len(BUOYS)))
    assert body["order"] == [b for s in sorties for b in s["order"]]
    for sortie in sorties:
        assert sortie["predicted_energy_wh"] + sortie["margin_wh"] == pytest.approx(energy["budget_wh"])
        assert sortie["margin_wh"] >= 0 and sortie["predicted_landing_charge_pct"] > 20
        assert sortie["route"][0] == sortie["route"][-1] == [body["depot"]["lat"], body["depot"]["lon"]]
    # the mission's route passes the depot between sorties
    assert len(body["route"]) == len(BUOYS) + len(sorties) + 1
    assert body["length_m"] == pytest.approx(sum(s["length_m"] for s in sorties))


def test_the_same_buoys_forced_into_one_sortie_report_a_negative_margin(client):
    body = plan(client, battery={"capacity_mah": 1000, "split": False})
    (sortie,) = body["sorties"]
    assert sortie["margin_wh"] < 0 and sortie["margin_pct"] < 0
    assert sortie["predicted_landing_charge_pct"] < body["energy"]["reserve_pct"]


def test_a_head_wind_costs_energy(client):
    calm = plan(client, battery={"split": False})["sorties"][0]["predicted_energy_wh"]
    windy = plan(client, battery={"split": False}, wind={"speed_m_s": 8, "from_deg": 90})["sorties"][0]
    assert windy["predicted_energy_wh"] > calm * 1.02


def test_vehicle_shorthand_takes_every_option_from_the_vehicle_or_says_what_stood_in(client):
    energy = plan(client, battery="vehicle")["energy"]
    pack = model_pack(MODEL)
    assert (energy["pack_source"], energy["reserve_source"]) == ("energy model", "energy model")
    assert energy["reserve_pct"] == pytest.approx(100 * pack.low_threshold)
    assert energy["usable_wh"] == pytest.approx(pack.energy_wh(1.0, pack.low_threshold, steady_load_w(MODEL)))


def test_a_buoy_no_sortie_can_reach_is_a_422_naming_it_and_its_shortfall(client):
    response = client.post("/missions", json={"buoys": BUOYS, "battery": {"capacity_mah": 300}, "start": False})
    errors = errors_of(response)
    assert errors and all(loc[:2] == ["body", "buoys"] for loc, _ in errors)
    far = [msg for loc, msg in errors if loc == ["body", "buoys", 12]]
    assert far and far[0].startswith("buoy B13 cannot be reached and flown back from within one battery"), errors
    assert "more than the" in far[0] and " Wh" in far[0]
    assert client.get("/missions").json() == []  # nothing stored


@pytest.mark.parametrize(
    ("battery", "wind", "loc"),
    [
        ({"reserve_pct": 95}, None, ["body", "battery", "BatteryIn", "reserve_pct", "constrained-float"]),
        ({"capacity_mah": -5}, None, ["body", "battery", "BatteryIn", "capacity_mah"]),
        ({"objective": "fuel"}, None, ["body", "battery", "BatteryIn", "objective"]),
        (None, {"speed_m_s": 3, "from_deg": 400}, ["body", "wind", "from_deg"]),
        (None, {"speed_m_s": -1, "from_deg": 0}, ["body", "wind", "speed_m_s"]),
    ],
)
def test_bad_battery_and_wind_options_are_422_naming_the_field(client, battery, wind, loc):
    fields = {"battery": battery} if battery is not None else {}
    fields |= {"wind": wind} if wind is not None else {}
    response = client.post("/plans", json={"buoys": BUOYS, **fields})
    assert loc in [e[0] for e in errors_of(response)], response.json()


def test_the_budget_is_the_pack_down_to_the_reserve_less_the_margin():
    request = PlanRequest(buoys=[{"lat": 0, "lon": 0}], battery={"reserve_pct": 25, "margin_pct": 10})
    battery = battery_plan(request, None, MODEL)
    energies = budget(battery, MODEL)
    assert battery.reserve == 0.25
    # 75 % of the charge holds more than 75 % of the energy: the voltage is higher at the top of the chart
    assert 0.75 * energies["capacity_wh"] < energies["usable_wh"] < 0.8 * energies["capacity_wh"]
    assert energies["budget_wh"] == pytest.approx(0.9 * energies["usable_wh"])
