"""ASGI middleware: a request body size limit (413), a budget of body bytes in flight (503), a bearer token
(401; a browser signs in once for a cookie instead, see `BearerToken`) and one log line per request.

All are plain ASGI so they see the raw byte stream: the limit refuses a body whose ``Content-Length`` is too
large before reading it, and stops a chunked body as soon as it passes the limit, answering with a
problem+json 413. The budget counts the bytes of every body being received at once (a declared length is
reserved up front, a chunked body counts as it arrives) and answers 503 with ``Retry-After`` to the body that
would pass it: parallel uploads cannot hold more than the budget in memory.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import time
from typing import Any
from urllib.parse import quote

from service.errors import TooLarge, Unavailable

log = logging.getLogger("lumenlink.service.requests")

Scope = dict[str, Any]


class _TooLarge(TooLarge):
    """Raised from inside `receive`: the app's handler turns it into the same 413 problem (with `limit`) as a
    body refused by its declared length."""


class _Busy(Unavailable):
    """Raised from inside `receive` where a chunked body would pass the budget of bytes in flight; the app's
    handler answers it as `_problem_busy` does."""

    headers = {"Retry-After": "1"}


def _problem(status: int, title: str, detail: str, limit: int, extra: tuple = ()) -> tuple[dict, bytes]:
    body = json.dumps({"type": "about:blank", "title": title, "status": status, "detail": detail,
                       "limit": limit}).encode()
    start = {"type": "http.response.start", "status": status,
             "headers": [(b"content-type", b"application/problem+json"),
                         (b"content-length", str(len(body)).encode()), (b"connection", b"close"), *extra]}
    return start, body


def _problem_413(limit: int) -> tuple[dict, bytes]:
    return _problem(413, "Content too large", f"the request body exceeds the limit of {limit} bytes", limit)


def _busy_detail(budget: int) -> str:
    return (f"the service is receiving {budget} bytes of request bodies at once, its limit: send this body again "
            f"in a moment")


def _problem_busy(budget: int) -> tuple[dict, bytes]:
    return _problem(503, "Service unavailable", _busy_detail(budget), budget, ((b"retry-after", b"1"),))


class BodyLimit:
    """Refuse request bodies larger than `max_bytes` with 413, and bodies that would take the bytes being received
    at once beyond `in_flight` with 503 (problem+json)."""

    def __init__(self, app: Any, max_bytes: int, in_flight: int | None = None) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.in_flight = max(in_flight or max_bytes, max_bytes)
        self.receiving = 0   # bytes of the bodies being received now (one event loop: no lock)

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.max_bytes
        declared = 0
        for name, value in scope.get("headers", []):
            if name == b"content-length":
                try:
                    declared = max(int(value), 0)
                except ValueError:
                    declared = 0
                if declared > limit:
                    await self._refuse(send, _problem_413(limit))
                    return
        if self.receiving + declared > self.in_flight:
            await self._refuse(send, _problem_busy(self.in_flight))
            return
        self.receiving += declared
        held = declared    # bytes this request holds of the budget
        received = 0
        started = False

        async def limited_receive() -> dict:
            nonlocal received, held
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise _TooLarge(f"the request body exceeds the limit of {limit} bytes", limit=limit)
                if received > held:   # a chunked body (or one longer than declared): count what arrives
                    if self.receiving + received - held > self.in_flight:
                        raise _Busy(_busy_detail(self.in_flight), limit=self.in_flight)
                    self.receiving += received - held
                    held = received
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
                await self._refuse(send, _problem_413(limit))
        except _Busy:
            if not started:
                await self._refuse(send, _problem_busy(self.in_flight))
        finally:
            self.receiving -= held

    @staticmethod
    async def _refuse(send: Any, problem: tuple[dict, bytes]) -> None:
        start, body = problem
        await send(start)
        await send({"type": "http.response.body", "body": body})


#: the cookie a browser gets by signing in (`session_value` of the token)
SESSION_COOKIE = "lumenlink_session"


def session_value(token: str) -> str:
    """What the sign-in cookie holds: an HMAC-SHA256 keyed by the token, never the token itself."""
    return hmac.new(token.encode(), b"lumenlink pages session", hashlib.sha256).hexdigest()


def _cookie(headers: list[tuple[bytes, bytes]], name: str) -> bytes:
    for key, value in headers:
        if key == b"cookie":
            for part in value.split(b";"):
                k, _, v = part.strip().partition(b"=")
                if k == name.encode():
                    return v
    return b""


class BearerToken:
    """Refuse (401, problem+json, ``WWW-Authenticate: Bearer``) every request without ``Authorization: Bearer
    <token>``, except the health probe, the API's documentation and the sign-in page (`OPEN_PATHS`) and the static
    scripts and styles the docs and pages load (`OPEN_PREFIX`, files of npm packages and of ``service/web/src``):
    they hold no data.

    A browser cannot add that header to a page it opens, nor to an event stream, so a person signs in once at
    ``/sign-in`` (`service.routes.pages`) with the token and gets the cookie `SESSION_COOKIE` (HttpOnly,
    SameSite=Strict: other sites' pages cannot send it), which counts as the header. A page opened without either
    (a GET that accepts text/html) is sent to the sign-in page instead of a 401 body."""

    OPEN_PATHS = ("/health", "/docs", "/docs/oauth2-redirect", "/redoc", "/openapi.json", "/sign-in", "/sign-out")
    OPEN_PREFIX = "/static/"

    def __init__(self, app: Any, token: str) -> None:
        self.app = app
        self.expected = f"Bearer {token}".encode()
        self.session = session_value(token).encode()

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        path = scope.get("path", "")
        if scope["type"] != "http" or path in self.OPEN_PATHS or path.startswith(self.OPEN_PREFIX):
            await self.app(scope, receive, send)
            return
        headers = scope.get("headers", [])
        given = next((v for k, v in headers if k == b"authorization"), b"")
        cookie = _cookie(headers, SESSION_COOKIE)
        if hmac.compare_digest(given, self.expected) or (cookie and hmac.compare_digest(cookie, self.session)):
            await self.app(scope, receive, send)
            return
        accept = next((v for k, v in headers if k == b"accept"), b"")
        if scope.get("method") == "GET" and b"text/html" in accept and not given:
            query = scope.get("query_string", b"").decode("latin-1")
            target = quote(path + (f"?{query}" if query else ""), safe="")
            await send({"type": "http.response.start", "status": 303,
                        "headers": [(b"location", f"/sign-in?next={target}".encode()), (b"content-length", b"0")]})
            await send({"type": "http.response.body", "body": b""})
            return
        why = ("the sign-in cookie is not this service's token's" if cookie and not given
               else "no Authorization header" if not given else "the token does not match")
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
