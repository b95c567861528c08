"""Errors of the CAD adapter: one root, each also the builtin it refines.

Every error says what went wrong in words a user can act on; where a node is concerned it carries the
node's occurrence path (and UUID when one is known) so that the caller can point at it.

Talking to the service has one error hierarchy for every client (`lumenlink.errors`): `PushError` is a
`LumenLinkError` as well as a `CadAdapterError` (with the service's ``status`` and ``problem``),
`ServiceUnavailable` a `ServiceUnreachable`, `RevisionConflict` a `PushError` with status 409.
"""

from __future__ import annotations

from typing import Any

from lumenlink.errors import LumenLinkError, ServiceUnreachable


class CadAdapterError(ValueError):
    """Root of the adapter's errors.

    Parameters
    ----------
    message : str
        What went wrong and, where possible, what to do about it.
    node : str, optional
        Occurrence path of the node concerned.
    uuid : str, optional
        UUID of the node concerned, when known.
    """

    def __init__(self, message: str, *, node: str | None = None, uuid: str | None = None) -> None:
        super().__init__(message)
        self.node = node
        self.uuid = uuid


class CadImportError(CadAdapterError):
    """The document cannot be read: missing, unreadable, not STEP, or holding no shapes."""


class EmptyDocumentError(CadImportError):
    """The document was read but holds no shape at all."""


class TessellationError(CadAdapterError):
    """A shape could not be tessellated (bad settings, or OCCT failed on it)."""


class IdentityError(CadAdapterError):
    """The sidecar file is unreadable or inconsistent, or a carried UUID is used twice."""


class PushError(CadAdapterError, LumenLinkError):
    """Talking to the service failed; nothing was half-pushed.

    Attributes
    ----------
    status, problem, usage
        As `lumenlink.errors.LumenLinkError`'s: the service's HTTP status and problem+json, and whether the
        call itself was wrong.
    """

    def __init__(self, message: str, *, status: int | None = None, problem: dict[str, Any] | None = None,
                 usage: bool = False) -> None:
        CadAdapterError.__init__(self, message)
        self.status = status
        self.problem = problem or {}
        self.usage = usage


class ServiceUnavailable(PushError, ServiceUnreachable):
    """The service cannot be reached (down, wrong URL, timed out)."""


class RevisionConflict(PushError):
    """The scene changed on the service since the revision this push was based on (HTTP 409).

    Attributes
    ----------
    current_revision : int or None
        The scene's revision as re-read after the conflict.
    """

    def __init__(self, message: str, *, current_revision: int | None = None,
                 problem: dict[str, Any] | None = None) -> None:
        super().__init__(message, status=409, problem=problem)
        self.current_revision = current_revision
