"""`kill -USR1 <pid>`: the running service writes where it is to its log, without stopping.

What an operator (or a test that waited too long for the service to stop) needs to say why it hangs: every
thread's Python stack, written by the interpreter itself (`faulthandler`, so that a thread stuck in a blocking
call, the event loop's included, answers too), then every asyncio task's stack (what each coroutine awaits),
logged from the event loop once it runs.
"""

from __future__ import annotations

import asyncio
import faulthandler
import io
import logging
import signal
import sys
from types import FrameType

log = logging.getLogger(__name__)

DUMP_SIGNAL = signal.SIGUSR1


def log_task_stacks() -> None:
    """Log each asyncio task of the running loop with the stack it is suspended in."""
    tasks = asyncio.all_tasks()
    for task in sorted(tasks, key=lambda t: t.get_name()):
        text = io.StringIO()
        task.print_stack(file=text)
        log.warning("%s", text.getvalue().rstrip())
    log.warning("stack dump: %d asyncio task(s)", len(tasks))


def _on_dump_signal(_signum: int, _frame: FrameType | None) -> None:
    # Python runs this in the main thread: the event loop's under uvicorn.run
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        return  # no loop yet (starting) or any more (stopped): the threads' stacks say it all
    loop.call_soon_threadsafe(log_task_stacks)


def install_stack_dump() -> None:
    """Before the service's event loop starts, in the main thread: DUMP_SIGNAL dumps threads, then tasks."""
    signal.signal(DUMP_SIGNAL, _on_dump_signal)
    # faulthandler writes the threads from its C handler at once, then chains to the Python handler above
    faulthandler.register(DUMP_SIGNAL, file=sys.stderr, all_threads=True, chain=True)
