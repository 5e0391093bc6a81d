"""WebSocket /ws: the vehicle's state and the active mission's progress, pushed to every client.

Push-only: the service reads nothing a client sends on it. With an API token set, a client must present it
(gcs.api.security); a browser page of a foreign origin is refused either way (cross-site WebSocket hijacking)."""

from __future__ import annotations

import contextlib
from typing import Annotated

from fastapi import APIRouter, Depends, WebSocket, WebSocketDisconnect, status
from starlette.requests import HTTPConnection

from gcs.api.live_feed import LiveFeed
from gcs.api.routes.deps import ServiceDep, SettingsDep
from gcs.api.security import accepted_subprotocol, websocket_refusal

router = APIRouter(tags=["live"])


async def live_feed(connection: HTTPConnection, service: ServiceDep, settings: SettingsDep) -> LiveFeed:
    """The app's one live feed (made with the first client; on the event loop, so made once): every /ws client
    sends the same encoded states."""
    state = connection.app.state
    if getattr(state, "live_feed", None) is None:
        state.live_feed = LiveFeed(service.live, settings.live_rate_hz)
    return state.live_feed


@router.websocket("/ws")
async def live(websocket: WebSocket, settings: SettingsDep, feed: Annotated[LiveFeed, Depends(live_feed)]) -> None:
    """The live state at the service's live rate. One producer encodes each state once for every client; a
    slow client only misses intermediate states (every message is the whole latest state) and never delays
    the others (gcs.api.live_feed)."""
    if (refusal := websocket_refusal(websocket, settings)) is not None:
        # closing before accepting answers the handshake with HTTP 403
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason=refusal)
        return
    await websocket.accept(subprotocol=accepted_subprotocol(websocket))
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        await feed.stream(websocket.send_text)
