"""A limit on request bodies: 413 for a body larger than the settings' max_body_bytes, before any route reads it.

Checked twice, because a client need not say how long its body is: a Content-Length above the limit is refused
before anything is read, and a body sent in chunks (Transfer-Encoding: chunked, no Content-Length) is counted
as it arrives and refused as soon as it passes the limit. The body is read here, up to the limit, and handed to
the application afterwards, so a route never sees a partial body and never starts answering one that is too big.
A path may have a limit of its own (POST /imports takes S-57 cells, larger than any other body).
"""

from __future__ import annotations

from collections.abc import Mapping

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from gcs.api.errors import error_bytes


class BodyTooLargeError(Exception):
    pass


class BodyLimitMiddleware:
    def __init__(self, app: ASGIApp, max_bytes: int, path_limits: Mapping[str, int] | None = None) -> None:
        self.app, self.max_bytes, self.path_limits = app, max_bytes, dict(path_limits or {})

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.path_limits.get(scope["path"], self.max_bytes)
        try:
            self._check_declared_length(scope, limit)
            body = await self._read_body(receive, limit)
        except BodyTooLargeError:
            await refuse_too_large(send, limit)
            return
        await self.app(scope, _replaying(body, receive), send)

    def _check_declared_length(self, scope: Scope, limit: int) -> None:
        for name, value in scope["headers"]:
            if name == b"content-length" and (not value.isdigit() or int(value) > limit):
                raise BodyTooLargeError  # a length that is no number cannot be trusted either

    async def _read_body(self, receive: Receive, limit: int) -> bytes:
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":  # the client went away: the route sees an empty body
                return b"".join(chunks)
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                raise BodyTooLargeError
            chunks.append(chunk)
            if not message.get("more_body", False):
                return b"".join(chunks)


def too_large_detail(limit: int) -> str:
    """The 413 answer's detail, the same wherever the limit is found out."""
    return f"the request body is larger than {limit} bytes"


async def refuse_too_large(send: Send, limit: int) -> None:
    detail = error_bytes(413, ("body",), too_large_detail(limit))
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(detail)).encode())]
    # Connection: close: the rest of a body that was not read must not be taken for the next request
    headers.append((b"connection", b"close"))
    await send({"type": "http.response.start", "status": 413, "headers": headers})
    await send({"type": "http.response.body", "body": detail})


def _replaying(body: bytes, receive: Receive) -> Receive:
    """The body, already read, as one message; then whatever the client sends next (its disconnect)."""
    pending = True

    async def replay() -> Message:
        nonlocal pending
        if pending:
            pending = False
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replay
