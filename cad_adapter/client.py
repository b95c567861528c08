"""REST client of the service: find or create a scene, upload missing meshes, push the tree.

Order of a push (docs/DESIGN.md's REST contract): ``GET /scenes`` (find the scene by name, ``POST /scenes``
if none has it) → ``GET /scenes/{id}`` (its revision) → ``POST /geometries/missing`` → ``PUT
/geometries/{gid}`` for each missing mesh (GLB) → ``PUT /scenes/{id}/document`` with that revision as
``base_revision``. Uploads are content-addressed, so an interrupted push leaves nothing half-done: the
tree changes in one request or not at all. A 409 means someone changed the scene meanwhile: the client
re-reads the revision, raises :class:`~cad_adapter.errors.RevisionConflict` and never retries by itself.

The connection, token and error answers are the one client's (`lumenlink.http.ServiceClient`); `Pusher` adds
the calls of a push and raises the adapter's `PushError` family (also `lumenlink.LumenLinkError`s).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import httpx

from lumenlink.http import ServiceClient

from .errors import PushError, RevisionConflict, ServiceUnavailable
from .glb import MEDIA_TYPE, encode_glb
from .payload import build_push
from .tessellate import Mesh, Tessellation
from .tree import Document


@dataclass
class PushResult:
    """What a push did.

    Attributes
    ----------
    answer : dict
        The service's answer to ``PUT /scenes/{id}/document`` (the diff, rebuilds, seconds).
    scene_id : str
    created_scene : bool
    geometries : int
        Distinct geometries in the tree.
    uploaded : int
        Meshes the service lacked and got now.
    uploaded_bytes : int
    seconds : dict of str to float
        Client-side stages: ``scene``, ``missing``, ``upload``, ``push``.
    """

    answer: dict
    scene_id: str
    created_scene: bool
    geometries: int
    uploaded: int
    uploaded_bytes: int
    seconds: dict[str, float] = field(default_factory=dict)


class Pusher(ServiceClient):
    """A client of one service, for pushes.

    Parameters
    ----------
    server : str
        Base URL, e.g. ``http://127.0.0.1:8000``.
    timeout : float
        Seconds per request.
    transport : httpx.BaseTransport, optional
        For tests (``httpx.MockTransport``).
    upload_progress : callable(done, total, gid), optional
        Called after each uploaded mesh.
    token : str, optional
        Bearer token; default ``$LUMENLINK_TOKEN`` (a service beyond loopback asks for it).
    """

    error = PushError
    unreachable = ServiceUnavailable

    def __init__(self, server: str, *, timeout: float = 60.0, transport: httpx.BaseTransport | None = None,
                 upload_progress: Callable[[int, int, str], None] | None = None, token: str | None = None) -> None:
        if not isinstance(server, str) or not server.strip():
            raise PushError(f"server must be an http(s) URL, got {server!r}", usage=True)
        super().__init__(server, token=token, timeout=timeout, transport=transport)
        self.upload_progress = upload_progress

    def __enter__(self) -> Pusher:
        return self

    # ---------------------------------------------------------------- the calls

    def scene_by_name(self, name: str) -> dict | None:
        """The scene called ``name`` (``{id, name, revision}``), or None."""
        scenes = self._call("GET", "/scenes", "listing scenes")
        if isinstance(scenes, dict):  # tolerate {"scenes": [...]}
            scenes = scenes.get("scenes", [])
        for s in scenes:
            if s.get("name") == name:
                return s
        return None

    def find_or_create_scene(self, name: str) -> tuple[dict, bool]:
        """``(scene, created)``: the scene called ``name``, created if no scene has that name."""
        if not isinstance(name, str) or not name.strip():
            raise PushError("the scene name must be a non-empty string")
        found = self.scene_by_name(name)
        if found is not None:
            return found, False
        created = self._call("POST", "/scenes", f"creating scene {name!r}", json={"name": name})
        return created, True

    def revision(self, scene_id: str) -> int:
        """The scene's current revision."""
        data = self._call("GET", f"/scenes/{scene_id}", f"reading scene {scene_id}")
        return int(data["revision"])

    def missing(self, ids: list[str]) -> list[str]:
        """Which of ``ids`` the service does not store yet."""
        if not ids:
            return []
        data = self._call("POST", "/geometries/missing", "asking for missing meshes", json={"ids": ids})
        return list(data["missing"])

    def upload(self, gid: str, glb: bytes) -> None:
        self._call("PUT", f"/geometries/{gid}", f"uploading geometry {gid[:12]}", content=glb,
                   headers={"content-type": MEDIA_TYPE})

    def geometry(self, gid: str) -> tuple:
        """A stored mesh (``GET /geometries/{gid}``): (vertices, triangles, normals or None)."""
        from .glb import decode_glb

        resp = self._request("GET", f"/geometries/{gid}")
        if resp.status_code != 200:
            self._answer(resp, f"reading geometry {gid[:12]}")  # raises, saying why
        return decode_glb(resp.content)

    def scene_tree(self, name: str) -> SceneTree | None:
        """What the scene called ``name`` holds now (its nodes, for reconciliation), or None if there is none."""
        info = self.scene_by_name(name)
        if info is None:
            return None
        sid = str(info["id"])
        summary = self._call("GET", f"/scenes/{sid}", f"reading scene {name!r}")
        nodes = self._call("GET", f"/scenes/{sid}/nodes", f"reading the nodes of scene {name!r}")
        if not isinstance(nodes, list):
            raise PushError(f"GET /scenes/{sid}/nodes answered {type(nodes).__name__}, not a list")
        resp = self._request("GET", f"/scenes/{sid}/removed-nodes")
        removed = self._answer(resp, f"reading the removed nodes of scene {name!r}") if resp.status_code != 404 else []
        if not isinstance(removed, list):
            raise PushError(f"GET /scenes/{sid}/removed-nodes answered {type(removed).__name__}, not a list")
        unit = summary.get("length_unit")
        return SceneTree(sid, int(summary["revision"]), unit, nodes,
                         (summary.get("source") or {}).get("tessellation"),
                         [r for r in removed if isinstance(r, dict) and r.get("length_unit") in (None, unit)])

    def push_document(self, scene_id: str, body: dict, dry_run: bool = False) -> dict:
        """``PUT /scenes/{id}/document``; :class:`RevisionConflict` on 409 (after re-reading the revision).

        ``dry_run``: the service diffs and answers without changing the scene."""
        resp = self._request("PUT", f"/scenes/{scene_id}/document", json=body,
                             params={"dry_run": "true"} if dry_run else None)
        if resp.status_code == 409:
            try:
                current = self.revision(scene_id)
            except PushError:
                current = None
            raise RevisionConflict(
                f"the scene changed on the service since revision {body.get('base_revision')} "
                f"(it is now at revision {current if current is not None else '?'}); nothing was pushed. "
                "Check what changed, then push again.", current_revision=current, problem=_json_or_empty(resp))
        return self._answer(resp, "pushing the document", ok=(200,))

    def push(self, doc: Document, tess: Tessellation, scene: str, base_revision: int | None = None,
             dry_run: bool = False, identity: bool = True) -> PushResult:
        """Push a document: scene, missing meshes, upload, tree.

        Parameters
        ----------
        doc : Document
            With UUIDs assigned.
        tess : Tessellation
        scene : str
            Scene name (created if absent).
        base_revision : int, optional
            Revision the push is based on; default the scene's revision read just before pushing.
        dry_run : bool
            Upload nothing, change nothing: the answer is the diff the push would make (a scene that
            does not exist yet is not created: the answer is then every node added).
        identity : bool
            Send the shape signatures the next STEP push is reconciled with (False where the UUIDs come from
            the CAD system itself, `cad_adapter.freecad`: its parts carry no OCP shape).

        Raises
        ------
        ServiceUnavailable, RevisionConflict, PushError
        """
        seconds: dict[str, float] = {}
        t = time.perf_counter()
        if dry_run:
            return self._dry_run(doc, tess, scene, base_revision, identity)
        info, created = self.find_or_create_scene(scene)
        scene_id = str(info["id"])
        if base_revision is None:
            base_revision = int(info["revision"]) if created else self.revision(scene_id)
        body = build_push(doc, tess, base_revision, identity)
        seconds["scene"] = time.perf_counter() - t
        t = time.perf_counter()
        by_gid: dict[str, Mesh] = {m.geometry_id: m for m in tess.meshes.values()}
        used = sorted({n["geometry"] for n in body["nodes"] if n["geometry"]})
        missing = self.missing(used)
        seconds["missing"] = time.perf_counter() - t
        t = time.perf_counter()
        sent = 0
        for i, gid in enumerate(missing, start=1):
            if gid not in by_gid:
                raise PushError(f"the service asked for geometry {gid} which this document does not have")
            m = by_gid[gid]
            glb = encode_glb(m.vertices, m.triangles, m.normals, m.face_ids)
            self.upload(gid, glb)
            sent += len(glb)
            if self.upload_progress is not None:
                self.upload_progress(i, len(missing), gid)
        seconds["upload"] = time.perf_counter() - t
        t = time.perf_counter()
        answer = self.push_document(scene_id, body)
        seconds["push"] = time.perf_counter() - t
        return PushResult(answer, scene_id, created, len(used), len(missing), sent, seconds)

    def _dry_run(self, doc: Document, tess: Tessellation, scene: str, base_revision: int | None,
                 identity: bool = True) -> PushResult:
        t = time.perf_counter()
        info = self.scene_by_name(scene)
        body = build_push(doc, tess, base_revision, identity)
        used = sorted({n["geometry"] for n in body["nodes"] if n["geometry"]})
        if info is None:  # nothing to diff against: everything would be added
            answer = {"scene": None, "revision": 0, "base_revision": base_revision, "dry_run": True,
                      "added": [n["uuid"] for n in body["nodes"]], "removed": [], "moved": [],
                      "geometry_changed": [], "renamed": [], "reparented": [], "recolored": [],
                      "unchanged": 0, "orphaned": [], "restored": [], "missing_geometries": used,
                      "blas_to_build": used, "reconciliation": body.get("reconciliation")}
            return PushResult(answer, "", False, len(used), 0, 0, {"dry_run": time.perf_counter() - t})
        scene_id = str(info["id"])
        if base_revision is None:
            body["base_revision"] = self.revision(scene_id)
        answer = self.push_document(scene_id, body, dry_run=True)
        return PushResult(answer, scene_id, False, len(used), 0, 0, {"dry_run": time.perf_counter() - t})


def _json_or_empty(resp: httpx.Response) -> dict:
    try:
        data = resp.json()
    except ValueError:
        return {}
    return data if isinstance(data, dict) else {}


@dataclass
class SceneTree:
    """A scene's current tree as the service holds it (the memory identity is reconciled with).

    Attributes
    ----------
    id : str
    revision : int
    length_unit : str or None
    nodes : list of dict
        ``GET /scenes/{id}/nodes``: uuid, parent, name, product, path, transform, world, geometry, signature.
    tessellation : dict or None
        The settings the scene's meshes were made with (``source.tessellation`` of its last push).
    removed : list of dict
        ``GET /scenes/{id}/removed-nodes`` (those in the scene's current unit): the nodes the scene removed and
        remembers; a node that comes back where one of them was gets its UUID again.
    """

    id: str
    revision: int
    length_unit: str | None
    nodes: list[dict]
    tessellation: dict | None
    removed: list[dict] = field(default_factory=list)
