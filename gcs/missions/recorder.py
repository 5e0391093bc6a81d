"""The mission recorder: one mission's telemetry samples and progress, taken from the link's messages.

A link listener: it sees every message the vehicle sends while the mission flies. It samples the vehicle's
state at most every `period_s` of the vehicle's (simulated) time, collects the items the vehicle reached and
sequenced past (the mission's progress: buoys visited and when), and the vehicle's own events (STATUSTEXTs and
mode changes), which name a failsafe when the vehicle ends a mission early.

A mission of several sorties is recorded sortie by sortie (`begin_sortie`): the items the vehicle reports are
those of the sortie on board, so seq -> buoy goes through that sortie's plan; the buoys visited, the samples
(tagged with their sortie) and the events run on across sorties. Each sortie's battery figures (the energy the
vehicle reports consumed from take-off to after landing, the charge left, the worst battery state it reported)
are kept for the report of predicted against used energy.

What counts as visited is what this mission's vehicle did, not what its messages claim: a buoy is visited when,
after this mission's (sortie's) upload was acknowledged (`mission_uploaded`), the vehicle reported itself armed,
airborne and within the buoy's acceptance radius (its GLOBAL_POSITION_INT, and the straight line between two
reports less than a second apart: the path between them at 10 Hz). MISSION_ITEM_REACHED and MISSION_CURRENT
count only after that acknowledgement: the first MISSION_CURRENTs a vehicle sends after a new upload may still
carry the previous mission's sequence number, which must neither mark buoys nor pick the leg a cross-track error
is measured on. Lost progress messages (any radio loses some) then cost nothing: the positions show the visits,
and `at_depot` shows the way home. One exception: a sortie re-attached after the service restarted flew partly
unwatched, and there the vehicle's own sequencing (its items on board, compared with the plan's by the
lifecycle) is the only evidence, so for that sortie an item reached or sequenced past also counts as visited.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime
from typing import Any

import numpy as np

from gcs.domain import tracking_metrics
from gcs.domain.planning import FIRST_BUOY_SEQ, MissionLayout, Plan, buoy_of_seq
from gcs.domain.records import MissionProgress, SortieFlown
from gcs.domain.schemas import (
    SEVERITIES,
    TELEMETRY_FROM_STATUS,
    OperatorCommand,
    PreflightCheck,
    TelemetrySample,
    VehicleEvent,
)
from gcs.vehicle.link import LinkManager
from uavcore.mavlink import statustext

VEHICLE_EVENTS_KEPT = 50  # STATUSTEXTs and mode changes kept in a mission's progress
# MAV_BATTERY_CHARGE_STATE by value, as the mission's battery figures name them
CHARGE_STATES = {2: "low", 3: "critical", 4: "emergency", 5: "failed", 6: "unhealthy"}
CHARGE_STATE_CRITICAL = 3
AIRBORNE_M = 0.5  # above home: a position report below it is the vehicle on the ground, visiting nothing
PATH_GAP_S = 1.0  # two position reports closer in time than this: the vehicle flew the line between them
# How far from the depot a vehicle may land after its return and still be home: the return's acceptance radius
# plus the drift of a landing in wind (PX4's and the simulator's land straight down from where they arrived).
LANDING_DRIFT_M = 1.5


class MissionRecorder:
    """Samples the vehicle's status at most every `period_s` of simulated time, and collects progress."""

    def __init__(self, link: LinkManager, plan: Plan, period_s: float, acceptance_radius_m: float) -> None:
        self.link, self.mission_plan, self.period_ms = link, plan, period_s * 1000.0
        self.acceptance_radius_m = acceptance_radius_m
        self.sortie = 0
        self.plan = plan.sortie_plan(0)  # the sortie on board
        self.layout = MissionLayout(len(self.plan.order))  # where its buoys' items are (set at each upload)
        self.camera: str | None = None  # the camera the sortie inspects with (None: the buoys are only visited)
        self.visited: set[int] = set()  # buoy indices the vehicle was seen within the acceptance radius of
        self.uploaded = False  # this sortie's items are acknowledged on board: its progress messages count
        self.current_seq: int | None = None  # this sortie's current item, from MISSION_CURRENT after the upload
        self.last_fix: tuple[float, float, float] | None = None  # (vehicle s, east, north) of the last position
        self.unwatched = False  # a sortie re-attached after a restart: its sequencing counts as visits too
        self.sorties_flown: list[SortieFlown] = []  # each flown sortie's battery figures
        self.consumed_at_start: float | None = None
        self.worst_charge_state = 0
        self.armed_seen = False  # the vehicle reported itself armed while this recorder listened
        self.samples: list[dict[str, Any]] = []
        self.last_ms: float | None = None
        self.reached_seqs: list[int] = []
        self.reached_at: dict[int, float] = {}  # buoy index -> vehicle time
        self.reached_wall_at: dict[int, float] = {}  # buoy index -> unix time the service heard it (MissionProgress)
        self.latest: dict[str, Any] | None = None
        self.route = self.plan.route_local()
        self.vehicle_events: list[VehicleEvent] = []  # the vehicle's STATUSTEXTs and mode changes
        self.preflight_checks: list[
            PreflightCheck
        ] = []  # each sortie's pre-flight charge check (gcs.missions.lifecycle)
        self.custom_mode: int | None = None
        self.sample_due = False
        self.command: OperatorCommand | None = None  # the operator's command in force (gcs.missions.lifecycle)

    def restore(self, progress: MissionProgress) -> None:
        """Continue from the progress a previous run of the service stored (re-attaching after a restart)."""
        self._on_board(progress.sortie or 0)
        self.visited = set(progress.visited_buoys)
        self.uploaded = True  # a re-attached sortie is the one on board (the lifecycle compared it item by item)
        self.unwatched = True
        self.sorties_flown = list(progress.sorties_flown)
        self.consumed_at_start = progress.consumed_at_start
        self.reached_seqs = list(progress.reached_seqs)
        self.reached_at = dict(progress.reached_at)
        self.reached_wall_at = dict(progress.reached_wall_at)
        # the current item is not restored: the vehicle flew on unwatched, and its next MISSION_CURRENT says where
        self.vehicle_events = list(progress.vehicle_events)
        self.preflight_checks = list(progress.preflight)
        self.camera = progress.camera
        self.layout = MissionLayout(len(self.plan.order), progress.capture)
        self.command = progress.command  # a vehicle held (or returning) before the restart still is

    def _on_board(self, sortie: int) -> None:
        self.sortie, self.plan = sortie, self.mission_plan.sortie_plan(sortie)
        self.route = self.plan.route_local()

    def begin_sortie(self, sortie: int) -> None:
        """The vehicle is to fly `sortie` next: its progress messages count once `mission_uploaded` says so."""
        self._on_board(sortie)
        self.uploaded, self.current_seq, self.reached_seqs, self.unwatched = False, None, [], False

    def replan(self, plan: Plan) -> None:
        """The vehicle now flies `plan` (one tour), uploaded in flight: the same buoys first, in the same indices,
        then more (a fleet's re-share); what was visited stays visited."""
        self.mission_plan = plan
        self.begin_sortie(self.sortie)

    def mission_uploaded(self, camera: str | None = None) -> None:
        """The vehicle acknowledged the upload of the sortie on board: from now on its MISSION_CURRENT and
        MISSION_ITEM_REACHED are this sortie's. `camera`: the items inspect each buoy with this camera."""
        self.uploaded, self.current_seq, self.reached_seqs = True, None, []
        self.camera, self.layout = camera, MissionLayout(len(self.plan.order), camera is not None)

    def preflight(self, check: PreflightCheck) -> None:
        """The pre-flight charge check of the sortie about to fly: kept with the mission's progress."""
        self.preflight_checks = [*(c for c in self.preflight_checks if c.sortie != check.sortie), check]

    def sortie_took_off(self) -> None:
        """Before arming for the sortie: what the battery has delivered so far (the swap zeroes it)."""
        self.consumed_at_start = self.link.status.battery_consumed_wh
        self.worst_charge_state = 0

    def sortie_landed(self) -> None:
        """After the landing: the sortie's battery figures, from the vehicle's latest BATTERY_STATUS."""
        s = self.link.status
        used = None
        if s.battery_consumed_wh is not None and self.consumed_at_start is not None:
            used = s.battery_consumed_wh - self.consumed_at_start
        self.sorties_flown = [
            *(entry for entry in self.sorties_flown if entry.sortie != self.sortie),
            SortieFlown(
                sortie=self.sortie,
                used_energy_wh=used,
                landing_charge_pct=s.battery_remaining_pct,
                battery_warning=CHARGE_STATES.get(self.worst_charge_state),
            ),
        ]

    @property
    def battery_failsafe(self) -> bool:
        """The vehicle reported its battery critical (or worse) in this sortie: the level of PX4's and
        ArduPilot's battery failsafes (return or land)."""
        return self.worst_charge_state >= CHARGE_STATE_CRITICAL

    def visited_buoys(self) -> set[int]:
        """Buoy indices visited so far, every sortie included."""
        return set(self.visited)

    def sortie_visited(self) -> bool:
        """Every buoy of the sortie on board was visited."""
        return self.visited.issuperset(self.plan.order)

    def at_depot(self) -> bool:
        """The vehicle's last position is the depot's, within the acceptance radius and a landing's drift."""
        if self.last_fix is None:
            return False
        return bool(np.hypot(self.last_fix[1], self.last_fix[2]) <= self.acceptance_radius_m + LANDING_DRIFT_M)

    def _position(self, t_s: float) -> None:
        """A position report: the sortie's buoys within the acceptance radius of it, or of the line from the last
        report when they are less than PATH_GAP_S apart, are visited (armed and airborne, this sortie on board)."""
        s = self.link.status
        if s.lat is None or s.lon is None:
            return
        east, north = (float(v) for v in self.plan.frame.project(np.array([[s.lat, s.lon]]))[0])
        previous, self.last_fix = self.last_fix, (t_s, east, north)
        if not (self.uploaded and s.armed and (s.alt_m or 0.0) > AIRBORNE_M):
            return
        start = (east, north) if previous is None or not 0.0 <= t_s - previous[0] <= PATH_GAP_S else previous[1:]
        todo = [b for b in self.plan.order if b not in self.visited]
        if not todo:
            return
        buoys = np.asarray(self.plan.buoys_local, dtype=float).reshape(-1, 2)[todo]
        for buoy, point in zip(todo, buoys, strict=True):
            distance = tracking_metrics.distance_to_segment(point, np.array(start), np.array([east, north]))[0]
            if distance <= self.acceptance_radius_m:
                self.visited.add(buoy)

    def not_inspected(self) -> list[str]:
        """The ids of the mission's buoys not visited (so far), in the planned order."""
        visited = self.visited_buoys()
        return [self.mission_plan.buoy_ids[b] for b in self.mission_plan.order if b not in visited]

    def resume_point(self) -> tuple[int, int | None]:
        """Where a resumed mission flies on from: the first item of the sortie's first buoy (in its visiting order)
        not visited yet (an inspection's whole group, so its burst is taken again), and that buoy; after the last
        buoy, the first item of the way home, and None."""
        order = self.plan.order
        position = next((p for p, buoy in enumerate(order) if buoy not in self.visited), len(order))
        return self.layout.group_start(position), order[position] if position < len(order) else None

    def operator(self, command: str) -> None:
        """An operator's command, among the vehicle's events: stored with the mission and shown in its report."""
        self._event(f"operator: {command}")

    def _event(self, text: str, severity: int | None = None) -> None:
        t_ms = self.link.status.time_boot_ms
        level = SEVERITIES[severity] if severity is not None and 0 <= severity < len(SEVERITIES) else None
        event = VehicleEvent(
            t_s=None if t_ms is None else t_ms / 1000.0, text=text, at=datetime.now(UTC), severity=level
        )
        self.vehicle_events = [*self.vehicle_events, event]
        self.vehicle_events = self.vehicle_events[-VEHICLE_EVENTS_KEPT:]

    def __call__(self, message: Any) -> None:
        kind = message.get_type()
        status = self.link.status
        from_autopilot = message.get_srcComponent() == status.compid
        if kind == "HEARTBEAT" and from_autopilot and status.armed:
            self.armed_seen = True  # this mission flew (or tried to): the vehicle's newest log is its
        if kind == "STATUSTEXT" and from_autopilot:
            self._event(statustext(message), message.severity)
        elif kind == "HEARTBEAT" and from_autopilot and message.custom_mode != self.custom_mode:
            if self.custom_mode is not None:
                names = self.link.autopilot.mode_name
                self._event(f"mode {names(self.custom_mode)} -> {names(message.custom_mode)}")
            self.custom_mode = message.custom_mode
        elif kind == "MISSION_ITEM_REACHED" and from_autopilot and self.uploaded:
            seq = self.link.autopilot.planned_seq(message.seq)
            if seq not in self.reached_seqs:
                self.reached_seqs.append(seq)
            buoy = buoy_of_seq(seq, self.plan, self.layout)
            if buoy is not None and status.time_boot_ms is not None:
                self.reached_at.setdefault(buoy, status.time_boot_ms / 1000.0)
            if buoy is not None:
                self.reached_wall_at.setdefault(buoy, time.time())
            if buoy is not None and self.unwatched:
                self.visited.add(buoy)
        elif kind == "BATTERY_STATUS" and from_autopilot and message.id == 0:
            self.worst_charge_state = max(self.worst_charge_state, message.charge_state)
        elif kind == "MISSION_CURRENT" and from_autopilot and self.uploaded:
            self.current_seq = self.link.autopilot.planned_seq(message.seq)
            if self.unwatched:
                passed = range(FIRST_BUOY_SEQ, self.current_seq + (1 if status.mission_complete else 0))
                self.visited |= {b for seq in passed if (b := buoy_of_seq(seq, self.plan, self.layout)) is not None}
        elif kind == "GLOBAL_POSITION_INT" and from_autopilot:
            self._position(message.time_boot_ms / 1000.0)
        elif kind == "LOCAL_POSITION_NED" and from_autopilot:
            now_ms = message.time_boot_ms
            if self.last_ms is None or now_ms - self.last_ms >= self.period_ms or now_ms < self.last_ms:
                self.last_ms = now_ms
                self.sample_due = True  # taken at the end of the chunk, with what else it brought of this instant

    def end_of_chunk(self) -> None:
        if self.sample_due:
            self.sample_due = False
            self.latest = self.sample()
            self.samples.append(self.latest)

    def sample(self) -> dict[str, Any]:
        """The vehicle's state now, as a TelemetrySample document."""
        s = self.link.status
        status = {name: getattr(s, name) for name in TELEMETRY_FROM_STATUS}
        status["mission_seq"] = self.current_seq  # this sortie's, never a previous mission's the link still holds
        sample = TelemetrySample(
            t_s=(s.time_boot_ms or 0) / 1000.0,
            eso=dict(s.estimates) or None,
            cross_track_m=self._cross_track(),
            sortie=self.sortie,
            **status,
        )
        return sample.model_dump()

    def _cross_track(self) -> float | None:
        s = self.link.status
        leg = self.layout.leg_of_seq(self.current_seq)
        if leg is None or s.lat is None:
            return None
        east, north = self.plan.frame.project(np.array([[s.lat, s.lon]]))[0]
        return tracking_metrics.cross_track_m(float(east), float(north), self.route, leg)

    def progress(self) -> MissionProgress:
        s = self.link.status
        visited = self.visited_buoys()
        return MissionProgress(
            current_seq=self.current_seq,
            total=s.mission_total if self.uploaded else None,
            mission_state=s.mission_state if self.uploaded else None,
            reached_seqs=list(self.reached_seqs),
            visited=len(visited),
            buoys=len(self.mission_plan.buoy_ids),
            reached_at=dict(self.reached_at),
            reached_wall_at=dict(self.reached_wall_at),
            vehicle_events=list(self.vehicle_events),
            sortie=self.sortie,
            sorties=len(self.mission_plan.sortie_orders()),
            visited_buoys=sorted(visited),
            sorties_flown=list(self.sorties_flown),
            consumed_at_start=self.consumed_at_start,
            preflight=list(self.preflight_checks),
            camera=self.camera,
            capture=self.layout.inspected,
            command=self.command,
        )

    def take(self) -> list[dict[str, Any]]:
        samples, self.samples = self.samples, []
        return samples
