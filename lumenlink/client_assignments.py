"""`lumenlink.Client`'s calls that give a scene's nodes what the simulation keeps by UUID: materials, lights
(a body, or a photometric file placed and aimed) and sensors. A mixin: the connection, the scene lookup and the
errors are `Client`'s."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

from lumenlink.client_base import ClientBase
from lumenlink.client_values import triples
from lumenlink.errors import LumenLinkError


class AssignmentCalls(ClientBase):
    """Materials, lights and sensors (`Client` is made of it)."""

    def assign(self, scene: str | dict, path_or_uuid: str, material: dict[str, Any]) -> dict[str, Any]:
        """Give a node (by path or UUID) a material (docs/DESIGN.md's bodies, e.g. ``{"type": "mirror",
        "reflectance": 0.9}``); its descendants without one inherit it. Answers ``{node (the UUID), material}``."""
        if not isinstance(material, dict):
            raise LumenLinkError(f"a material is a JSON object like {{\"type\": \"lambertian\", \"reflectance\": "
                                 f"0.8}}, got {type(material).__name__}", usage=True)
        sid = self._sid(scene)
        return dict(self._call("PUT", f"/scenes/{sid}/materials/{quote(path_or_uuid, safe='')}",
                               f"assigning a material to {path_or_uuid!r}", json=material))

    def add_light(self, scene: str | dict, body: dict[str, Any] | None = None, *, ies: str | Path | None = None,
                  at: Iterable[float] | None = None, attach: str | None = None, name: str | None = None,
                  direction: Iterable[float] | None = None) -> dict[str, Any]:
        """Add a light: a docs/DESIGN.md body, or a photometric file (`ies`: IES LM-63 ``.ies``, or EULUMDAT ``.ldt``)
        placed `at` (x, y, z), metres, aimed along `direction` (its γ = 0 axis; default straight down). `attach`:
        a node path or UUID; the light then moves with that node and `at` is in the node's frame. Answers
        ``{id, body, orphaned}``."""
        if (body is None) == (ies is None):
            raise LumenLinkError("give a light body or ies=FILE (with at=(x, y, z)), one of them", usage=True)
        if ies is not None:
            path = Path(ies)
            if at is None:
                raise LumenLinkError("a light from a photometric file needs at=(x, y, z), metres", usage=True)
            try:
                text = path.read_text(encoding="utf-8", errors="replace")
            except OSError as exc:
                raise LumenLinkError(f"cannot read the photometric file {path}: {exc}", usage=True) from exc
            fmt = "ldt" if path.suffix.lower() in (".ldt", ".eul") else "ies"
            body = {"type": "goniometric", "position": triples([list(at)], "at")[0], "format": fmt, "data": text,
                    "name": name or path.stem}
            if direction is not None:
                body["direction"] = triples([list(direction)], "direction")[0]
        assert body is not None
        body = dict(body)
        if attach is not None:
            body["attached_to"] = attach
        if name is not None:
            body["name"] = name
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/lights", "adding a light", json=body))

    def add_sensor(self, scene: str | dict, body: dict[str, Any], *, attach: str | None = None) -> dict[str, Any]:
        """Add a sensor: ``{"type": "grid", "origin", "u", "v", "nu", "nv"}`` (front side u × v, metres) or
        ``{"type": "disk", "center", "normal", "radius"}``. Answers ``{id, body, orphaned}``."""
        if not isinstance(body, dict):
            raise LumenLinkError("a sensor is a JSON object (type grid or disk)", usage=True)
        body = dict(body)
        if attach is not None:
            body["attached_to"] = attach
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/sensors", "adding a sensor", json=body))

    @staticmethod
    def grid(origin: Sequence[float], u: Sequence[float], v: Sequence[float], nu: int, nv: int,
             name: str | None = None) -> dict[str, Any]:
        """A grid sensor's body: the rectangle origin + s·u + t·v, nu × nv cells (metres; front side u × v)."""
        origin_, u_, v_ = triples([list(origin), list(u), list(v)], "grid")
        body: dict[str, Any] = {"type": "grid", "origin": origin_, "u": u_, "v": v_, "nu": int(nu), "nv": int(nv)}
        if name:
            body["name"] = name
        return body
