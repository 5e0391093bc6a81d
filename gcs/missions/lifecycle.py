"""The flight lifecycle: upload -> arm -> start -> watch to the end, persisted at every transition.

One mission flies at a time; each runs as an asyncio task that ends in a terminal state.

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

The operator's commands while a sortie is in the air (`command`, `resume`), each the autopilot's own mode
(COMMAND_PURPOSES): hold where it is, return to the depot, land where it is; resume (after a hold or a return)
flies on in the mission mode from the first buoy not visited. The mission stays flying under a command, and its
flight-time budget counts none of that time (`budget_step`); a return or a landing ends it aborted once the vehicle
is down and disarmed (`operator_end`). The command in force is the mission's `progress.command`.

Completed means: every buoy visited (gcs.missions.recorder: the vehicle's own positions, after this mission's upload was
acknowledged), and the vehicle landed at the depot (its last position there) and disarmed (HEARTBEAT base_mode),
whichever messages showed it: a mission whose MISSION_ITEM_REACHED or MISSION_CURRENT were lost on the radio
but which flew is completed, and one whose messages claim completion without the positions to show it is not.

Before every arming, the pre-flight check (`_preflight`): the predicted energy of the sortie about to be flown
(gcs.missions.energy_planning.charge_needed) against the charge the vehicle reports, with its reserve (a vehicle that
reports no charge, having no battery monitor, is flown and the record says the check was not made). Short of charge,
the first sortie is refused (the mission fails naming both figures) unless the request said `override` (flown,
and the override recorded in the mission's events and progress); a later sortie waits in `waiting_for_battery`
until the operator confirms a battery swap (`battery_swapped`, POST /vehicles/{sysid}/battery-swap). The
service never tells the vehicle its pack was swapped unless the operator says so: MAV_CMD_BATTERY_RESET resets
ArduPilot's consumed-energy count, so sent unasked it would report a depleted pack full.

Inspection: when the vehicle has a camera (heard on its system, its CAMERA_INFORMATION read) and the request did
not say `inspect: false`, each sortie's items inspect every buoy (gcs.domain.planning.inspection_items) and an
Inspector (gcs.missions.inspector) judges each as the vehicle leaves it; otherwise each buoy is recorded not
inspected, with why, at the upload. A re-attached sortie's inspection goes on from the re-attachment (the frames
reported while no service listened are lost to it); the buoys of sorties that never flew end "not reached".

When no vehicle answers, POST /missions with start=true still answers 201 (status planned); the background
lifecycle then ends in `failed` with reason "no vehicle" after `vehicle_wait_s`. Clients poll
GET /missions/{id} or watch /ws.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Awaitable, Callable
from typing import Any

from gcs.domain.planning import FIRST_BUOY_SEQ, FlightParams, Plan, inspection_time_s, mission_items
from gcs.domain.records import MissionProgress
from gcs.domain.schemas import OperatorCommand, PreflightCheck, VehicleEvent
from gcs.domain.status import TERMINAL, MissionStatus
from gcs.missions.energy_planning import ChargeNeed, charge_needed, model_pack
from gcs.missions.flight_log import fetch_flight_log
from gcs.missions.inspector import NO_CAMERA, NOT_ASKED, FrameAnalysis, InspectionLimits, Inspector, not_inspected
from gcs.missions.recorder import MissionRecorder
from gcs.missions.results import flight_results
from gcs.missions.validation import fence_from_request
from gcs.settings import Settings
from gcs.storage import MissionRecord
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.camera import CameraInfo
from gcs.vehicle.errors import CommandDeniedError
from gcs.vehicle.link import CommandTimeoutError, LinkError, LinkManager
from gcs.vehicle.mission_protocol import MissionTransferError
from planner.energy import EnergyModel
from uavcore.battery_pack import PACK_PARAMETERS, PackSpec
from uavcore.mission import MissionItem

log = logging.getLogger(__name__)

FLUSH_PERIOD_S = 0.5  # wall clock between telemetry writes and checks
DISARM_GRACE_S = 3.0  # wall clock a flying mission may be disarmed (before takeoff) before it counts as ended
CLIMB_RATE_M_S = 1.0  # for the flight-time budget only
ABORTED_BEFORE_TAKEOFF = "aborted by the operator before takeoff"
RESTART_NOT_FLYING = "GCS restarted; vehicle no longer flying this mission"
REATTACHED = "GCS restarted; re-attached to the vehicle flying this mission"
MISSION_CURRENT_WAIT_S = 3.0  # wall clock a re-attaching service waits for the vehicle's MISSION_CURRENT
BATTERY_REPORT_WAIT_S = 5.0  # wall clock for the vehicle's battery report (BATTERY_STATUS comes at 1 Hz)
BATTERY_SETTLE_MS = 1500.0  # vehicle time after a landing before its battery report counts (one report after it)
CAMERA_WAIT_S = 2.5  # wall clock after the vehicle is heard for its camera's heartbeat (1 Hz) to be heard too
SWAPPED_CHARGE_WAIT_S = 5.0  # wall clock for the vehicle to report the charge of a pack the operator swapped
# The operator's commands on a flying mission, each the autopilot's own mode for it (its flavour's purpose,
# gcs.vehicle.autopilots: PX4 AUTO.LOITER, AUTO.RTL, AUTO.LAND, AUTO.MISSION; ArduPilot Copter LOITER 5, RTL 6,
# LAND 9, AUTO 3). A resume is back in the mission mode: the offboard controller takes it to OFFBOARD itself.
COMMAND_PURPOSES: dict[str, str] = {"hold": "hold", "return": "return", "land": "land", "resume": "mission"}
RETURNED_BY_OPERATOR = "returned at the operator's command"
LANDED_BY_OPERATOR = "landed where it was at the operator's command"


async def vehicle_pack(link: LinkManager) -> PackSpec | None:
    """The vehicle's pack and warning thresholds from its parameters (BAT1_*, BAT_*_THR); None when it has no
    such parameters (an ArduPilot names them otherwise) or does not answer."""
    if not link.status.connected:
        return None
    try:
        return PackSpec.from_parameters(await link.read_parameters(list(PACK_PARAMETERS)))
    except (LinkError, TimeoutError, ValueError):
        return None


def charge_text(remaining_pct: float | None) -> str:
    return "no charge" if remaining_pct is None else f"{remaining_pct:.0f} %"


def need_text(need: ChargeNeed) -> str:
    predicted = f"{need.energy_wh:.1f} Wh predicted"
    return f"{need.needed_pct:.0f} % ({predicted}, landing with the {need.reserve_pct:.0f} % reserve)"


class MissionConflictError(RuntimeError):
    """Another mission is using the vehicle, or the mission is not in a state that allows the request."""


class VehicleCommandError(RuntimeError):
    """The vehicle did not answer an operator's command (it may or may not have acted on it: its mode says)."""


class MissionEndError(Exception):
    """Raised inside the lifecycle to finish with a terminal status and a reason."""

    def __init__(self, status: MissionStatus, reason: str | None) -> None:
        super().__init__(reason)
        self.status, self.reason = status, reason


def flight_budget_s(plan: Plan, flight: FlightParams, margin_s: float, inspected: bool = False) -> float:
    """Simulated seconds a mission may take before it is declared failed (`inspected`: with a burst per buoy)."""
    cruise = plan.length_m / flight.speed_m_s
    bursts = inspection_time_s(plan) if inspected else 0.0
    return cruise + len(plan.order) * flight.dwell_s + 2 * flight.altitude_m / CLIMB_RATE_M_S + bursts + margin_s


def budget_step(step_s: float, command: OperatorCommand | None) -> float:
    """How many of `step_s` vehicle seconds the flight-time budget counts under the operator's `command`: held,
    landing or returning, none (the planned flight is not going on); returning, minus as many, since a return
    resumed is flown back out as far as it came home."""
    if command is None:
        return step_s
    return -step_s if command == "return" else 0.0


def operator_end(recorder: MissionRecorder, command: OperatorCommand) -> MissionEndError:
    """How a mission ends that the operator returned or landed: aborted, naming the buoys not inspected."""
    missing = recorder.not_inspected()
    what = RETURNED_BY_OPERATOR if command == "return" else LANDED_BY_OPERATOR
    which = f" ({', '.join(missing)})" if missing else ""
    return MissionEndError(
        MissionStatus.ABORTED, f"{what}; {len(missing)} buoy{'' if len(missing) == 1 else 's'} not inspected{which}"
    )


BATTERY_FAILSAFE = "battery failsafe"  # the reason of a mission the vehicle's battery failsafe ended begins so


def ended_by_the_vehicle(status: MissionStatus, reason: str | None) -> bool:
    """Whether a mission ended by what happened to its vehicle (lost, rebooted, brought down by a failsafe) rather
    than by the operator or as planned: failed, or aborted by its battery failsafe (`ended_early`)."""
    return status == MissionStatus.FAILED or (
        status == MissionStatus.ABORTED and (reason or "").startswith(BATTERY_FAILSAFE)
    )


def ended_early(recorder: MissionRecorder) -> MissionEndError:
    """How a mission ends when the vehicle disarmed before completing it: aborted after a battery failsafe (the
    vehicle reported its battery critical and came down: returned or landed, as its COM_LOW_BAT_ACT /
    BATT_FS_CRT_ACT says), with the buoys not inspected; failed after anything else."""
    progress = recorder.progress()
    if recorder.battery_failsafe:
        said = f" ({battery_failsafe_text([e.text for e in recorder.vehicle_events])})"
        return MissionEndError(
            MissionStatus.ABORTED,
            f"{BATTERY_FAILSAFE}{said}: the vehicle came down with {progress.visited} of {progress.buoys} buoys "
            f"inspected; not inspected: {', '.join(recorder.not_inspected())}",
        )
    reason = ended_early_reason(recorder.vehicle_events, progress.visited, progress.buoys)
    return MissionEndError(MissionStatus.FAILED, reason)


def battery_failsafe_text(texts: list[str]) -> str:
    """What the vehicle said of its battery failsafe: the first battery text followed by a mode change (the
    action taken: "Critical battery level! Executing RTL; mode OFFBOARD -> AUTO.RTL"), else its last battery text."""
    said = [i for i, text in enumerate(texts) if "battery" in text.lower()]
    for i in said:
        if i + 1 < len(texts) and texts[i + 1].startswith("mode "):
            return f"{texts[i]}; {texts[i + 1]}"
    return texts[said[-1]] if said else "battery critical"


def ended_early_reason(events: list[VehicleEvent], visited: int, buoys: int) -> str:
    """Why a mission ended with the vehicle disarmed before completing it: its failsafe, when it reported one
    (the last "Failsafe..." STATUSTEXT and the mode change that followed it), else the plain fact."""
    texts = [event.text for event in events]
    failsafes = [i for i, text in enumerate(texts) if text.lower().startswith("failsafe")]
    count = f"{visited} of {buoys} buoys visited"
    if not failsafes:
        return f"the vehicle disarmed before completing the mission ({count})"
    first = failsafes[-1]
    modes = [text for text in texts[first:] if text.startswith("mode ")]
    mode = f"; {modes[0]}" if modes else ""
    return f"vehicle failsafe: {texts[first]}{mode}; landed and disarmed with {count}"


class FlightLifecycle:
    """Flies stored missions over one LinkManager, one at a time, and records them."""

    def __init__(
        self,
        settings: Settings,
        storage: AsyncStorage,
        link: LinkManager,
        energy_model: EnergyModel,
        analysis: FrameAnalysis | None = None,
    ) -> None:
        """`energy_model`: the calibrated route energy model the service plans sorties with (the pre-flight check
        predicts with the same one); `analysis`: where camera frames are analysed (the service's, shared by its
        vehicles; default: the settings' number of worker processes, for this lifecycle alone)."""
        self.analysis = analysis or FrameAnalysis(settings.inspection_workers)
        self.settings, self.storage, self.link = settings, storage, link
        self.energy_model = energy_model
        self._tasks: dict[int, asyncio.Task] = {}
        self._abort_requested: set[int] = set()
        self._recorders: dict[int, MissionRecorder] = {}
        self._statuses: dict[int, MissionStatus] = {}  # last status of missions run here, for the live view
        self._handing_over = False  # stop() leaves flying missions for the next owner of the vehicle link
        self._replans: dict[int, Plan] = {}  # new plans for flying missions, uploaded in flight by their monitor
        self._swapped = asyncio.Event()  # the operator confirmed a battery swap (a waiting mission goes on)
        self._inspectors: dict[int, Inspector] = {}  # each flying mission's inspection of its sortie's buoys
        self._watching: set[int] = set()  # missions whose sortie is in the air, watched: the operator commands it
        self._log_fetches: set[asyncio.Task] = set()  # flight logs being downloaded after their missions ended

    async def reattach(self, unfinished: list[int]) -> None:
        """At start-up, with the ids of the missions a previous run left unfinished (oldest first)."""
        # the vehicle flies one mission at a time: only the latest unfinished one can still be in the air
        for mission_id in unfinished[:-1]:
            await self._transition(mission_id, MissionStatus.FAILED, RESTART_NOT_FLYING)
        if unfinished:
            mission_id = unfinished[-1]
            log.warning("mission %s was unfinished at start-up: re-attaching if the vehicle still flies it", mission_id)
            self._start_task(mission_id, resume=True)

    async def stop(self, hand_over: bool = False) -> None:
        """Cancel every running mission: each ends failed ("the service stopped during the mission"), or with
        `hand_over` a mission in flight is left as it is, its samples and progress stored, for the instance that
        owns the vehicle link next (a stand-by on the shared database, or this one restarted) to re-attach."""
        self._handing_over = hand_over
        for task in [*self._tasks.values(), *self._log_fetches]:
            task.cancel()
        for task in [*self._tasks.values(), *self._log_fetches]:
            with contextlib.suppress(asyncio.CancelledError):
                await task

    def active_mission(self) -> int | None:
        for mission_id, task in self._tasks.items():
            if not task.done():
                return mission_id
        return None

    def ensure_vehicle_free(self) -> None:
        if (active := self.active_mission()) is not None:
            raise MissionConflictError(f"mission {active} is using the vehicle; abort it or wait for it to end")

    def launch(self, record: MissionRecord) -> None:
        """Fly a planned mission in the background."""
        self.ensure_vehicle_free()
        if record.status != MissionStatus.PLANNED:
            raise MissionConflictError(f"mission {record.id} is {record.status}; only a planned mission can start")
        self._start_task(record.id)

    async def abort(self, record: MissionRecord) -> None:
        """Return to the depot. A mission not yet flying ends at once; a flying one ends when it has landed."""
        mission_id = record.id
        if record.status in TERMINAL:
            raise MissionConflictError(f"mission {mission_id} is {record.status}; nothing to abort")
        task = self._tasks.get(mission_id)
        between_sorties = record.status == MissionStatus.WAITING_FOR_BATTERY  # the wait ends it at the depot
        if (record.status == MissionStatus.FLYING or between_sorties) and task is not None and not task.done():
            self._abort_requested.add(mission_id)
            return
        if task is not None and not task.done():
            self._abort_requested.add(mission_id)  # _run ends it as aborted
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            # A task cancelled before it began, or while it still read its mission (an await since the storage left
            # the event loop), ended before its `try`: nothing recorded the end, so it is recorded here.
            if (await self.storage.existing_mission(mission_id)).status in TERMINAL:
                return
            self._abort_requested.discard(mission_id)
        await self._transition(mission_id, MissionStatus.ABORTED, ABORTED_BEFORE_TAKEOFF)

    def replan(self, mission_id: int, plan: Plan) -> None:
        """Fly a new plan (one tour: the mission's buoys in the same indices, then more) on a mission in flight:
        its monitor uploads it to the flying vehicle, which flies on from its cruise-speed item (the take-off is
        behind it) through the new plan's buoys. Raises MissionConflictError unless the mission is flying here."""
        task = self._tasks.get(mission_id)
        if task is None or task.done() or self._statuses.get(mission_id) != MissionStatus.FLYING:
            raise MissionConflictError(f"mission {mission_id} is not flying here: it cannot be re-planned in flight")
        self._replans[mission_id] = plan

    # ----- the operator's commands in flight
    async def command(self, record: MissionRecord, command: OperatorCommand) -> None:
        """Hold where it is, return to the depot or land where it is: the autopilot's own mode for it
        (COMMAND_PURPOSES). The mission stays flying; a return or a landing ends it aborted once the vehicle is
        down and disarmed (the monitor). Raises MissionConflictError (not flying here, or the vehicle refused) or
        VehicleCommandError (no answer)."""
        recorder = self._airborne(record, command)
        await self._tell_vehicle(record.id, command, lambda: self.link.set_mode(COMMAND_PURPOSES[command]))
        await self._commanded(record.id, recorder, command, command)

    async def resume(self, record: MissionRecord) -> None:
        """After a hold or a return: fly on in the mission mode from the first buoy not visited (its first item),
        the items before it skipped. Raises as `command`."""
        recorder = self._airborne(record, "resume")
        if recorder.command not in ("hold", "return"):
            why = "it is landing where it was" if recorder.command == "land" else "it is neither held nor returning"
            raise MissionConflictError(f"mission {record.id} has nothing to resume: {why}")
        seq, buoy = recorder.resume_point()
        # the current item first: the mission mode then flies from it, on PX4 and ArduPilot alike
        await self._tell_vehicle(record.id, "resume", lambda: self.link.set_current_item(seq))
        await self._tell_vehicle(record.id, "resume", lambda: self.link.set_mode(COMMAND_PURPOSES["resume"]))
        where = "on the way home" if buoy is None else f"from buoy {recorder.plan.buoy_ids[buoy]}"
        await self._commanded(record.id, recorder, None, f"resume {where}")

    def _airborne(self, record: MissionRecord, command: str) -> MissionRecorder:
        """The recorder of `record`, whose sortie is in the air and watched here; else MissionConflictError."""
        mission_id = record.id
        if mission_id in self._abort_requested:
            raise MissionConflictError(f"mission {mission_id} is being aborted: nothing to {command}")
        if record.status != MissionStatus.FLYING:
            raise MissionConflictError(f"mission {mission_id} is {record.status}, not in the air: nothing to {command}")
        recorder = self._recorders.get(mission_id)
        s = self.link.status
        if mission_id not in self._watching or recorder is None or not s.armed or s.on_ground:
            raise MissionConflictError(
                f"mission {mission_id}'s vehicle is on the ground (taking off, between sorties or landed): "
                f"nothing to {command}"
            )
        return recorder

    async def _tell_vehicle(self, mission_id: int, command: str, action: Callable[[], Awaitable[None]]) -> None:
        """Send one command; a refusal is a conflict (the vehicle's state does not allow it, in its own words),
        silence a VehicleCommandError."""
        try:
            await action()
        except CommandDeniedError as error:
            raise MissionConflictError(f"{error}: mission {mission_id} goes on as it was") from None
        except LinkError as error:
            raise VehicleCommandError(f"the vehicle did not answer the operator's {command}: {error}") from None

    async def _commanded(
        self, mission_id: int, recorder: MissionRecorder, command: OperatorCommand | None, text: str
    ) -> None:
        """The vehicle took the command: it is in force, among the vehicle's events and in the status history,
        and stored now, so the answer (and /ws) shows it."""
        recorder.command = command
        recorder.operator(text)
        if mission_id not in self._watching:  # the sortie ended while the vehicle was told: its end is on record
            return
        await self.storage.set_progress(mission_id, recorder.progress())
        await self._note(mission_id, f"operator: {text}")

    def live_mission(self) -> dict[str, Any] | None:
        """The active mission's status, progress and latest sample, for /ws; None when no mission flies."""
        active = self.active_mission()
        if active is None:
            return None
        recorder = self._recorders.get(active)
        return {
            "id": active,
            "status": self._statuses.get(active, MissionStatus.PLANNED),
            "progress": recorder.progress().model_dump(mode="json") if recorder else None,
            "sample": recorder.latest if recorder else None,
            "first_buoy_seq": FIRST_BUOY_SEQ,
        }

    # ----- one mission's task
    def _start_task(self, mission_id: int, resume: bool = False) -> None:
        self._tasks[mission_id] = asyncio.create_task(self._run(mission_id, resume), name=f"mission-{mission_id}")

    async def _run(self, mission_id: int, resume: bool = False) -> None:
        record = await self.storage.existing_mission(mission_id)
        plan, flight = record.plan, record.flight
        recorder = MissionRecorder(self.link, plan, self.settings.telemetry_period_s, flight.acceptance_radius_m)
        status = MissionStatus.FAILED
        reason: str | None = "internal error"  # MissionEndError's reason may be None
        try:
            if resume:
                recorder.restore(record.progress)
                await self._resume(mission_id, plan, flight, recorder)
            else:
                await self._fly(mission_id, plan, flight, recorder)
        except MissionEndError as ended:
            status, reason = ended.status, ended.reason
        except CommandTimeoutError as error:
            reason = f"the vehicle stopped answering: {error}"
        except (MissionTransferError, LinkError) as error:  # refused commands and transfers say why themselves
            reason = str(error)
        except asyncio.CancelledError:
            if self._handing_over and (await self.storage.existing_mission(mission_id)).status == MissionStatus.FLYING:
                await self._detach(mission_id, recorder)
                log.warning("mission %s handed over in flight: the next owner of the link re-attaches it", mission_id)
                raise
            status, reason = MissionStatus.FAILED, "the service stopped during the mission"
            if mission_id in self._abort_requested:
                status, reason = MissionStatus.ABORTED, ABORTED_BEFORE_TAKEOFF
            await self._finish(mission_id, recorder.mission_plan, flight, recorder, status, reason, fetch_log=False)
            raise
        except Exception as error:  # never leave a mission hanging in a non-terminal state
            log.exception("mission %s failed", mission_id)
            reason = f"internal error: {type(error).__name__}: {error}"
        await self._finish(mission_id, recorder.mission_plan, flight, recorder, status, reason)

    def _record_with(self, mission_id: int, recorder: MissionRecorder) -> None:
        """From now on the recorder hears every message of the vehicle, and /ws shows its progress."""
        self.link.add_listener(recorder, recorder.end_of_chunk)
        self._recorders[mission_id] = recorder

    async def _finish(
        self,
        mission_id: int,
        plan: Plan,
        flight: FlightParams,
        recorder: MissionRecorder,
        status: MissionStatus,
        reason: str | None,
        fetch_log: bool = True,
    ) -> None:
        """End a mission: its samples, progress and results stored, its status set; then (fetch_log) the vehicle's
        flight log downloaded in the background."""
        self._abort_requested.discard(mission_id)
        progress = await self._detach(mission_id, recorder)
        inspected = {record.buoy for record in await self.storage.inspections(mission_id)}
        for index in range(len(plan.buoy_ids)):
            if index not in inspected:  # never reached: its sortie did not fly, or not that far
                ended = reason or "the mission ended"
                await self.storage.set_inspection(mission_id, not_inspected(plan, index, f"not reached ({ended})"))
        samples = await self.storage.telemetry(mission_id)
        if samples:
            await self.storage.set_results(mission_id, flight_results(plan, flight, samples, progress))
        await self._transition(mission_id, status, reason)
        if recorder.armed_seen and fetch_log:  # it flew: the vehicle's newest log is its (gcs.missions.flight_log)
            fetch = fetch_flight_log(self.link, self.storage, mission_id)
            task = asyncio.create_task(fetch, name=f"flight-log-{mission_id}")  # the vehicle is free meanwhile
            self._log_fetches.add(task)
            task.add_done_callback(self._log_fetches.discard)

    async def _detach(self, mission_id: int, recorder: MissionRecorder) -> MissionProgress:
        """Stop recording a mission, storing all it recorded: its samples and progress (returned). A mission
        that goes on flying (`stop(hand_over=True)`) is left there; `_finish` goes on to end it."""
        self.link.remove_listener(recorder, recorder.end_of_chunk)
        self._recorders.pop(mission_id, None)
        await self.storage.add_telemetry(mission_id, recorder.take())
        progress = recorder.progress()
        await self.storage.set_progress(mission_id, progress)
        return progress

    async def _transition(self, mission_id: int, status: MissionStatus, reason: str | None = None) -> None:
        await self.storage.set_status(mission_id, status, reason)
        self._statuses[mission_id] = status

    async def _note(self, mission_id: int, reason: str) -> None:
        """An event on the mission's record that leaves its status as it is."""
        await self._transition(mission_id, self._statuses[mission_id], reason)

    async def _fly(self, mission_id: int, plan: Plan, flight: FlightParams, recorder: MissionRecorder) -> None:
        if not await self.link.wait_connected(self.settings.vehicle_wait_s):
            raise MissionEndError(MissionStatus.FAILED, "no vehicle")
        for sortie in range(len(plan.sortie_orders())):
            await self._fly_sortie(mission_id, plan, flight, recorder, sortie)
        raise MissionEndError(MissionStatus.COMPLETED, None)

    async def _fly_sortie(
        self, mission_id: int, plan: Plan, flight: FlightParams, recorder: MissionRecorder, sortie: int
    ) -> None:
        """Upload, check, arm, start and watch one sortie to its landing at the depot. Between sorties the mission
        stays flying, its events saying which sortie is on (or waits for a battery swap)."""
        sorties = len(plan.sortie_orders())
        on = f"sortie {sortie + 1} of {sorties}" if sorties > 1 else None
        self._check_abort_between_sorties(mission_id, sortie)
        if sortie == 0:
            await self._transition(mission_id, MissionStatus.UPLOADING, on)
            self._record_with(mission_id, recorder)  # from here: what the vehicle says is the mission's too
        else:
            recorder.begin_sortie(sortie)
        await self._preflight(mission_id, plan, flight, recorder, sortie)
        if sortie > 0:
            await self._transition(mission_id, MissionStatus.FLYING, on)
        incarnation = self.link.status.incarnation  # after the check: a pack swapped by hand reboots a vehicle
        sortie_plan = plan.sortie_plan(sortie)
        camera, camera_text = await self._camera(flight)
        items = self._items(sortie_plan, flight, camera is not None)
        await self._upload_fence_and_rally(plan)
        await self.link.upload_mission(items, self.link.status.home or self.settings.home)
        recorder.mission_uploaded(camera_text if camera is not None else None)
        if sortie == 0:
            await self._transition(mission_id, MissionStatus.UPLOADED, on)
        inspector = None
        if camera is None:
            for index in sortie_plan.order:
                await self.storage.set_inspection(mission_id, not_inspected(sortie_plan, index, camera_text))
        else:
            inspector = self._start_inspector(mission_id, sortie_plan, camera)
        try:
            self._check_abort_between_sorties(mission_id, sortie)
            recorder.sortie_took_off()
            await self.link.arm()
            await self.link.start_mission(items)
            if sortie == 0:
                await self._transition(mission_id, MissionStatus.FLYING, on)
            await self._monitor(mission_id, sortie_plan, flight, recorder, incarnation)
            await self._landed(recorder)
        finally:
            if inspector is not None:
                await self._inspectors.pop(mission_id, inspector).close()

    async def _upload_fence_and_rally(self, plan: Plan) -> None:
        """The plan's geofence and rally points to the vehicle before its mission, every sortie (a pack swapped by
        hand may reboot it): the fence first, since PX4 refuses a mission with an item outside its fence and
        enforces the fence itself in flight (GF_ACTION); the vehicle keeps its own lists when the plan has none."""
        if plan.fence is not None:
            await self.link.upload_fence(fence_from_request(plan.fence))
        if plan.rally_points:
            await self.link.upload_rally_points([(p[0], p[1], p[2]) for p in plan.rally_points])

    def _start_inspector(self, mission_id: int, sortie_plan: Plan, camera: CameraInfo) -> Inspector:
        s = self.settings
        limits = InspectionLimits(s.max_frame_bytes, s.max_mission_frame_bytes, s.inspection_drain_s)
        inspector = Inspector(self.link, self.storage, mission_id, sortie_plan, camera, limits, self.analysis)
        self._inspectors[mission_id] = inspector
        inspector.start()
        return inspector

    async def _camera(self, flight: FlightParams) -> tuple[CameraInfo | None, str]:
        """The camera the sortie inspects with and its description, or None and why the buoys will not be."""
        if not flight.inspect:
            return None, NOT_ASKED
        camera = self.link.camera
        await camera.wait_heard(CAMERA_WAIT_S)
        if camera.component is None:
            return None, NO_CAMERA
        try:
            info = await camera.information()
        except LinkError as error:
            return None, f"the camera gave no usable CAMERA_INFORMATION: {error}"
        m = info.model
        return info, f"component {info.component}: {info.vendor} {info.model_name} ({m.width_px}x{m.height_px})"

    def _check_abort_between_sorties(self, mission_id: int, sortie: int) -> None:
        if sortie > 0 and mission_id in self._abort_requested:
            raise MissionEndError(
                MissionStatus.ABORTED, f"aborted by the operator at the depot before sortie {sortie + 1}"
            )

    async def _charge_need(self, plan: Plan, flight: FlightParams, sortie: int) -> ChargeNeed:
        pack = await vehicle_pack(self.link) or model_pack(self.energy_model)
        return await asyncio.to_thread(charge_needed, plan, sortie, flight, pack, self.energy_model)

    async def _preflight(
        self, mission_id: int, plan: Plan, flight: FlightParams, recorder: MissionRecorder, sortie: int
    ) -> None:
        """Before arming for `sortie`: its predicted energy against the charge the vehicle reports (module doc)."""
        need = await self._charge_need(plan, flight, sortie)
        remaining = await self._battery_remaining()
        check = PreflightCheck(sortie=sortie, needed_pct=need.needed_pct, energy_wh=need.energy_wh,
                               reserve_pct=need.reserve_pct, remaining_pct=remaining, override=False)  # fmt: skip
        short = remaining is not None and remaining < need.needed_pct
        if remaining is None:  # no battery monitor reported: nothing to check against, and the record says so
            await self._note(
                mission_id,
                f"pre-flight check not made: the vehicle reports no charge; the sortie needs {need_text(need)}",
            )
        elif short and flight.override:
            check.override = True
            await self._note(
                mission_id,
                f"pre-flight check overridden by the request: the vehicle reports {charge_text(remaining)}, "
                f"the sortie needs {need_text(need)}",
            )
        elif short and sortie == 0:
            recorder.preflight(check)
            raise MissionEndError(
                MissionStatus.FAILED,
                f"refused by the pre-flight check: the vehicle reports {charge_text(remaining)}, the "
                f"{'first sortie' if len(plan.sortie_orders()) > 1 else 'tour'} needs {need_text(need)}; swap the "
                'pack (POST /vehicles/{sysid}/battery-swap), or fly it anyway with "override": true',
            )
        elif short:
            check.remaining_pct = remaining = await self._wait_for_battery(mission_id, recorder, sortie, need)
            check.swapped = True
        recorder.preflight(check)
        await self.storage.set_progress(mission_id, recorder.progress())  # the check is on record before the arming

    async def _wait_for_battery(
        self, mission_id: int, recorder: MissionRecorder, sortie: int, need: ChargeNeed
    ) -> float | None:
        """`waiting_for_battery` until the operator confirms a swap and the vehicle reports the charge the sortie
        needs (or the operator aborts at the depot). Returns the charge then reported."""
        while True:
            remaining = self.link.status.battery_remaining_pct
            self._swapped.clear()  # before the status is stored: a swap confirmed meanwhile counts
            await self._transition(
                mission_id,
                MissionStatus.WAITING_FOR_BATTERY,
                f"sortie {sortie + 1} needs {need_text(need)}; the vehicle reports {charge_text(remaining)}: swap "
                "the pack and confirm the swap",
            )
            while not self._swapped.is_set():
                self._check_abort_between_sorties(mission_id, sortie)
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(FLUSH_PERIOD_S):
                        await self._swapped.wait()
                await self.storage.add_telemetry(mission_id, recorder.take())
            deadline = time.monotonic() + SWAPPED_CHARGE_WAIT_S
            while time.monotonic() < deadline:
                remaining = self.link.status.battery_remaining_pct
                if remaining is not None and remaining >= need.needed_pct:
                    return remaining
                await asyncio.sleep(0.1)

    def waiting_for_battery(self) -> int | None:
        """The mission waiting here for a battery swap, if one is."""
        active = self.active_mission()
        waiting = active is not None and self._statuses.get(active) == MissionStatus.WAITING_FOR_BATTERY
        return active if waiting else None

    async def battery_swapped(self, charge_pct: float = 100.0) -> str:
        """The operator says a fresh pack is in: tell the vehicle (MAV_CMD_BATTERY_RESET: the simulator puts the
        pack in, ArduPilot resets its consumed-energy count), and wake a mission waiting for it. A vehicle that
        refuses the command (PX4 measures a new pack itself) still reports its charge, which the waiting mission
        checks. Returns what the vehicle answered. Raises MissionConflictError while the vehicle is in the air."""
        s = self.link.status
        if not s.connected:
            raise MissionConflictError("no vehicle is connected: there is nobody to tell of a swap")
        if s.armed or not s.on_ground:
            raise MissionConflictError("the vehicle is armed or airborne: a pack is swapped on the ground")
        try:
            await self.link.reset_battery(charge_pct)
            answer = "accepted"
        except LinkError as error:
            answer = str(error)
        self._swapped.set()
        return answer

    async def _battery_remaining(self) -> float | None:
        deadline = time.monotonic() + BATTERY_REPORT_WAIT_S
        while self.link.status.battery_remaining_pct is None and time.monotonic() < deadline:
            await asyncio.sleep(0.1)
        return self.link.status.battery_remaining_pct

    async def _landed(self, recorder: MissionRecorder) -> None:
        """The sortie is down: its battery figures once the vehicle has reported its battery after the disarm."""
        s = self.link.status
        since_ms = s.time_boot_ms or 0
        deadline = time.monotonic() + BATTERY_REPORT_WAIT_S
        while (s.time_boot_ms or 0) - since_ms < BATTERY_SETTLE_MS and time.monotonic() < deadline:
            await asyncio.sleep(0.1)
        recorder.sortie_landed()

    async def _resume(self, mission_id: int, plan: Plan, flight: FlightParams, recorder: MissionRecorder) -> None:
        """Re-attach to a mission a previous run of the service left unfinished, or end it (see the module doc)."""
        if not await self.link.wait_connected(self.settings.vehicle_wait_s):
            raise MissionEndError(MissionStatus.FAILED, f"{RESTART_NOT_FLYING} (no vehicle)")
        s = self.link.status
        deadline = time.monotonic() + MISSION_CURRENT_WAIT_S
        while s.mission_total is None and time.monotonic() < deadline:
            await asyncio.sleep(0.1)
        sortie = recorder.sortie
        sortie_plan = plan.sortie_plan(sortie)
        expected = self._items(sortie_plan, flight, recorder.layout.inspected)
        on_board = await self.link.download_mission()
        same = len(on_board) == len(expected) and all(
            (a.command, a.x, a.y) == (b.command, b.x, b.y) for a, b in zip(on_board, expected, strict=True)
        )
        if not same:
            raise MissionEndError(MissionStatus.FAILED, f"{RESTART_NOT_FLYING} (another mission is on board)")
        self._record_with(mission_id, recorder)
        if not s.armed:
            if not (s.mission_complete and s.on_ground):
                raise MissionEndError(MissionStatus.FAILED, RESTART_NOT_FLYING)
        else:
            await self._transition(mission_id, MissionStatus.FLYING, REATTACHED)
            # its inspection goes on from here: the frames reported while no service listened are not known
            camera = (await self._camera(flight))[0] if recorder.layout.inspected else None
            inspector = None if camera is None else self._start_inspector(mission_id, sortie_plan, camera)
            try:
                # seen armed just now: a sortie that lands before the first check is finished, not ended early
                await self._monitor(mission_id, sortie_plan, flight, recorder, s.incarnation, armed=True)
            finally:
                if inspector is not None:
                    await self._inspectors.pop(mission_id, inspector).close()
        await self._landed(recorder)
        for later in range(sortie + 1, len(plan.sortie_orders())):
            await self._fly_sortie(mission_id, plan, flight, recorder, later)
        raise MissionEndError(MissionStatus.COMPLETED, None)

    def _items(self, plan: Plan, flight: FlightParams, camera: bool) -> list[MissionItem]:
        """The mission items of a (sortie) plan for this vehicle: back to its home by RTL when the depot is it and
        the plan has no rally points, else landing at the depot (gcs.domain.planning.mission_items); with `camera`,
        each buoy inspected (gcs.domain.planning.inspection_items)."""
        home = self.link.status.home
        return mission_items(plan, flight, None if home is None else (home[0], home[1]), camera)

    async def _upload_in_flight(
        self, mission_id: int, plan: Plan, flight: FlightParams, recorder: MissionRecorder
    ) -> None:
        """Upload `plan` to the flying vehicle (MISSION_ITEM_INT while in AUTO), fly on from its cruise-speed item,
        record against it."""
        items = self._items(plan, flight, recorder.layout.inspected)
        added = len(plan.buoy_ids) - len(recorder.mission_plan.buoy_ids)
        camera = recorder.camera
        recorder.replan(plan)  # the items on board are no longer the ones it records against
        await self.link.upload_mission(items, self.link.status.home or self.settings.home)
        await self.link.set_current_item(FIRST_BUOY_SEQ - 1)  # the take-off is behind it; the speed, then buoys
        recorder.mission_uploaded(camera)
        if (inspector := self._inspectors.get(mission_id)) is not None:  # buoys judged stay so; the rest anew
            await inspector.close("re-planned in flight before its inspection")
            self._inspectors[mission_id] = inspector = inspector.replanned(plan)
            inspector.start()
        await self.storage.set_plan(mission_id, plan)
        await self._transition(mission_id, MissionStatus.FLYING, f"re-planned in flight: {added} more buoys")

    async def _monitor(
        self,
        mission_id: int,
        plan: Plan,
        flight: FlightParams,
        recorder: MissionRecorder,
        incarnation: int,
        armed: bool = False,
    ) -> None:
        """Watch the sortie on board until it has landed finished (return) or ends otherwise (MissionEndError).
        `armed`: the vehicle is known to have been armed for this sortie (a re-attached one). While it is watched,
        the operator may command it (`command`, `resume`)."""
        self._watching.add(mission_id)
        try:
            await self._watch_sortie(mission_id, plan, flight, recorder, incarnation, armed)
        finally:
            self._watching.discard(mission_id)

    async def _watch_sortie(
        self,
        mission_id: int,
        plan: Plan,
        flight: FlightParams,
        recorder: MissionRecorder,
        incarnation: int,
        armed: bool,
    ) -> None:
        s = self.link.status
        sysid = s.sysid
        budget_s = flight_budget_s(plan, flight, self.settings.mission_timeout_margin_s, recorder.layout.inspected)
        last_s = (s.time_boot_ms or 0) / 1000.0
        elapsed = 0.0  # vehicle seconds the budget counts: none held, landing or returning (budget_step)
        disarmed_since: float | None = None
        was_armed = armed  # "finished" counts only after the vehicle flew this sortie (not a stale report)
        aborting = False
        last_progress: MissionProgress | None = None
        while True:
            await asyncio.sleep(FLUSH_PERIOD_S)
            s = self.link.status  # a new vehicle on the link gets a new status object
            now_s = (s.time_boot_ms or 0) / 1000.0
            elapsed += budget_step(max(0.0, now_s - last_s), recorder.command)
            last_s = now_s
            await self.storage.add_telemetry(mission_id, recorder.take())
            progress = recorder.progress()
            if progress != last_progress:
                await self.storage.set_progress(mission_id, progress)
                last_progress = progress
            if (replanned := self._replans.pop(mission_id, None)) is not None and not aborting:
                await self._upload_in_flight(mission_id, replanned, flight, recorder)
                budget_s = elapsed + flight_budget_s(
                    replanned, flight, self.settings.mission_timeout_margin_s, recorder.layout.inspected
                )
            if s.incarnation != incarnation:
                what = (
                    "the vehicle rebooted" if s.sysid == sysid else f"another vehicle (system {s.sysid}) took the link"
                )
                raise MissionEndError(MissionStatus.FAILED, f"{what} during the mission")
            if not s.connected:
                raise MissionEndError(MissionStatus.FAILED, "link lost: no heartbeat from the vehicle")
            if mission_id in self._abort_requested and not aborting:
                aborting = True
                recorder.command = None  # the abort's return replaces any command of the operator's
                await self.link.return_to_launch()
                await self._transition(
                    mission_id, MissionStatus.ABORTED, "aborted by the operator: returning to the depot"
                )
            was_armed = was_armed or s.armed
            on_ground_disarmed = not s.armed and s.on_ground
            # what the vehicle did, whichever messages showed it (gcs.missions.recorder): every buoy visited, back home
            finished = recorder.sortie_visited() and recorder.at_depot()
            if on_ground_disarmed and aborting:
                recorder.sortie_landed()
                raise MissionEndError(MissionStatus.ABORTED, "aborted by the operator: returned to the depot")
            if on_ground_disarmed and finished and was_armed and not recorder.not_inspected():
                return  # every buoy visited: whatever the operator commanded on the way, completed as planned
            command = recorder.command
            if on_ground_disarmed and was_armed and command is not None and command != "hold":
                recorder.sortie_landed()  # returned or landed at the operator's command: over, with what is left
                raise operator_end(recorder, command)
            if on_ground_disarmed and finished and was_armed:
                return
            if not s.armed:
                disarmed_since = disarmed_since or time.monotonic()
                if time.monotonic() - disarmed_since > DISARM_GRACE_S:
                    recorder.sortie_landed()  # the sortie's battery figures, as far as it flew
                    raise ended_early(recorder)
            else:
                disarmed_since = None
            # a vehicle already down and disarmed is not overrunning: the disarm check above ends the mission
            # (a lockstep vehicle with no controller runs free, so the wall-clock grace is many simulated seconds)
            if elapsed > budget_s and not aborting and s.armed and recorder.command is None:
                with contextlib.suppress(LinkError):
                    await self.link.return_to_launch()
                raise MissionEndError(
                    MissionStatus.FAILED, f"the mission took longer than {budget_s:.0f} s (vehicle time); returning"
                )
