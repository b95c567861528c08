"""The one HTTP client of the LumenLink service: base URL, bearer token, requests, problem+json errors.

`ServiceClient` is the plumbing both clients are made of: `lumenlink.Client` (the engineer's calls) and
`cad_adapter.client.Pusher` (a push) subclass it and add their calls. A failed call raises the client's
``error`` class (`lumenlink.errors.LumenLinkError` unless a subclass names a subclass of it, as the adapter's
`PushError`), carrying the service's problem+json; a service that does not answer raises its ``unreachable``
class (`ServiceUnreachable`). This module imports nothing of ours but `lumenlink.errors`, so the adapter may
use it (tests/test_layout.py).
"""

from __future__ import annotations

import os
import re
from typing import Any, ClassVar

import httpx

from lumenlink.errors import LumenLinkError, ServiceUnreachable

DEFAULT_SERVER = "http://127.0.0.1:8000"


def check_server(server: str, error: type[LumenLinkError] = LumenLinkError) -> str:
    """The base URL without a trailing slash; a usage `error` saying what to add if it has no http(s) scheme."""
    if not isinstance(server, str) or not server.strip():
        raise error("the server URL is empty: give one like http://127.0.0.1:8000", usage=True)
    server = server.strip()
    if not re.match(r"^https?://", server, re.IGNORECASE):
        if "://" in server:
            raise error(f"the server URL {server!r} is not http(s): give one like http://127.0.0.1:8000",
                        usage=True)
        raise error(f"the server URL {server!r} has no scheme: add http:// (http://{server})", usage=True)
    return server.rstrip("/")


def problem_message(resp: httpx.Response, what: str) -> tuple[str, dict[str, Any]]:
    """A readable message out of an RFC 9457 problem (or any) error response, and the problem itself.

    The message reads ``"{what} failed: HTTP {status}: {title}: {detail}"`` (and the field ``errors`` where the
    problem lists them)."""
    head = f"{what} failed: HTTP {resp.status_code}"
    try:
        data = resp.json()
    except ValueError:
        return f"{head}: {resp.text[:500] or resp.reason_phrase}", {}
    if not isinstance(data, dict):
        return f"{head}: {str(data)[:500]}", {}
    parts = [str(data[k]) for k in ("title", "detail") if data.get(k)]
    if data.get("errors"):
        parts.append(str(data["errors"])[:500])
    return f"{head}: {': '.join(parts) or str(data)[:500]}", data


class ServiceClient:
    """A connection to one LumenLink service.

    Parameters
    ----------
    server : str, optional
        Base URL (``http://host:port``); default ``$LUMENLINK_SERVER``, else http://127.0.0.1:8000.
    token : str, optional
        Bearer token; default ``$LUMENLINK_TOKEN``.
    timeout : float
        Seconds per request.
    transport : httpx.BaseTransport, optional
        For tests (``httpx.MockTransport``).
    """

    #: raised for a refused call (an error status, an answer without JSON, a bad argument)
    error: ClassVar[type[LumenLinkError]] = LumenLinkError
    #: raised when no service answers (a subclass of `error` and of `ServiceUnreachable`)
    unreachable: ClassVar[type[LumenLinkError]] = ServiceUnreachable

    def __init__(self, server: str | None = None, *, token: str | None = None, timeout: float = 120.0,
                 transport: httpx.BaseTransport | None = None) -> None:
        self.server = check_server(server or os.environ.get("LUMENLINK_SERVER") or DEFAULT_SERVER, self.error)
        self.token = token if token is not None else os.environ.get("LUMENLINK_TOKEN")
        headers = {"Authorization": f"Bearer {self.token}"} if self.token else {}
        self.http = httpx.Client(base_url=self.server, timeout=timeout, transport=transport, headers=headers)

    def close(self) -> None:
        self.http.close()

    def __enter__(self) -> ServiceClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _request(self, method: str, url: str, **kwargs: Any) -> httpx.Response:
        """One request; `unreachable` when the service does not answer (or not in time)."""
        try:
            return self.http.request(method, url, **kwargs)
        except httpx.TimeoutException as exc:
            raise self.unreachable(f"the service at {self.server} did not answer {method} {url} in time "
                                   f"({type(exc).__name__})") from exc
        except httpx.TransportError as exc:
            raise self.unreachable(f"cannot reach the service at {self.server} ({exc}); is `lumenlink serve` "
                                   "running there?") from exc

    def _refused(self, resp: httpx.Response, what: str) -> LumenLinkError:
        message, problem = problem_message(resp, what)
        return self.error(message, status=resp.status_code, problem=problem,
                          usage=400 <= resp.status_code < 500 and resp.status_code != 409)

    def _call(self, method: str, url: str, what: str, ok: tuple[int, ...] = (200, 201, 204), **kwargs: Any) -> Any:
        """A request whose answer is JSON (None for an empty answer: 204 No Content, a removal's); `error` for a
        status not in `ok`."""
        return self._answer(self._request(method, url, **kwargs), what, ok)

    def _answer(self, resp: httpx.Response, what: str, ok: tuple[int, ...] = (200, 201, 204)) -> Any:
        """The JSON of an answer (None for an empty one); `error` for a status not in `ok` or a body not JSON."""
        if resp.status_code not in ok:
            raise self._refused(resp, what)
        if resp.status_code == 204 or not resp.content:
            return None
        try:
            return resp.json()
        except ValueError as exc:
            raise self.error(f"{what}: the service answered HTTP {resp.status_code} without JSON",
                             status=resp.status_code) from exc

    def _bytes(self, url: str, what: str, params: dict[str, Any] | None = None) -> bytes:
        """A GET whose answer is bytes (a file, an image); `error` for a status other than 200."""
        resp = self._request("GET", url, params=params)
        if resp.status_code != 200:
            raise self._refused(resp, what)
        return resp.content
