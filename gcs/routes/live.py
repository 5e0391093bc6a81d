"""WebSocket /ws: the vehicle's state and the active mission's progress, pushed to every client.

Push-only: the service reads nothing a client sends on it. With an API token set, a client must present it
(gcs.security); a browser page of a foreign origin is refused either way (cross-site WebSocket hijacking)."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect, status

from gcs.routes.deps import ServiceDep, SettingsDep
from gcs.security import accepted_subprotocol, websocket_refusal

router = APIRouter(tags=["live"])


@router.websocket("/ws")
async def live(websocket: WebSocket, service: ServiceDep, settings: SettingsDep) -> None:
    """Each client gets its own paced loop, so a slow client never delays the others; a client that cannot
    keep up only misses intermediate states, since every message is the whole latest state."""
    if (refusal := websocket_refusal(websocket, settings)) is not None:
        # closing before accepting answers the handshake with HTTP 403
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason=refusal)
        return
    await websocket.accept(subprotocol=accepted_subprotocol(websocket))
    period = 1.0 / settings.live_rate_hz
    loop = asyncio.get_running_loop()
    next_time = loop.time()
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while True:
            await websocket.send_json(service.live())
            next_time = max(next_time + period, loop.time())
            await asyncio.sleep(next_time - loop.time())
