"""What the coordinator of a fleet mission keeps in the database so that another service instance can carry the
fleet mission on (gcs.missions.fleet_missions, gcs.missions.ownership): the closest approach of any two vehicles so
far, each lost part's re-share (who took which buoys, in which order), and which instance follows it now.

The rest of a fleet mission's state is stored already: its parts are the missions whose `fleet_id` is its id, its
shares (and what each lost share handed over) are its plan's `fleet` section, its status and events its row's. A
re-share is written with the fleet mission's plan and status event in one transaction
(`Storage.record_reshare`), before the receiving parts are told: a new owner finds either no trace of it (and
re-shares the lost part's buoys itself) or the whole decision (and delivers what the receivers did not get).
"""

from __future__ import annotations

from pydantic import BaseModel, Field

from gcs.domain.schemas import SeparationOut


class Reshare(BaseModel):
    """One lost part's buoys shared among the parts still flying, as decided."""

    part_id: int = Field(description="the lost part mission")
    sysid: int = Field(description="its vehicle")
    reason: str | None = Field(description="why it was lost (the part's reason)")
    handed_over: dict[str, list[int]] = Field(description="receiving sysid -> the fleet mission's buoy indices")
    # receiving sysid -> its part's new remaining order, in the part's buoy indices (its own, then the added ones
    # numbered after them): what a new owner uploads to a receiver whose part did not get its new plan
    orders: dict[str, list[int]] = Field(default_factory=dict)
    at: str = Field(description="when it was decided (ISO 8601, UTC)")


class FleetCoordination(BaseModel):
    """A fleet mission's coordinator state as stored (one row per fleet mission once it is followed)."""

    fleet_id: int
    coordinator: str | None = Field(None, description="the service instance following it (last to claim it)")
    separation: SeparationOut = Field(
        default_factory=lambda: SeparationOut(min_horizontal_m=None, min_vertical_m=None, min_distance_m=None)
    )
    reshares: list[Reshare] = Field(default_factory=list)
    updated_at: str | None = None

    def handled(self) -> set[int]:
        """The lost parts whose buoys were re-shared (by whichever instance followed the fleet then)."""
        return {reshare.part_id for reshare in self.reshares}
