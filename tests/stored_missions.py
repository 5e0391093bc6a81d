"""A small real mission as storage keeps one, for tests that store missions without planning them: its flight
and a two-buoy plan; and a multi-sortie mission's battery figures."""

from __future__ import annotations

from gcs.domain.planning import FlightParams, sorties_plan
from gcs.domain.records import SortieFlown

FLIGHT = FlightParams(altitude_m=5.0, speed_m_s=10.0, dwell_s=1.0, acceptance_radius_m=2.0)
PLAN = sorties_plan((55.0, 12.0), [(55.0005, 12.0), (55.0, 12.0008)], ["B1", "B2"], [[1, 0]], "test", 0.0)

# What the vehicle reported after each flown sortie of a three-sortie mission (gcs.missions.recorder's
# sorties_flown): the third never flew.
SORTIES_FLOWN = [
    SortieFlown(sortie=0, used_energy_wh=10.4, landing_charge_pct=34.0, battery_warning=None),
    SortieFlown(sortie=1, used_energy_wh=12.9, landing_charge_pct=14.0, battery_warning="low"),
]
