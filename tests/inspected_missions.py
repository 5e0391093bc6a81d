"""A mission with inspection records and real camera frames, stored as gcs.missions.inspector stores them (records
by buoy, frames with their bytes), for the report and browser tests; no flight, so it takes a second.

Four buoys flown in input order: B1 ok, B2 off station (a burst of BURST frames), B3 not inspected (no frame),
B4 with its light out. The frames are the simulator camera's, rendered from a world of these buoys
(bench.inspection_scenes.capture_burst) and JPEG-encoded, small.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, replace

from PIL import Image
from stored_missions import FLIGHT

from bench.inspection_scenes import capture_burst
from gcs.domain.inspection import (
    BuoyInspection,
    Finding,
    InspectedBuoy,
    InspectionRecord,
    LatLon,
    StoredFrame,
)
from gcs.domain.planning import BuoyMark, Plan, sorties_plan
from gcs.domain.records import MissionProgress
from gcs.domain.status import MissionStatus
from gcs.storage import Storage
from uavcore.buoy_world import World
from uavcore.geodesy import DEFAULT_HOME

IDS = ["B1", "B2", "B3", "B4"]
OFFSETS = [(0.0004, 0.0), (0.0004, 0.0006), (0.0, 0.0008), (-0.0003, 0.0004)]  # from the depot, degrees
MARKS = [
    BuoyMark(kind="safe_water", light="LFl 10s", swing_radius_m=3.0),
    BuoyMark(kind="starboard", light="Fl G 5s", swing_radius_m=3.0),
    BuoyMark(kind="port", light="Fl R 5s", swing_radius_m=3.0),
    BuoyMark(kind="starboard", light="Fl(2) G 6s", swing_radius_m=3.0),
]
BURST = 50  # B2's frames: more than the page's strip shows
FRAMES = [5, BURST, 0, 4]
OFF_STATION = {"offset_m": 7.3, "swing_radius_m": 3.0, "bearing_deg": 45}
NOT_INSPECTED_REASON = "the buoy's search area was in none of the 6 frames"
RESOLUTION = (192, 108)
CAMERA = "component 100: buoy-sim Camera (1920x1080)"  # progress.camera as gcs.missions.lifecycle writes it


@dataclass(frozen=True)
class InspectedMission:
    id: int
    plan: Plan
    records: list[InspectionRecord]
    frame_bytes: dict[int, bytes]  # stored frame id -> its bytes


def inspected_plan(ids: list[str] = IDS) -> Plan:
    depot = DEFAULT_HOME[:2]
    buoys = [(depot[0] + north, depot[1] + east) for north, east in OFFSETS]
    plan = sorties_plan(depot, buoys, ids, [[0, 1, 2, 3]], "test", 0.0)
    return replace(plan, marks=MARKS)


def burst_jpegs(plan: Plan, index: int, count: int) -> list[bytes]:
    """Buoy `index`'s burst as the camera's JPEGs: count frames rendered from 15 m off."""
    if count == 0:
        return []
    world = World.default(plan.buoys_lat_lon, plan.buoy_ids)
    burst = capture_burst(world, index, 15.0, 200.0, resolution=RESOLUTION, frames=count)
    jpegs = []
    for shot in burst.shots:
        out = io.BytesIO()
        Image.fromarray(shot.image).save(out, "JPEG", quality=80)
        jpegs.append(out.getvalue())
    return jpegs


def inspection_result(plan: Plan, index: int, frames: int, reason: str) -> BuoyInspection:
    """Buoy `index`'s result as the module's docstring gives it, found in `frames` frames."""
    lat, lon = plan.buoys_lat_lon[index]
    mark = plan.mark(index)
    charted = InspectedBuoy(lat=lat, lon=lon, kind=mark.kind or "unknown", light=mark.light,
                            swing_radius_m=mark.swing_radius_m)  # fmt: skip
    seen = {"observed": LatLon(lat=lat, lon=lon), "offset_m": 0.4, "frames": list(range(frames))}
    if index == 0:
        return BuoyInspection(buoy=charted, verdict="ok", findings=[], light_seen="long-flashing - W 10.0s", **seen)
    if index == 1:
        moved = LatLon(lat=lat + 0.0000464, lon=lon + 0.0000597)  # about OFF_STATION's 7.3 m to the north-east
        seen |= {"observed": moved, "offset_m": OFF_STATION["offset_m"]}
        return BuoyInspection(buoy=charted, verdict="defect", findings=[Finding(code="off_station", **OFF_STATION)],
                              light_seen="flashing . G 5.0s", **seen)  # fmt: skip
    if index == 2:
        return BuoyInspection(buoy=charted, verdict="not_inspected", findings=[], observed=None, offset_m=None,
                              light_seen=None, frames=[], reason=reason)  # fmt: skip
    light_out = Finding(code="light_out", charted="Fl(2)G.6s", seen="dark")
    return BuoyInspection(buoy=charted, verdict="defect", findings=[light_out], light_seen="dark", **seen)


def store_inspected_mission(
    storage: Storage,
    ids: list[str] = IDS,
    reason: str = NOT_INSPECTED_REASON,
    recorded: tuple[int, ...] = (0, 1, 2, 3),
    status: MissionStatus = MissionStatus.COMPLETED,
    camera: str = CAMERA,
) -> InspectedMission:
    """The four-buoy mission with the records of the buoys `recorded` (input indices) and their frames, in
    `status` (its status history as the lifecycle leaves it), inspected with `camera`."""
    plan = inspected_plan(ids)
    mission_id = storage.create_mission(FLIGHT, plan)
    records, stored = [], {}
    for index in recorded:
        record = inspection_record(storage, mission_id, plan, index, reason, stored)
        storage.set_inspection(mission_id, record)
        records.append(record)
    for step in (MissionStatus.UPLOADING, MissionStatus.UPLOADED, MissionStatus.FLYING):
        storage.set_status(mission_id, step)
    if status != MissionStatus.FLYING:
        storage.set_status(mission_id, status)
    visited = list(recorded)
    storage.set_progress(mission_id, MissionProgress(visited=len(visited), buoys=len(ids), visited_buoys=visited,
                                                     camera=camera))  # fmt: skip
    return InspectedMission(mission_id, plan, records, stored)


def inspection_record(
    storage: Storage, mission_id: int, plan: Plan, index: int, reason: str, stored: dict[int, bytes]
) -> InspectionRecord:
    """Buoy `index`'s record, its frames stored first (their ids into `stored`); the best one the burst's middle."""
    ids = []
    lat, lon = plan.buoys_lat_lon[index]
    for k, jpeg in enumerate(burst_jpegs(plan, index, FRAMES[index])):
        frame = StoredFrame(buoy=index, image_index=k, t_s=100.0 + k / 4, lat=lat, lon=lon, height_m=5.0,
                            q=(1.0, 0.0, 0.0, 0.0), file_url=f"/DCIM/{index}_{k}.jpg", found=True)  # fmt: skip
        frame_id = storage.add_frame(mission_id, frame, jpeg, 50_000_000)
        stored[frame_id] = jpeg
        ids.append(frame_id)
    return InspectionRecord(
        buoy=index,
        buoy_id=plan.buoy_ids[index],
        result=inspection_result(plan, index, len(ids), reason),
        frame_ids=ids,
        best_frame=ids[len(ids) // 2] if ids else None,
    )
