"""A mission's lifecycle states, defined once: storage's CHECK constraint, the REST schema (OpenAPI
`components.schemas.MissionStatus`, which the map page reads), the lifecycle and `up --demo` all use these.

planned -> uploading -> uploaded -> flying -> completed | aborted | failed. A StrEnum, so a member is equal to
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
    COMPLETED = "completed"
    ABORTED = "aborted"
    FAILED = "failed"


# Started but not ended: a service that stops leaves these behind, and re-attaches to them at start-up.
UNFINISHED: tuple[MissionStatus, ...] = (MissionStatus.UPLOADING, MissionStatus.UPLOADED, MissionStatus.FLYING)
# Ended: nothing more happens to a mission in one of these.
TERMINAL: tuple[MissionStatus, ...] = (MissionStatus.COMPLETED, MissionStatus.ABORTED, MissionStatus.FAILED)
