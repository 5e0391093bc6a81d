"""A sortie's inspection of its buoys, frame by frame as the camera reports them, and a verdict per buoy.

For a sortie flown with an inspection group per buoy (gcs.domain.planning.inspection_items) an `Inspector`:
- takes every CAMERA_IMAGE_CAPTURED the camera sends, checks it (gcs.vehicle.camera.Capture), and gives it to the
  buoy whose items were current when it was taken (its geotag's time, moved from the camera's clock onto the
  vehicle's, against the MISSION_CURRENT changes seen: the burst's report may arrive after the vehicle went on);
- downloads each frame (MAVLink FTP from the camera; HTTP when its file_url is http(s)) up to `max_frame_bytes`,
  decodes it and looks for the buoy in it (gcs.domain.buoy_detection) in a worker thread, and stores the frame
  with what was found (up to the mission's `max_mission_frame_bytes`);
- once the vehicle has gone on to the buoy itself (the burst is over) and that buoy's frames are in, judges it
  (gcs.domain.inspection.inspect_buoy) and stores its record: the page shows each verdict as the buoy is left.
Whatever goes wrong with a frame (a malformed report, an FTP error or silence, a file too large or not an image,
the mission's frame store full) is counted against its buoy and named in its reason if that leaves the buoy
not inspected; none of it stops the mission or the other buoys.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import logging
import multiprocessing
import time
from collections import Counter, defaultdict, deque
from collections.abc import Sequence
from concurrent.futures import BrokenExecutor, ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import httpx
import numpy as np
from PIL import Image, UnidentifiedImageError

from gcs.domain.buoy_detection import BuoyDetection, ChartedBuoy, detect_buoy
from gcs.domain.camera_geometry import CameraModel, FrameGeotag
from gcs.domain.inspection import (
    BuoyInspection,
    InspectedBuoy,
    InspectionRecord,
    StoredFrame,
    against_target,
    inspect_buoy,
)
from gcs.domain.planning import MissionLayout, Plan
from gcs.storage import FramesFullError
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.camera import CameraInfo, Capture, CaptureReportError
from gcs.vehicle.errors import LinkError
from gcs.vehicle.link import LinkManager

log = logging.getLogger(__name__)

SETTLE_S = 1.0  # vehicle seconds after the vehicle left a buoy's burst before its last report is taken as in
HTTP_TIMEOUT_S = 10.0
DRAIN_POLL_S = 1.0
CLOCK_SAMPLES = 32  # the camera's latest time-stamped messages its clock's offset is taken from
NO_CAMERA = "the vehicle has no camera"
NOT_ASKED = "the mission asked for no inspection (inspect: false)"
MAX_PIXELS = 50_000_000  # a frame larger than this is no camera's: refused before it is decoded


@dataclass(frozen=True)
class InspectionLimits:
    max_frame_bytes: int
    max_mission_frame_bytes: int
    drain_s: float  # wall clock the sortie's end waits at most for frames still downloading and being analysed
    stall_s: float = 60.0  # ... and at most this long without one of them done


def not_inspected(plan: Plan, index: int, reason: str) -> InspectionRecord:
    """Buoy `index`'s record when it could not be inspected at all (no camera, not reached...)."""
    return InspectionRecord(
        buoy=index,
        buoy_id=plan.buoy_ids[index],
        result=BuoyInspection(
            buoy=charted_record(plan, index),
            verdict="not_inspected",
            findings=[],
            observed=None,
            offset_m=None,
            light_seen=None,
            frames=[],
            reason=reason,
        ),
    )


def charted_record(plan: Plan, index: int) -> InspectedBuoy:
    mark = plan.mark(index)
    lat, lon = plan.charted_lat_lon(index)
    return InspectedBuoy(lat=lat, lon=lon, kind=mark.kind or "unknown", light=mark.light,
                         swing_radius_m=mark.swing_radius_m, region=mark.region)  # fmt: skip


def detect_frame(data: bytes, model: CameraModel, geotag: FrameGeotag, charted: ChartedBuoy) -> BuoyDetection:
    """One frame's finding of the buoy, from the file's bytes (what a worker process runs). Raises ValueError when
    the file is not an image."""
    return detect_buoy(decode(data), model, geotag, charted)


class FrameAnalysis:
    """Where frames are analysed: `workers` processes (spawned, not forked: the service has threads), so detection
    uses every core and never holds the event loop's interpreter lock; 0 workers: a thread of this process. The
    pool starts with the first frame and stops with the service."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._pool: ProcessPoolExecutor | None = None

    async def detect(self, data: bytes, model: CameraModel, geotag: FrameGeotag, charted: ChartedBuoy) -> BuoyDetection:
        if self.workers == 0:
            return await asyncio.to_thread(detect_frame, data, model, geotag, charted)
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"))
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._pool, detect_frame, data, model, geotag, charted)

    def shutdown(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)  # the workers gone, their semaphores released
            self._pool = None


def decode(data: bytes, limit_px: int = MAX_PIXELS) -> np.ndarray:
    """An image file's pixels (H, W, 3 uint8); raises ValueError when it is not an image Pillow reads."""
    try:
        with Image.open(io.BytesIO(data)) as image:
            if image.width * image.height > limit_px:
                raise ValueError(f"{image.width}x{image.height} pixels is no camera frame")
            return np.asarray(image.convert("RGB"))
    except (UnidentifiedImageError, OSError, Image.DecompressionBombError) as error:
        raise ValueError(f"not an image ({error})") from None


@dataclass
class _Buoy:
    """What one buoy's burst has brought so far."""

    frames: list[tuple[FrameGeotag, BuoyDetection, int]] = field(default_factory=list)  # with the stored id
    problems: Counter[str] = field(default_factory=Counter)
    reported: int = 0  # captures given to it; each ends in `frames` or in `problems`
    judged: bool = False

    @property
    def pending(self) -> int:
        """Its captures still being downloaded or analysed."""
        return self.reported - len(self.frames) - sum(self.problems.values())


class Inspector:
    """Inspects the buoys of one sortie (module doc). `start()` before the sortie flies, `await close()` after."""

    def __init__(
        self,
        link: LinkManager,
        storage: AsyncStorage,
        mission_id: int,
        plan: Plan,
        camera: CameraInfo,
        limits: InspectionLimits,
        analysis: FrameAnalysis,
    ) -> None:
        """`plan`: the sortie's (its order is what the vehicle flies)."""
        self.link, self.storage, self.mission_id, self.plan, self.camera = link, storage, mission_id, plan, camera
        self.limits, self.analysis = limits, analysis
        self.layout = MissionLayout(len(plan.order), inspected=True)
        self._seqs: list[tuple[float, int]] = []  # (vehicle s, current item) at each change seen
        self._clock_offsets: deque[float] = deque(maxlen=CLOCK_SAMPLES)  # vehicle s - camera s, as each arrived
        self._buoys: dict[int, _Buoy] = defaultdict(_Buoy)  # by position in the sortie's order
        self._work: asyncio.Queue[tuple[int, Capture] | int] = asyncio.Queue()  # frames, and positions to judge
        self._tasks: list[asyncio.Task] = []
        self._queued_judgement: set[int] = set()

    def replanned(self, plan: Plan) -> Inspector:
        """The inspector of the same sortie flying a new plan (uploaded in flight): buoys judged stay judged."""
        return Inspector(self.link, self.storage, self.mission_id, plan, self.camera, self.limits, self.analysis)

    # ----- running
    def start(self) -> None:
        self.link.add_listener(self._heard)
        self._tasks = [
            asyncio.create_task(self._receive(), name=f"inspect-{self.mission_id}-receive"),
            asyncio.create_task(self._process(), name=f"inspect-{self.mission_id}-process"),
        ]

    async def close(self, why_unjudged: str = "the sortie ended before the vehicle inspected it") -> None:
        """The sortie is over: judge every buoy the vehicle went on from once its frames are in (waiting for the
        ones still being downloaded while that goes on: `_drain`), and record the others as not inspected, since a
        part of a burst would misread the light: one the vehicle was still at says its burst was cut short and how
        much of it was reported, one whose frames are not all in says how many are missing, one never reached
        `why_unjudged`."""
        self.link.remove_listener(self._heard)
        receiving = self._tasks[0] if self._tasks else None
        if receiving is not None:
            receiving.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await receiving
        # only a buoy the vehicle went on from has its whole burst: one it was still at when the sortie ended (or
        # its link was lost) has a part of it, which would misread the light
        reached = {p for p in range(len(self.plan.order)) if self._passed(p)}
        for position in sorted(reached):
            self._judge_later(position)
        if len(self._tasks) > 1:
            await self._drain()
            self._tasks[1].cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._tasks[1]
        for position, index in enumerate(self.plan.order):
            buoy = self._buoys.get(position)
            if buoy is not None and buoy.judged:
                continue
            reason = why_unjudged
            if buoy is not None and position not in reached:
                expected = self.plan.mark(index).burst_frames()
                reason = (
                    f"its burst was cut short: the sortie's inspection stopped while the camera was at it "
                    f"({buoy.reported} of its {expected} frames reported)"
                )
            elif buoy is not None and buoy.pending:  # a part of a burst is not judged: its light would read wrong
                reason = (
                    f"the sortie's inspection stopped while {buoy.pending} of its {buoy.reported} frames were still "
                    "being downloaded and analysed"
                )
            record = not_inspected(self.plan, index, reason)
            if buoy is not None:  # the frames that are in stay with it, as evidence
                ids = [frame_id for _, _, frame_id in sorted(buoy.frames, key=lambda f: f[0].t_s)]
                record = record.model_copy(update={"frame_ids": ids, "best_frame": _best_frame(buoy.frames)})
            await self.storage.set_inspection(self.mission_id, record)

    async def _drain(self) -> None:
        """Wait for the frames still queued while their processing goes on: until none is left, or none has been
        done for `stall_s`, or `drain_s` has passed (a loaded machine analyses slowly, a stuck download stalls)."""
        deadline = time.monotonic() + self.limits.drain_s
        left, progress_at = self._work.qsize(), time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - progress_at < self.limits.stall_s:
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(DRAIN_POLL_S):
                    await self._work.join()
                return
            if self._work.qsize() < left:
                left, progress_at = self._work.qsize(), time.monotonic()

    def _heard(self, message: Any) -> None:
        """Each MISSION_CURRENT change (vehicle time), and each buoy the vehicle has gone on from: judged; each
        time-stamped message of the camera, for its clock (`_vehicle_time`)."""
        boot_ms, now_ms = getattr(message, "time_boot_ms", 0), self.link.status.time_boot_ms
        if message.get_srcComponent() == self.camera.component and boot_ms and now_ms:
            self._clock_offsets.append((now_ms - boot_ms) / 1000.0)
        if message.get_type() != "MISSION_CURRENT" or message.get_srcComponent() != self.link.target[1]:
            return
        seq = self.link.autopilot.planned_seq(message.seq)
        t_s = (self.link.status.time_boot_ms or 0) / 1000.0
        if not self._seqs or self._seqs[-1][1] != seq:
            self._seqs.append((t_s, seq))
        for position in range(len(self.plan.order)):
            if position not in self._queued_judgement and self._passed(position, settle_s=SETTLE_S):
                self._judge_later(position)

    def _passed(self, position: int, settle_s: float = 0.0) -> bool:
        """Whether the vehicle went on to the position-th buoy's waypoint (or beyond) `settle_s` vehicle seconds ago:
        its burst is over (the standoff's hold outlasts the burst)."""
        if not self._seqs:
            return False
        now = (self.link.status.time_boot_ms or 0) / 1000.0
        since = next((t for t, seq in self._seqs if seq >= self.layout.visit_seq(position)), None)
        return since is not None and now - since >= settle_s

    def _judge_later(self, position: int) -> None:
        if position not in self._queued_judgement:
            self._queued_judgement.add(position)
            self._work.put_nowait(position)

    def _vehicle_time(self, capture: Capture) -> float:
        """The capture's instant on the vehicle's clock, the one the MISSION_CURRENT changes are timed by.

        CAMERA_IMAGE_CAPTURED's time_boot_ms is the camera's clock: the autopilot's only where the camera is a part
        of it (our simulator's); a camera of its own counts from its own boot (MAVSDK's CameraServer stamps its
        host's uptime), ahead of the autopilot or behind it. The offset comes from the camera's time-stamped
        messages (CAMERA_IMAGE_CAPTURED, CAMERA_CAPTURE_STATUS...) as they arrive: the vehicle's latest time less
        the message's stamp, the smallest of the recent ones (a message is sent as it is stamped; one slow in
        coming only makes the difference larger)."""
        return capture.geotag.t_s + min(self._clock_offsets, default=0.0)

    def _position_at(self, t_s: float) -> int | None:
        """The buoy whose items were current at vehicle time t_s."""
        current = None
        for since, seq in self._seqs:
            if since > t_s + 1e-3:
                break
            current = seq
        return self.layout.position_of(current)

    async def _receive(self) -> None:
        with self.link.camera.captures() as reports:
            while True:
                message = await reports.get()
                try:
                    capture = Capture.from_message(message)
                except CaptureReportError as error:
                    # a report that does not add up cannot say which buoy it was for: the current one
                    position = self.layout.position_of(self._seqs[-1][1] if self._seqs else None)
                    if position is not None:
                        self._buoys[position].problems[f"a malformed CAMERA_IMAGE_CAPTURED ({error})"] += 1
                    continue
                position = self._position_at(self._vehicle_time(capture))
                if position is None or position in self._queued_judgement:
                    log.info("mission %s: a frame outside any buoy's burst: %s", self.mission_id, capture.file_url)
                    continue
                self._buoys.setdefault(position, _Buoy()).reported += 1  # even if every frame of it fails
                self._work.put_nowait((position, capture))

    async def _process(self) -> None:
        while True:
            work = await self._work.get()
            try:
                if isinstance(work, int):
                    buoy = self._buoys[work]
                    if not buoy.judged:
                        await self._store(work, self.plan.order[work], buoy)
                else:
                    await self._frame(*work)
            except Exception:  # one frame or buoy gone wrong must not stop the others
                log.exception("mission %s: inspection work %r failed", self.mission_id, work)
            finally:
                self._work.task_done()

    async def _download(self, capture: Capture) -> bytes:
        url = capture.file_url
        if url.startswith(("http://", "https://")):
            async with httpx.AsyncClient(timeout=HTTP_TIMEOUT_S) as client, client.stream("GET", url) as response:
                response.raise_for_status()
                data = bytearray()
                async for chunk in response.aiter_bytes():
                    data += chunk
                    if len(data) > self.limits.max_frame_bytes:
                        raise ValueError(f"{url}: over the limit of {self.limits.max_frame_bytes} bytes")
                return bytes(data)
        return await self.link.download_file(url, capture.component, self.limits.max_frame_bytes)

    async def _frame(self, position: int, capture: Capture) -> None:
        buoy, index = self._buoys[position], self.plan.order[position]
        try:
            data = await self._download(capture)
        except (LinkError, httpx.HTTPError, ValueError) as error:
            buoy.problems[f"a frame could not be downloaded ({error})"] += 1
            return
        sought = _charted(self.plan, index, where_sought=True)
        try:
            if sought is None:
                decode(data)  # kept only if it is an image
                detection = BuoyDetection(
                    False, "uncharted: the buoy's kind is not charted: nothing says what to look for"
                )
            else:
                detection = await self.analysis.detect(data, self.camera.model, capture.geotag, sought)
        except ValueError as error:
            buoy.problems[f"a frame is {error}"] += 1
            return
        except BrokenExecutor as error:  # a worker died (killed, out of memory): this frame is lost, not the rest
            buoy.problems[f"a frame's analysis failed ({type(error).__name__})"] += 1
            self.analysis.shutdown()  # the next frame starts a new pool
            return
        g = capture.geotag
        record = StoredFrame(buoy=index, image_index=g.image_index, t_s=g.t_s, lat=g.lat, lon=g.lon,
                             height_m=g.height_m, q=g.attitude, file_url=capture.file_url, found=detection.found,
                             light_on=None if detection.light is None else detection.light.lit,
                             note=detection.why)  # fmt: skip
        try:
            frame_id = await self.storage.add_frame(self.mission_id, record, data, self.limits.max_mission_frame_bytes)
        except FramesFullError as error:
            buoy.problems[f"a frame was not stored: {error}"] += 1
            return
        buoy.frames.append((g, detection, frame_id))

    async def _store(self, position: int, index: int, buoy: _Buoy, reason: str | None = None) -> None:
        """Judge the buoy from its frames and store its record (`reason` overrides a not-inspected one's)."""
        buoy.judged = True
        charted = _charted(self.plan, index)
        if charted is None:
            frames_reason = "its kind is not charted: give the buoy's kind to have it inspected"
            record = not_inspected(self.plan, index, frames_reason)
        else:
            result = inspect_buoy(charted, [(g, d) for g, d, _ in buoy.frames])
            if self.plan.mark(index).charted_lat_lon is not None:  # looked for elsewhere: compared with both
                result = against_target(result, self.plan.buoys_lat_lon[index])
            if result.verdict == "not_inspected":
                result = result.model_copy(update={"reason": reason or _reason(result.reason, buoy)})
            record = InspectionRecord(buoy=index, buoy_id=self.plan.buoy_ids[index], result=result)
        ids = [frame_id for _, _, frame_id in sorted(buoy.frames, key=lambda f: f[0].t_s)]
        record = record.model_copy(update={"frame_ids": ids, "best_frame": _best_frame(buoy.frames)})
        await self.storage.set_inspection(self.mission_id, record)


def _charted(plan: Plan, index: int, where_sought: bool = False) -> ChartedBuoy | None:
    """The buoy as charted (`where_sought`: at the position the mission looked for it, the centre of the
    detection's search: its latest AIS position when the plan took that); None when its kind is not charted."""
    mark = plan.mark(index)
    if mark.kind is None:
        return None
    lat, lon = plan.buoys_lat_lon[index] if where_sought else plan.charted_lat_lon(index)
    return ChartedBuoy(lat, lon, mark.kind, mark.light, mark.swing_radius_m, mark.region)


def _reason(result_reason: str | None, buoy: _Buoy) -> str:
    """Why a buoy was not inspected: the frames' problems first (they are the cause when frames are missing)."""
    problems = [f"{text} x{count}" if count > 1 else text for text, count in buoy.problems.most_common(3)]
    if not buoy.frames and problems:
        return "no frame could be used: " + "; ".join(problems)
    if not buoy.frames:
        return "no frame of its burst came from the camera (no CAMERA_IMAGE_CAPTURED while its items were current)"
    return "; ".join([result_reason or "not inspected", *problems])


def _best_frame(frames: Sequence[tuple[FrameGeotag, BuoyDetection, int]]) -> int | None:
    """The frame to show first: the buoy found with its light lit, else found, nearest the burst's middle."""
    if not frames:
        return None
    ordered = sorted(frames, key=lambda f: f[0].t_s)
    middle = ordered[len(ordered) // 2][0].t_s

    def rank(frame: tuple[FrameGeotag, BuoyDetection, int]) -> tuple[int, float]:
        geotag, detection, _ = frame
        lit = detection.light is not None and detection.light.lit
        return (0 if detection.found and lit else 1 if detection.found else 2, abs(geotag.t_s - middle))

    return min(ordered, key=rank)[2]
