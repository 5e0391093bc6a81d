"""WebSocket /ws: the vehicle's state and the active mission's progress, pushed to every client."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from gcs.routes.deps import ServiceDep, SettingsDep

router = APIRouter(tags=["live"])


@router.websocket("/ws")
async def live(websocket: WebSocket, service: ServiceDep, settings: SettingsDep) -> None:
    """Each client gets its own paced loop, so a slow client never delays the others; a client that cannot
    keep up only misses intermediate states, since every message is the whole latest state."""
    await websocket.accept()
    period = 1.0 / settings.live_rate_hz
    loop = asyncio.get_running_loop()
    next_time = loop.time()
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while True:
            await websocket.send_json(service.live())
            next_time = max(next_time + period, loop.time())
            await asyncio.sleep(next_time - loop.time())
