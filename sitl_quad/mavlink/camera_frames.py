"""The camera's frames made into files: rendered (sitl_quad.camera_render), JPEG-encoded and written.

A `FrameJob` is everything a frame needs, taken at its simulated instant (the camera's pose, the scene, where the
file goes), so it can be made anywhere later and still show that instant. Two ways to make it:
- in the loop (`write_frame`): before the vehicle flies on, as lockstep needs (a frame costs tens of ms);
- in a worker process (`FrameWorker`), for a paced vehicle: its loop only hands the job over (a pipe write) and
  collects what is finished when it polls, so its ticks stay on time while the camera captures. A process, not a
  thread: rendering is mostly Python and numpy holding the GIL, and a thread would delay the loop's ticks.
  Jobs are made in the order given and their results come back in that order. The worker runs at a lower
  priority (nice 10): where the machine's cores are busy, its frames come later rather than the loop's ticks.
  It is spawned (no state inherited), so a program that builds a paced vehicle must guard its main module.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path

from sitl_quad.camera_render import CameraPose, Intrinsics, Scene, encode_jpeg, render

log = logging.getLogger(__name__)

# at most this long, all told, for the frames still being made and the worker's exit when the vehicle stops: a
# vehicle told to stop (SIGTERM) must be gone well within the 10 s a supervisor gives it before SIGKILL
STOP_WAIT_S = 4.0
WORKER_NICENESS = 10  # the loop's ticks come first: on a busy machine the worker's frames wait, not the ticks


@dataclass(frozen=True)
class FrameJob:
    index: int
    path: Path
    pose: CameraPose
    intrinsics: Intrinsics
    scene: Scene
    quality: int


@dataclass(frozen=True)
class FrameResult:
    index: int
    ok: bool
    seconds: float  # wall time spent making it (render, JPEG, write)


def write_frame(job: FrameJob) -> FrameResult:
    """Render, encode and write one frame; a failure is logged and reported, never raised: a full or vanished
    disk or a renderer bug must not stop the vehicle, the capture is reported failed instead."""
    started = time.perf_counter()
    try:
        job.path.write_bytes(encode_jpeg(render(job.pose, job.intrinsics, job.scene), job.quality))
        ok = True
    except OSError as exc:
        log.warning("image %s not written: %s", job.path.name, exc)
        ok = False
    except Exception:
        log.exception("image %s not rendered", job.path.name)
        ok = False
    return FrameResult(job.index, ok, time.perf_counter() - started)


class WorkerGoneError(RuntimeError):
    """The worker process died (its frames in hand are lost)."""


class FrameWorker:
    """One worker process making frames in order (module docstring)."""

    def __init__(self, warm_up: FrameJob | None = None) -> None:
        """warm_up: a frame rendered (not written) at once, so the first real one does not pay for the
        renderer's first-call costs (its cached grids for these intrinsics)."""
        context = multiprocessing.get_context("spawn")  # nothing inherited from the vehicle's process
        self._connection, child = context.Pipe()
        self._process = context.Process(target=_serve, args=(child, warm_up), name="camera-frames", daemon=True)
        self._process.start()
        child.close()
        self.in_hand = 0  # jobs handed over and not yet returned

    def submit(self, job: FrameJob) -> None:
        try:
            self._connection.send(job)
        except OSError as exc:  # BrokenPipeError: the worker is gone
            raise WorkerGoneError(f"the camera's frame worker is gone: {exc}") from exc
        self.in_hand += 1

    def finished(self, timeout: float = 0.0) -> list[FrameResult]:
        """The results ready now (or within `timeout` seconds for the first), in the order the jobs came."""
        results = []
        try:
            while self.in_hand and self._connection.poll(timeout if not results else 0.0):
                results.append(self._connection.recv())
                self.in_hand -= 1
        except (EOFError, OSError) as exc:
            raise WorkerGoneError(f"the camera's frame worker is gone: {exc}") from exc
        if self.in_hand and not results and not self._process.is_alive():
            raise WorkerGoneError(f"the camera's frame worker exited with {self._process.exitcode}")
        return results

    def close(self) -> list[FrameResult]:
        """Stop the worker after the frames in hand (STOP_WAIT_S for all of it); returns their results."""
        results = []
        deadline = time.monotonic() + STOP_WAIT_S
        try:
            while self.in_hand and time.monotonic() < deadline:
                results += self.finished(timeout=max(0.0, deadline - time.monotonic()))
            self._connection.send(None)
        except (WorkerGoneError, OSError):
            pass
        self._process.join(max(0.1, deadline - time.monotonic()))
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        self._connection.close()
        return results


def _serve(connection: Connection, warm_up: FrameJob | None) -> None:
    """The worker's loop: make each job, send its result; None or a closed pipe (the vehicle gone) ends it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the vehicle stops it, after its frames in hand
    os.nice(WORKER_NICENESS)
    if warm_up is not None:
        try:
            render(warm_up.pose, warm_up.intrinsics, warm_up.scene)
        except Exception:  # a real frame will say what is wrong
            log.debug("warm-up frame failed", exc_info=True)
    while True:
        try:
            job = connection.recv()
            if job is None:
                return
            connection.send(write_frame(job))
        except (EOFError, OSError):  # the vehicle is gone
            return
