"""The errors of talking to the LumenLink service: one hierarchy for every client of it.

`LumenLinkError` is the root (the service's problem+json in ``problem``, its HTTP ``status``, ``usage`` when the
call itself was wrong); `ServiceUnreachable` is the one raised when no service answers. The CAD adapter's push
errors (`cad_adapter.errors.PushError`, `ServiceUnavailable`, `RevisionConflict`) are subclasses of these as well
as of its own root, so a caller of either package catches one family. This module imports nothing (the adapter
imports it without loading httpx).
"""

from __future__ import annotations

from typing import Any


class LumenLinkError(Exception):
    """Anything that went wrong talking to the service.

    Attributes
    ----------
    status : int or None
        The HTTP status of the service's answer; None when the client refused before asking (a bad
        argument, a scene name no scene has) or no service answered.
    problem : dict
        The service's RFC 9457 problem (``title``, ``detail``, and extensions such as ``errors`` or
        ``did_you_mean``); empty when the client refused by itself.
    usage : bool
        The request itself was wrong (a bad argument, an unknown name, a 4xx other than 409): fix the call.
    """

    def __init__(self, message: str, *, status: int | None = None, problem: dict[str, Any] | None = None,
                 usage: bool = False) -> None:
        super().__init__(message)
        self.status = status
        self.problem = problem or {}
        self.usage = usage

    @property
    def did_you_mean(self) -> list[str]:
        return list(self.problem.get("did_you_mean") or [])


class ServiceUnreachable(LumenLinkError):
    """No service answered at the server's address (or not in time)."""
