"""What a stored mission holds besides its plan and flight, typed: its progress, its results, the plan's energy and
fleet sections, and its status history. Storage reads and writes these (JSON columns), the service and the reports
use their attributes, and the API's documents are built from them (gcs.reports.views).

Each is a pydantic model so that a stored document is checked once, when it is read, and written back as the same
JSON. Every field has a default where a document stored by an earlier version of the service may lack it, and
unknown keys (a field since removed) are ignored: a database keeps working across upgrades.
"""

from __future__ import annotations

from pydantic import BaseModel, Field

from gcs.domain.schemas import BuoyResult, EnergyOut, Progress, SeparationOut, TrackingFigures
from gcs.domain.status import MissionStatus


# ----- the plan's sections
class SortiePrediction(BaseModel):
    """The energy model's prediction for one sortie (gcs.missions.energy_planning.predictions)."""

    energy_wh: float
    time_s: float
    margin_wh: float = Field(description="budget left after the predicted energy (negative: over budget)")
    margin_pct: float
    landing_charge_pct: float = Field(description="charge predicted at landing, on a full pack")
    needed_charge_pct: float = Field(description="charge needed at take-off to land with the reserve")


class PlanEnergy(EnergyOut):
    """An energy-planned mission's battery, budget and per-sortie predictions (`Plan.energy`); the API shows it
    without the sorties (each SortieOut carries its own prediction)."""

    sorties: list[SortiePrediction]


class PlannedShare(BaseModel):
    """One vehicle's share of a fleet mission as planned, and what happened to it: lost, and to whom its buoys
    went (a share is flown by its own part mission, whose plan has the route)."""

    sysid: int
    home: list[float] = Field(description="[lat, lon]")
    buoys: list[int] = Field(description="the fleet mission's buoy indices, in flying order")
    altitude_m: float
    predicted_time_s: float
    length_m: float
    # its turn at the depot (planner.fleet_schedule); the defaults: a plan stored before there were turns
    start_s: float = Field(default=0.0, description="predicted mission start, seconds after the fleet's")
    depart_after: int | None = Field(default=None, description="started when this vehicle has left the depot zone")
    final_hold_s: float = Field(default=0.0, description="hover added at its last buoy so that it lands in its turn")
    zone_centre: list[float] | None = Field(default=None, description="[lat, lon] of its depot zone's centre")
    zone_radius_m: float | None = None
    # when the service started it in its turn: its vehicle's clock and the one it waited for's (time_boot_ms / 1000),
    # read at that instant: how its flight lines up with the other's in their own times (bench.fleet_flown)
    started_t_s: float | None = None
    ahead_t_s: float | None = None
    lost: str | None = None
    handed_over: dict[str, list[int]] = Field(default_factory=dict, description="sysid -> buoys it took over")


class PlanFleet(BaseModel):
    """A fleet mission's section of its plan (`Plan.fleet`); the plan itself has the buoys and their ids."""

    makespan_s: float
    total_time_s: float
    layer_gap_m: float
    separation_m: float | None = None  # None: planned before take-offs and landings were sequenced
    shares: list[PlannedShare]

    def share_of(self, sysid: int) -> PlannedShare:
        return next(share for share in self.shares if share.sysid == sysid)


# ----- progress
class SortieFlown(BaseModel):
    """A flown sortie's battery figures, from the vehicle's BATTERY_STATUS (gcs.missions.recorder)."""

    sortie: int
    used_energy_wh: float | None
    landing_charge_pct: float | None
    battery_warning: str | None


class ShareProgress(BaseModel):
    """A fleet mission's share as flown: its part mission, that part's status and the buoys it inspected."""

    sysid: int
    mission_id: int
    status: MissionStatus
    visited: list[int] = Field(description="the fleet mission's buoy indices")


class MissionProgress(Progress):
    """The progress stored with a mission: what the API shows (Progress) and what the recorder keeps for itself,
    so that a restarted service continues a mission where it was."""

    reached_at: dict[int, float] = Field(default_factory=dict, description="buoy index -> vehicle time reached")
    # buoy index -> when the service heard it reached (unix seconds, its own clock): the operator's time of day,
    # which the vehicle's boot time is not (and a lockstep vehicle's clock runs faster than the wall's)
    reached_wall_at: dict[int, float] = Field(default_factory=dict)
    sorties_flown: list[SortieFlown] = Field(default_factory=list)
    consumed_at_start: float | None = None  # the battery's consumed energy when the sortie took off
    shares: list[ShareProgress] = Field(default_factory=list)  # a fleet mission's
    capture: bool = False  # the sortie on board has an inspection group per buoy (gcs.domain.planning.MissionLayout)

    def shown(self) -> Progress:
        """The part the API shows."""
        return Progress.model_validate(self.model_dump(include=set(Progress.model_fields)))


# ----- results
class MissionResults(BaseModel):
    """Stored when a mission ends: a flight's tracking and per-buoy figures (gcs.missions.results), or a fleet
    mission's separation and who inspected what (gcs.missions.fleet_missions)."""

    tracking: TrackingFigures | None = None
    buoys: list[BuoyResult] | None = None
    separation: SeparationOut | None = None
    inspected_by: dict[str, int] = Field(default_factory=dict, description="buoy id -> the sysid that inspected it")
