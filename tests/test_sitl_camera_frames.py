"""The camera's frames made off the loop (a paced vehicle) against those made in it (lockstep): the same pixels for
the same instant, CAMERA_IMAGE_CAPTURED only once the file is written, in order, and a dead worker survived."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
from PIL import Image

from sitl_quad.camera import CameraSpec
from sitl_quad.config import VehicleConfig
from sitl_quad.gimbal import Gimbal
from sitl_quad.mavlink.camera import CameraComponent
from sitl_quad.vehicle import Vehicle
from uavcore.buoy_world import World
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import mavlink

pytestmark = pytest.mark.integration  # a worker process

SPEC = CameraSpec("buoy-sim", "SimCam small", 4.5, 6.17, 6.17 * 9 / 16, 320, 180)
FRAME = LocalFrame(*DEFAULT_HOME)


class RecordingLink:
    """The camera's link: keeps what it sends; a CAMERA_IMAGE_CAPTURED must find its file complete on disk."""

    def __init__(self, image_dir: Path) -> None:
        self.image_dir = image_dir
        self.sent: list = []
        self.sysid, self.compid = 1, 1

    def add_component(self, compid: int) -> None:
        pass

    def send(self, msg, peer=None, compid=None) -> None:
        if msg.get_type() == "CAMERA_IMAGE_CAPTURED" and msg.capture_result == 1:
            with Image.open(self.image_dir / f"IMG_{msg.image_index:06d}.jpg") as image:
                image.load()  # the whole JPEG is there, as a client downloading it on receipt needs
        self.sent.append(msg)

    def of_type(self, kind: str) -> list:
        return [m for m in self.sent if m.get_type() == kind]


def world() -> World:
    lat, lon, _ = FRAME.from_ned(20.0, 0.0, 0.0)
    return World.default([[lat, lon]], ["B0"])


def camera(tmp_path: Path, name: str, in_loop: bool) -> tuple[Vehicle, CameraComponent, RecordingLink]:
    vehicle = Vehicle(VehicleConfig(), home=DEFAULT_HOME, seed=4)
    image_dir = tmp_path / name
    image_dir.mkdir()
    link = RecordingLink(image_dir)
    gimbal = Gimbal()
    gimbal.pitch = -0.2
    component = CameraComponent(
        vehicle, link, gimbal, image_dir, world(), spec=SPEC, boot_unix_us=0, frames_in_loop=in_loop
    )
    return vehicle, component, link


def capture(vehicle: Vehicle, component: CameraComponent, ticks: int) -> None:
    """The server's order: tick, capture what is due, then poll (reports of finished frames)."""
    assert component.start_capture(0, 0.1, 5, 0).name == "ACCEPTED"
    for _ in range(ticks):
        vehicle.tick()
        component.capture_due()
        component.report_finished()


def test_frames_made_off_the_loop_are_those_made_in_it_and_reported_once_written(tmp_path):
    in_loop = camera(tmp_path, "loop", in_loop=True)
    worker = camera(tmp_path, "worker", in_loop=False)
    capture(*in_loop[:2], ticks=30)
    capture(*worker[:2], ticks=30)
    # in the loop every report follows its tick at once; off it, later
    reports = in_loop[2].of_type("CAMERA_IMAGE_CAPTURED")
    assert [m.time_boot_ms for m in reports] == [20, 120, 220, 320, 420]
    deadline = time.monotonic() + 30
    while worker[1].worker.in_hand and time.monotonic() < deadline:
        worker[1].report_finished(timeout=0.5)
    worker[1].close()
    late = worker[2].of_type("CAMERA_IMAGE_CAPTURED")
    # the same reports (instant, geotag, attitude, index, result) and, byte for byte, the same files
    assert [m.to_dict() for m in late] == [m.to_dict() for m in reports]
    for msg in reports:
        name = f"IMG_{msg.image_index:06d}.jpg"
        assert (tmp_path / "worker" / name).read_bytes() == (tmp_path / "loop" / name).read_bytes()
    # each report is followed by a capture status counting the reported images
    statuses = [m for m in worker[2].sent if m.get_type() in ("CAMERA_IMAGE_CAPTURED", "CAMERA_CAPTURE_STATUS")]
    counts = [m.image_count for m in statuses if m.get_type() == "CAMERA_CAPTURE_STATUS"]
    assert counts[-5:] == [1, 2, 3, 4, 5]
    stats = worker[1].stats()
    assert stats["frames_made"] == "worker" and stats["images"] == 5 and not stats["worker_lost"]


def test_a_dead_worker_fails_its_frames_in_hand_and_the_loop_makes_the_next(tmp_path):
    vehicle, component, link = camera(tmp_path, "images", in_loop=False)
    assert component.worker is not None
    os.kill(component.worker._process.pid, signal.SIGKILL)
    component.worker._process.join(10)
    capture(vehicle, component, ticks=30)  # the first capture finds the worker gone
    reports = link.of_type("CAMERA_IMAGE_CAPTURED")
    assert [m.image_index for m in reports] == [0, 1, 2, 3, 4]
    assert all(m.capture_result == 1 for m in reports)
    assert component.worker is None and component.stats()["worker_lost"]


def test_frames_in_hand_when_the_worker_dies_are_reported_failed(tmp_path):
    vehicle, component, link = camera(tmp_path, "images", in_loop=False)
    assert component.start_capture(0, 0.1, 2, 0).name == "ACCEPTED"
    os.kill(component.worker._process.pid, signal.SIGSTOP)
    vehicle.tick()
    component.capture_due()  # image 0 handed over, never to be made
    os.kill(component.worker._process.pid, signal.SIGKILL)
    component.worker._process.join(10)
    for _ in range(10):
        vehicle.tick()
        component.capture_due()
        component.report_finished()
    results = [(m.image_index, m.capture_result) for m in link.of_type("CAMERA_IMAGE_CAPTURED")]
    assert results == [(0, 0), (1, 1)]  # lost, then made in the loop
    assert component.request_message(mavlink.MAVLINK_MSG_ID_CAMERA_IMAGE_CAPTURED, 0).name == "ACCEPTED"
