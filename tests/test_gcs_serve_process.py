"""`python -m gcs serve` as the process an operator runs: its log says when things happened, SIGUSR1 makes it
write where it is without stopping it, and SIGTERM stops it cleanly even while a live-feed client holds on."""

from __future__ import annotations

import json
import re
import signal
import time
import urllib.request
from pathlib import Path

import pytest
from service_process import running_service
from websockets.sync.client import connect

pytestmark = pytest.mark.integration

TIMESTAMPED = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} (INFO|WARNING|ERROR) ", re.MULTILINE)


def wait_for_text(log: Path, text: str, timeout_s: float = 60.0) -> str:
    deadline = time.monotonic() + timeout_s
    while text not in (content := log.read_text(errors="replace")):
        assert time.monotonic() < deadline, f"{text!r} not in the log:\n{content}"
        time.sleep(0.1)
    return content


def test_sigusr1_writes_every_threads_and_tasks_stack_to_the_log_and_the_service_goes_on(tmp_path):
    log = tmp_path / "serve.log"
    with running_service(tmp_path / "gcs.sqlite", log) as (url, process):
        process.send_signal(signal.SIGUSR1)
        content = wait_for_text(log, "stack dump:")
        # the threads, from faulthandler: the main thread runs the event loop, called from `gcs serve`
        assert "Current thread" in content and 'gcs/cli.py", line' in content, content
        # the tasks, from the loop: the link's receive task among them, with the coroutine it is suspended in
        assert re.search(r"stack dump: [1-9]\d* asyncio task\(s\)", content), content
        assert "Stack for <Task" in content and "gcs/vehicle/" in content, content
        with urllib.request.urlopen(f"{url}/vehicle", timeout=10) as answer:
            assert answer.status == 200
        assert process.poll() is None


def test_sigterm_stops_the_service_while_a_live_feed_client_holds_its_connection(tmp_path):
    log = tmp_path / "serve.log"
    with (
        running_service(tmp_path / "gcs.sqlite", log) as (url, process),
        connect(url.replace("http://", "ws://") + "/ws") as live,
    ):
        assert json.loads(live.recv(timeout=60))["type"] == "state"
        process.send_signal(signal.SIGTERM)
        code = process.wait(60)  # the client neither reads nor closes meanwhile
    content = log.read_text()
    # after its shutdown uvicorn ends by the signal it caught, as a process that had not caught it would
    assert code == -signal.SIGTERM, content
    assert "Application shutdown complete" in content, content
    # every line of ours and uvicorn's says when it was written
    lines = [line for line in content.splitlines() if line and not line.startswith(" ")]
    assert lines and all(TIMESTAMPED.match(line) for line in lines), content
