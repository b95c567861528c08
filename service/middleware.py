"""ASGI middleware: a request body size limit (413) and one log line per request.

Both are plain ASGI so they see the raw byte stream: the limit refuses a body whose
``Content-Length`` is too large before reading it, and stops a chunked body as soon as it
passes the limit, answering with a problem+json 413.
"""

from __future__ import annotations

import hmac
import json
import logging
import time
from typing import Any

from service.errors import TooLarge

log = logging.getLogger("lumenlink.service.requests")

Scope = dict[str, Any]


class _TooLarge(TooLarge):
    """Raised from inside `receive`: the app's handler turns it into the same 413 problem (with `limit`) as a
    body refused by its declared length."""


def _problem_413(limit: int) -> tuple[dict, bytes]:
    body = json.dumps({"type": "about:blank", "title": "Content too large", "status": 413,
                       "detail": f"the request body exceeds the limit of {limit} bytes", "limit": limit}).encode()
    start = {"type": "http.response.start", "status": 413,
             "headers": [(b"content-type", b"application/problem+json"),
                         (b"content-length", str(len(body)).encode()), (b"connection", b"close")]}
    return start, body


class BodyLimit:
    """Refuse request bodies larger than `max_bytes` with 413 (problem+json)."""

    def __init__(self, app: Any, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.max_bytes
        for name, value in scope.get("headers", []):
            if name == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    declared = 0
                if declared > limit:
                    await self._refuse(send)
                    return
        received = 0
        started = False

        async def limited_receive() -> dict:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise _TooLarge(f"the request body exceeds the limit of {limit} bytes", limit=limit)
            return message

        async def tracking_send(message: dict) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except _TooLarge:
            if not started:
                await self._refuse(send)

    async def _refuse(self, send: Any) -> None:
        start, body = _problem_413(self.max_bytes)
        await send(start)
        await send({"type": "http.response.body", "body": body})


class BearerToken:
    """Refuse (401, problem+json, ``WWW-Authenticate: Bearer``) every request without ``Authorization: Bearer
    <token>``, except the health probe and the API's documentation (`OPEN_PATHS`): they hold no data."""

    OPEN_PATHS = ("/health", "/docs", "/docs/oauth2-redirect", "/redoc", "/openapi.json")

    def __init__(self, app: Any, token: str) -> None:
        self.app = app
        self.expected = f"Bearer {token}".encode()

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope.get("path") in self.OPEN_PATHS:
            await self.app(scope, receive, send)
            return
        given = next((v for k, v in scope.get("headers", []) if k == b"authorization"), b"")
        if hmac.compare_digest(given, self.expected):
            await self.app(scope, receive, send)
            return
        why = "no Authorization header" if not given else "the token does not match"
        body = json.dumps({"type": "about:blank", "title": "Unauthorized", "status": 401,
                           "detail": f"{why}: send 'Authorization: Bearer <LUMENLINK_TOKEN>'"}).encode()
        await send({"type": "http.response.start", "status": 401,
                    "headers": [(b"content-type", b"application/problem+json"),
                                (b"content-length", str(len(body)).encode()), (b"www-authenticate", b"Bearer")]})
        await send({"type": "http.response.body", "body": body})


class RequestLog:
    """Log method, path, status and milliseconds of every request (logger ``lumenlink.service.requests``)."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        status = [500]

        async def tracking_send(message: dict) -> None:
            if message["type"] == "http.response.start":
                status[0] = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, tracking_send)
        finally:
            log.info("%s %s %d %.1f ms", scope.get("method"), scope.get("path"), status[0],
                     (time.perf_counter() - t0) * 1e3)
