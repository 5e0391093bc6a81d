"""Mission lifecycle: plan -> upload -> arm -> start -> monitor, persisted at every transition.

States: planned -> uploading -> uploaded -> flying -> completed | aborted | failed (with a reason). Every way a
flight can go wrong ends in a terminal state, never a hang: no vehicle within `vehicle_wait_s` ("no vehicle"),
a refused upload, arm or mode change, a lost link (no heartbeat for `heartbeat_timeout_s`), a vehicle reboot,
a disarm before the end (named after the vehicle's failsafe when it reported one, e.g. "Failsafe: offboard
setpoints lost, AUTO.RTL", with the mode change), or a flight longer than planned plus a margin (simulated
time).

A mission left unfinished by a previous run of the service is re-attached at start-up when the vehicle is still
flying it (the same waypoints on board, downloaded and compared, and armed): recording and monitoring go on
where they stopped, and the mission ends as it would have. A vehicle that finished it meanwhile (mission
complete, landed, disarmed) completes it; anything else fails it with reason RESTART_NOT_FLYING.

Completed means: the vehicle reported the mission complete (MISSION_CURRENT.mission_state COMPLETE, or the
last item reached), and it is on the ground (EXTENDED_SYS_STATE) and disarmed (HEARTBEAT base_mode).

When no vehicle answers, POST /missions with start=true still answers 201 (status planned); the background
lifecycle then ends in `failed` with reason "no vehicle" after `vehicle_wait_s`. Clients poll
GET /missions/{id} or watch /ws.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from dataclasses import asdict
from typing import Any

import numpy as np

from gcs import tracking
from gcs.link import (
    ARMED_FLAG,
    AUTOPILOT_COMPID,
    ON_GROUND,
    CommandTimeoutError,
    LinkManager,
    mavlink,
)
from gcs.mission_protocol import MissionTransferError, download_mission, upload_mission
from gcs.planning import FIRST_BUOY_SEQ, FlightParams, Plan, buoy_of_seq, leg_of_seq, make_plan, mission_items
from gcs.schemas import MissionRequest, PlanRequest
from gcs.settings import Settings
from gcs.storage import UNFINISHED, MissionRecord, Storage
from gcs.validation import validate_request, validate_route_length
from uavcore.mavlink import result_name, statustext
from uavcore.modes import px4_mode_name

log = logging.getLogger(__name__)

MISSION_STATE_COMPLETE = 5  # MISSION_STATE enum (MISSION_CURRENT.mission_state)
FLUSH_PERIOD_S = 0.5  # wall clock between telemetry writes and checks
DISARM_GRACE_S = 3.0  # wall clock a flying mission may be disarmed (before takeoff) before it counts as ended
CLIMB_RATE_M_S = 1.0  # for the flight-time budget only
ABORTED_BEFORE_TAKEOFF = "aborted by the operator before takeoff"
RESTART_NOT_FLYING = "GCS restarted; vehicle no longer flying this mission"
REATTACHED = "GCS restarted; re-attached to the vehicle flying this mission"
VEHICLE_EVENTS_KEPT = 50  # STATUSTEXTs and mode changes kept in a mission's progress
MISSION_CURRENT_WAIT_S = 3.0  # wall clock a re-attaching service waits for the vehicle's MISSION_CURRENT
ARMED_CONFIRM_S = 2.0  # wall clock to see an "already armed" vehicle's heartbeat say armed


class MissionNotFoundError(KeyError):
    pass


class MissionConflictError(RuntimeError):
    """Another mission is using the vehicle, or the mission is not in a state that allows the request."""


class MissionEndError(Exception):
    """Raised inside the lifecycle to finish with a terminal status and a reason."""

    def __init__(self, status: str, reason: str | None) -> None:
        super().__init__(reason)
        self.status, self.reason = status, reason


def flight_budget_s(plan: Plan, flight: FlightParams, margin_s: float) -> float:
    """Simulated seconds a mission may take before it is declared failed."""
    cruise = plan.length_m / flight.speed_m_s
    return cruise + len(plan.order) * flight.dwell_s + 2 * flight.altitude_m / CLIMB_RATE_M_S + margin_s


class Recorder:
    """Samples the vehicle's status at most every `period_s` of simulated time, and collects progress."""

    def __init__(self, link: LinkManager, plan: Plan, period_s: float) -> None:
        self.link, self.plan, self.period_ms = link, plan, period_s * 1000.0
        self.samples: list[dict[str, Any]] = []
        self.last_ms: float | None = None
        self.reached_seqs: list[int] = []
        self.reached_at: dict[int, float] = {}  # buoy index -> vehicle time
        self.highest_seq = -1  # the vehicle moved past every item below this one
        self.latest: dict[str, Any] | None = None
        self.route = plan.route_local()
        self.vehicle_events: list[dict[str, Any]] = []  # {t_s, text}: the vehicle's STATUSTEXTs, mode changes
        self.custom_mode: int | None = None
        self.sample_due = False

    def restore(self, progress: dict[str, Any]) -> None:
        """Continue from the progress a previous run of the service stored (re-attaching after a restart)."""
        self.reached_seqs = list(progress.get("reached_seqs") or [])
        self.reached_at = {int(k): float(v) for k, v in (progress.get("reached_at") or {}).items()}
        current = progress.get("current_seq")
        self.highest_seq = -1 if current is None else int(current)
        self.vehicle_events = list(progress.get("vehicle_events") or [])

    def _event(self, text: str) -> None:
        t_ms = self.link.status.time_boot_ms
        self.vehicle_events = [*self.vehicle_events, {"t_s": None if t_ms is None else t_ms / 1000.0, "text": text}]
        self.vehicle_events = self.vehicle_events[-VEHICLE_EVENTS_KEPT:]

    def __call__(self, message: Any) -> None:
        kind = message.get_type()
        status = self.link.status
        from_autopilot = message.get_srcComponent() == AUTOPILOT_COMPID
        if kind == "STATUSTEXT" and from_autopilot:
            self._event(statustext(message))
        elif kind == "HEARTBEAT" and from_autopilot and message.custom_mode != self.custom_mode:
            if self.custom_mode is not None:
                self._event(f"mode {px4_mode_name(self.custom_mode)} -> {px4_mode_name(message.custom_mode)}")
            self.custom_mode = message.custom_mode
        elif kind == "MISSION_ITEM_REACHED" and message.get_srcComponent() == AUTOPILOT_COMPID:
            if message.seq not in self.reached_seqs:
                self.reached_seqs.append(message.seq)
            buoy = buoy_of_seq(message.seq, self.plan)
            if buoy is not None and status.time_boot_ms is not None:
                self.reached_at.setdefault(buoy, status.time_boot_ms / 1000.0)
        elif kind == "MISSION_CURRENT" and message.get_srcComponent() == AUTOPILOT_COMPID:
            self.highest_seq = max(self.highest_seq, message.seq)
        elif kind == "LOCAL_POSITION_NED" and message.get_srcComponent() == AUTOPILOT_COMPID:
            now_ms = message.time_boot_ms
            if self.last_ms is None or now_ms - self.last_ms >= self.period_ms or now_ms < self.last_ms:
                self.last_ms = now_ms
                self.sample_due = True  # taken at the end of the datagram, with the rest of this tick

    def end_of_datagram(self) -> None:
        if self.sample_due:
            self.sample_due = False
            self.latest = self.sample()
            self.samples.append(self.latest)

    def sample(self) -> dict[str, Any]:
        s = self.link.status
        fields = (
            "lat",
            "lon",
            "alt_m",
            "north",
            "east",
            "down",
            "vn",
            "ve",
            "vd",
            "roll",
            "pitch",
            "yaw",
            "ref_north",
            "ref_east",
            "ref_down",
            "ref_yaw",
            "landed_state",
        )
        data: dict[str, Any] = {name: getattr(s, name) for name in fields}
        data["t_s"] = (s.time_boot_ms or 0) / 1000.0
        data["mission_seq"] = s.mission_seq
        data["armed"] = s.armed
        data["eso"] = dict(s.estimates) or None
        data["cross_track_m"] = self._cross_track(s)
        return data

    def _cross_track(self, s) -> float | None:
        leg = leg_of_seq(s.mission_seq, len(self.plan.order))
        if leg is None or s.lat is None:
            return None
        east, north = self.plan.frame.project(np.array([[s.lat, s.lon]]))[0]
        return tracking.cross_track_m(float(east), float(north), self.route, leg)

    def progress(self) -> dict[str, Any]:
        s = self.link.status
        # a buoy counts as visited when the vehicle reported it reached or sequenced past it (a lost
        # MISSION_ITEM_REACHED datagram must not leave a buoy unvisited)
        done = set(self.reached_seqs) | set(range(FIRST_BUOY_SEQ, self.highest_seq))
        visited = sum(1 for seq in done if buoy_of_seq(seq, self.plan) is not None)
        return {
            "current_seq": s.mission_seq,
            "total": s.mission_total,
            "mission_state": s.mission_state,
            "reached_seqs": list(self.reached_seqs),
            "visited": visited,
            "buoys": len(self.plan.order),
            "reached_at": {str(k): v for k, v in self.reached_at.items()},
            "vehicle_events": list(self.vehicle_events),
        }

    def take(self) -> list[dict[str, Any]]:
        samples, self.samples = self.samples, []
        return samples


def ended_early_reason(events: list[dict[str, Any]], visited: int, buoys: int) -> str:
    """Why a mission ended with the vehicle disarmed before completing it: its failsafe, when it reported one
    (the last "Failsafe..." STATUSTEXT and the mode change that followed it), else the plain fact."""
    texts = [event["text"] for event in events]
    failsafes = [i for i, text in enumerate(texts) if text.lower().startswith("failsafe")]
    count = f"{visited} of {buoys} buoys visited"
    if not failsafes:
        return f"the vehicle disarmed before completing the mission ({count})"
    first = failsafes[-1]
    modes = [text for text in texts[first:] if text.startswith("mode ")]
    mode = f"; {modes[0]}" if modes else ""
    return f"vehicle failsafe: {texts[first]}{mode}; landed and disarmed with {count}"


def _airborne(sample: dict[str, Any]) -> bool:
    landed = sample.get("landed_state")
    if landed is not None and landed != mavlink.MAV_LANDED_STATE_UNDEFINED:
        return landed != ON_GROUND
    return (sample.get("alt_m") or 0.0) > 0.5


def flight_results(plan: Plan, flight: FlightParams, samples: list[dict[str, Any]], progress: dict[str, Any]) -> dict:
    """Tracking and per-buoy figures of a recorded flight (pure given its inputs)."""
    located = [s for s in samples if s.get("lat") is not None]
    en = plan.frame.project(np.array([[s["lat"], s["lon"]] for s in located]).reshape(-1, 2))
    track = [
        tracking.TrackPoint(
            t_s=s["t_s"],
            east=float(e),
            north=float(n),
            airborne=_airborne(s),
            leg=leg_of_seq(s.get("mission_seq"), len(plan.order)),
        )
        for s, (e, n) in zip(located, en, strict=True)
    ]
    reached_at = {int(k): float(v) for k, v in (progress.get("reached_at") or {}).items()}
    buoys = tracking.buoy_figures(
        np.asarray(plan.buoys_local), [flight.acceptance_radius_m] * len(plan.buoys_local), track, reached_at
    )
    for result in buoys:
        result["id"] = plan.buoy_ids[result["index"]]
    return {"tracking": tracking.tracking_figures(plan.route_local(), plan.length_m, track), "buoys": buoys}


class MissionService:
    """Plans, stores and flies missions over one LinkManager."""

    def __init__(self, settings: Settings, storage: Storage, link: LinkManager) -> None:
        self.settings, self.storage, self.link = settings, storage, link
        self._tasks: dict[int, asyncio.Task] = {}
        self._abort_requested: set[int] = set()
        self.recorders: dict[int, Recorder] = {}
        self._statuses: dict[int, str] = {}  # last status of missions run here, for the live view

    async def start(self) -> None:
        unfinished = self.storage.unfinished_missions()
        await self.link.start()
        # the vehicle flies one mission at a time: only the latest unfinished one can still be in the air
        for mission_id in unfinished[:-1]:
            self._transition(mission_id, "failed", RESTART_NOT_FLYING)
        if unfinished:
            mission_id = unfinished[-1]
            log.warning("mission %s was unfinished at start-up: re-attaching if the vehicle still flies it", mission_id)
            self._tasks[mission_id] = asyncio.create_task(
                self._run(mission_id, resume=True), name=f"mission-{mission_id}"
            )

    async def stop(self) -> None:
        for task in list(self._tasks.values()):
            task.cancel()
        for task in list(self._tasks.values()):
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await self.link.stop()

    # ----- planning
    def default_depot(self) -> tuple[float, float]:
        home = self.link.status.home or self.settings.home
        return home[0], home[1]

    def plan(self, request: PlanRequest) -> tuple[Plan, FlightParams]:
        """Validate and plan (CPU-bound: call it from a worker thread). Raises RequestInvalidError or InputError."""
        depot = (request.depot.lat, request.depot.lon) if request.depot else self.default_depot()
        validate_request(request, depot, self.settings.limits)
        ids = [b.id or f"B{i + 1}" for i, b in enumerate(request.buoys)]
        plan = make_plan(
            depot,
            [(b.lat, b.lon) for b in request.buoys],
            ids,
            request.planner.method,
            request.planner.seed,
            request.planner.time_limit_s,
        )
        validate_route_length(plan.length_m, self.settings.limits)
        flight = FlightParams(request.altitude_m, request.speed_m_s, request.dwell_s, request.acceptance_radius_m)
        return plan, flight

    def active_mission(self) -> int | None:
        for mission_id, task in self._tasks.items():
            if not task.done():
                return mission_id
        return None

    async def create(self, request: MissionRequest) -> int:
        if request.start and (active := self.active_mission()) is not None:
            raise MissionConflictError(f"mission {active} is using the vehicle; abort it or wait for it to end")
        plan, flight = await asyncio.to_thread(self.plan, request)
        mission_id = self.storage.create_mission(asdict(flight), plan.to_dict())
        if request.start:
            try:
                self.launch(mission_id)
            except MissionConflictError as error:  # another mission started while this one was planned
                raise MissionConflictError(
                    f"{error}; mission {mission_id} is stored as planned: POST /missions/{mission_id}/start later"
                ) from None
        return mission_id

    def launch(self, mission_id: int) -> None:
        if (active := self.active_mission()) is not None:
            raise MissionConflictError(f"mission {active} is using the vehicle; abort it or wait for it to end")
        record = self.get(mission_id)
        if record.status != "planned":
            raise MissionConflictError(f"mission {mission_id} is {record.status}; only a planned mission can start")
        self._tasks[mission_id] = asyncio.create_task(self._run(mission_id), name=f"mission-{mission_id}")

    def get(self, mission_id: int) -> MissionRecord:
        record = self.storage.get_mission(mission_id)
        if record is None:
            raise MissionNotFoundError(mission_id)
        return record

    async def abort(self, mission_id: int) -> None:
        """Return to the depot. A mission not yet flying ends at once; a flying one ends when it has landed."""
        record = self.get(mission_id)
        if record.status not in ("planned", *UNFINISHED):
            raise MissionConflictError(f"mission {mission_id} is {record.status}; nothing to abort")
        task = self._tasks.get(mission_id)
        if record.status == "flying" and task is not None and not task.done():
            self._abort_requested.add(mission_id)
            return
        if task is not None and not task.done():
            self._abort_requested.add(mission_id)  # _run ends it as aborted
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        else:
            self._transition(mission_id, "aborted", ABORTED_BEFORE_TAKEOFF)

    # ----- the lifecycle
    async def _run(self, mission_id: int, resume: bool = False) -> None:
        record = self.get(mission_id)
        plan, flight = Plan.from_dict(record.plan), FlightParams(**record.flight)
        recorder = Recorder(self.link, plan, self.settings.telemetry_period_s)
        status, reason = "failed", "internal error"
        try:
            if resume:
                recorder.restore(record.progress)
                await self._resume(mission_id, plan, flight, recorder)
            else:
                await self._fly(mission_id, plan, flight, recorder)
        except MissionEndError as ended:
            status, reason = ended.status, ended.reason
        except MissionTransferError as error:
            reason = str(error)
        except CommandTimeoutError as error:
            reason = f"the vehicle stopped answering: {error}"
        except asyncio.CancelledError:
            status, reason = "failed", "the service stopped during the mission"
            if mission_id in self._abort_requested:
                status, reason = "aborted", ABORTED_BEFORE_TAKEOFF
            self._finish(mission_id, plan, flight, recorder, status, reason)
            raise
        except Exception as error:  # never leave a mission hanging in a non-terminal state
            log.exception("mission %s failed", mission_id)
            reason = f"internal error: {type(error).__name__}: {error}"
        self._finish(mission_id, plan, flight, recorder, status, reason)

    def _finish(
        self, mission_id: int, plan: Plan, flight: FlightParams, recorder: Recorder, status: str, reason: str | None
    ) -> None:
        self.link.remove_listener(recorder, recorder.end_of_datagram)
        self.recorders.pop(mission_id, None)
        self._abort_requested.discard(mission_id)
        self.storage.add_telemetry(mission_id, recorder.take())
        progress = recorder.progress()
        self.storage.set_progress(mission_id, progress)
        samples = self.storage.telemetry(mission_id)
        if samples:
            self.storage.set_results(mission_id, flight_results(plan, flight, samples, progress))
        self._transition(mission_id, status, reason)

    def _transition(self, mission_id: int, status: str, reason: str | None = None) -> None:
        self.storage.set_status(mission_id, status, reason)
        self._statuses[mission_id] = status

    async def _command(self, command: int, params: list[float], what: str) -> None:
        result = await self.link.command_long(command, params)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise MissionEndError("failed", f"the vehicle refused to {what} ({result_name('MAV_RESULT', result)})")

    async def _arm(self) -> None:
        """ARM, surviving a lost acknowledgement: the link resends a command whose ACK was lost, and the vehicle
        answers an ARM while armed with TEMPORARILY_REJECTED. If its heartbeat then says armed, the first ARM
        did arrive and the mission goes on."""
        result = await self.link.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1])
        if result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED:
            deadline = time.monotonic() + ARMED_CONFIRM_S
            while time.monotonic() < deadline and not self.link.status.armed:
                await asyncio.sleep(0.05)
            if self.link.status.armed:
                return
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise MissionEndError("failed", f"the vehicle refused to arm ({result_name('MAV_RESULT', result)})")

    async def _fly(self, mission_id: int, plan: Plan, flight: FlightParams, recorder: Recorder) -> None:
        if not await self.link.wait_connected(self.settings.vehicle_wait_s):
            raise MissionEndError("failed", "no vehicle")
        boot = self.link.status.reboots
        self._transition(mission_id, "uploading")
        home = self.link.status.home
        items = mission_items(plan, flight, None if home is None else (home[0], home[1]))
        await upload_mission(self.link, items)
        self._transition(mission_id, "uploaded")
        self.link.add_listener(recorder, recorder.end_of_datagram)
        self.recorders[mission_id] = recorder
        await self._arm()
        # AUTO.MISSION as MAVSDK's start_mission does: DO_SET_MODE(custom | armed, main 4, sub 4)
        mode_flags = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | ARMED_FLAG
        result = await self.link.command_long(mavlink.MAV_CMD_DO_SET_MODE, [mode_flags, 4, 4])
        if result != mavlink.MAV_RESULT_ACCEPTED:
            await self._command(mavlink.MAV_CMD_MISSION_START, [0, len(items) - 1], "start the mission")
        self._transition(mission_id, "flying")
        await self._monitor(mission_id, plan, flight, recorder, boot, len(items))

    async def _resume(self, mission_id: int, plan: Plan, flight: FlightParams, recorder: Recorder) -> None:
        """Re-attach to a mission a previous run of the service left unfinished, or end it (see the module doc)."""
        if not await self.link.wait_connected(self.settings.vehicle_wait_s):
            raise MissionEndError("failed", f"{RESTART_NOT_FLYING} (no vehicle)")
        s = self.link.status
        deadline = time.monotonic() + MISSION_CURRENT_WAIT_S
        while s.mission_total is None and time.monotonic() < deadline:
            await asyncio.sleep(0.1)
        home = s.home
        expected = mission_items(plan, flight, None if home is None else (home[0], home[1]))
        on_board = await download_mission(self.link)
        same = len(on_board) == len(expected) and all(
            (a.command, a.x, a.y) == (b.command, b.x, b.y) for a, b in zip(on_board, expected, strict=True)
        )
        if not same:
            raise MissionEndError("failed", f"{RESTART_NOT_FLYING} (another mission is on board)")
        self.link.add_listener(recorder, recorder.end_of_datagram)
        self.recorders[mission_id] = recorder
        if not s.armed:
            finished = s.mission_state == MISSION_STATE_COMPLETE and s.landed_state == ON_GROUND
            raise MissionEndError("completed", None) if finished else MissionEndError("failed", RESTART_NOT_FLYING)
        self._transition(mission_id, "flying", REATTACHED)
        await self._monitor(mission_id, plan, flight, recorder, s.reboots, len(expected))

    async def _monitor(
        self, mission_id: int, plan: Plan, flight: FlightParams, recorder: Recorder, boot: int, n_items: int
    ) -> None:
        s = self.link.status
        budget_s = flight_budget_s(plan, flight, self.settings.mission_timeout_margin_s)
        start_s = (s.time_boot_ms or 0) / 1000.0
        disarmed_since: float | None = None
        aborting = False
        last_progress: dict[str, Any] | None = None
        while True:
            await asyncio.sleep(FLUSH_PERIOD_S)
            self.storage.add_telemetry(mission_id, recorder.take())
            progress = recorder.progress()
            if progress != last_progress:
                self.storage.set_progress(mission_id, progress)
                last_progress = progress
            if s.reboots != boot:
                raise MissionEndError("failed", "the vehicle rebooted during the mission")
            if not s.connected:
                raise MissionEndError("failed", "link lost: no heartbeat from the vehicle")
            if mission_id in self._abort_requested and not aborting:
                aborting = True
                await self._command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, [], "return to launch")
                self._transition(mission_id, "aborted", "aborted by the operator: returning to the depot")
            on_ground_disarmed = not s.armed and s.landed_state == ON_GROUND
            finished = s.mission_state == MISSION_STATE_COMPLETE or (n_items - 1) in recorder.reached_seqs
            if on_ground_disarmed and aborting:
                raise MissionEndError("aborted", "aborted by the operator: returned to the depot")
            if on_ground_disarmed and finished:
                raise MissionEndError("completed", None)
            if not s.armed:
                disarmed_since = disarmed_since or time.monotonic()
                if time.monotonic() - disarmed_since > DISARM_GRACE_S:
                    reason = ended_early_reason(recorder.vehicle_events, progress["visited"], len(plan.order))
                    raise MissionEndError("failed", reason)
            else:
                disarmed_since = None
            elapsed = (s.time_boot_ms or 0) / 1000.0 - start_s
            # a vehicle already down and disarmed is not overrunning: the disarm check above ends the mission
            # (a lockstep vehicle with no controller runs free, so the wall-clock grace is many simulated seconds)
            if elapsed > budget_s and not aborting and s.armed:
                with contextlib.suppress(CommandTimeoutError):
                    await self.link.command_long(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, [])
                raise MissionEndError(
                    "failed", f"the mission took longer than {budget_s:.0f} s (vehicle time); returning"
                )

    # ----- views
    def live(self) -> dict[str, Any]:
        """What /ws pushes: the vehicle, and the active mission's status, progress and latest sample."""
        mission: dict[str, Any] | None = None
        active = self.active_mission()
        if active is not None:
            recorder = self.recorders.get(active)
            mission = {
                "id": active,
                "status": self._statuses.get(active, "planned"),
                "progress": recorder.progress() if recorder else None,
                "sample": recorder.latest if recorder else None,
                "first_buoy_seq": FIRST_BUOY_SEQ,
            }
        return {"type": "state", "vehicle": self.link.status.as_dict(), "mission": mission}
