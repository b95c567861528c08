"""What `lumenlink.Client`'s parts stand on: the connection (`lumenlink.http.ServiceClient`) and the lookups that
`Client` itself defines (a scene's id from its name, a sensor's records, following a job), declared here so that each
part (`client_assignments`, `client_elements`, `client_images`, `client_results`) is checked as what it is."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from lumenlink.http import ServiceClient


class ClientBase(ServiceClient):
    """The base of `Client`'s parts; `Client` defines what is declared here."""

    if TYPE_CHECKING:
        def _sid(self, scene: str | dict) -> str: ...

        def _sensor_ids(self, sid: str, sensor: str) -> list[dict[str, Any]]: ...

        def follow(self, url: str, progress: Callable[[dict[str, Any]], None] | None = None,
                   poll: float = 0.25) -> dict[str, Any]: ...
