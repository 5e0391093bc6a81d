"""A mission's lifecycle states, defined once: storage's CHECK constraint, the REST schema (OpenAPI
`components.schemas.MissionStatus`, which the map page reads), the lifecycle and `up --demo` all use these.

planned -> uploading -> uploaded -> flying -> completed | aborted | failed; a mission of several sorties may wait
in waiting_for_battery between them (flying -> waiting_for_battery -> flying). A StrEnum, so a member is equal to
(and stored, sent and hashed as) its string.
"""

from __future__ import annotations

from enum import StrEnum


class MissionStatus(StrEnum):
    """Where a mission is in its lifecycle: planned -> uploading -> uploaded -> flying -> completed | aborted |
    failed (the last three are terminal; a terminal mission carries a reason unless it completed)."""

    PLANNED = "planned"
    UPLOADING = "uploading"
    UPLOADED = "uploaded"
    FLYING = "flying"
    WAITING_FOR_BATTERY = "waiting_for_battery"  # on the ground between sorties until the operator swaps the pack
    COMPLETED = "completed"
    ABORTED = "aborted"
    FAILED = "failed"


# Started but not ended: a service that stops leaves these behind, and re-attaches to them at start-up.
UNFINISHED: tuple[MissionStatus, ...] = (
    MissionStatus.UPLOADING,
    MissionStatus.UPLOADED,
    MissionStatus.FLYING,
    MissionStatus.WAITING_FOR_BATTERY,
)
# Ended: nothing more happens to a mission in one of these.
TERMINAL: tuple[MissionStatus, ...] = (MissionStatus.COMPLETED, MissionStatus.ABORTED, MissionStatus.FAILED)


class MissionKind(StrEnum):
    """What a mission is: flown by one vehicle, shared by a fleet (flown by its parts, never by a vehicle
    itself), or one vehicle's part of a fleet mission."""

    SINGLE = "single"
    FLEET = "fleet"
    FLEET_PART = "fleet_part"
