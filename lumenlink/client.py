"""A small Python client of the LumenLink service (httpx): the engineer's loop without curl.

    from lumenlink import Client

    with Client("http://127.0.0.1:8000") as ll:
        lens = ll.node("car", "car/lamp/lens")                  # scenes by name or id, nodes by path
        ll.assign("car", "car/lamp/lens", {"type": "dielectric", "ior": 1.5})
        ll.add_light("car", ies="downlight.ies", at=(0, 0, 2.5))
        sensor = ll.add_sensor("car", {"type": "grid", "origin": [-1, -1, 0], "u": [2, 0, 0], "v": [0, 2, 0],
                                       "nu": 20, "nv": 20})
        results = ll.simulate("car", sensor["id"], max_photons=200_000)   # {sensor id: result}

Every call that names a scene takes its name or its id (a UUID); a name no scene has is an error naming the
closest scene names, unless ``scene(name, create=True)``. Every call that names a node takes its path
(``GET /scenes/{id}/nodes`` lists them) or its UUID. Positions and lengths are metres in the world (in the
node's frame for a light or sensor attached to a node). Every failure raises :class:`LumenLinkError`, which
carries the service's problem+json (``status``, ``problem``); :class:`ServiceUnreachable` is the one raised
when no service answers. The server defaults to ``$LUMENLINK_SERVER`` (else http://127.0.0.1:8000) and the
bearer token to ``$LUMENLINK_TOKEN``.
"""

from __future__ import annotations

import difflib
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import httpx

from lumenlink.client_assignments import AssignmentCalls
from lumenlink.client_elements import ElementCalls
from lumenlink.client_images import ImageCalls
from lumenlink.client_results import ResultCalls
from lumenlink.client_values import triples
from lumenlink.errors import LumenLinkError, ServiceUnreachable
from lumenlink.http import DEFAULT_SERVER, check_server
from lumenlink.sensor_outputs import sensor_csv

__all__ = ["DEFAULT_SERVER", "Client", "LumenLinkError", "ServiceUnreachable", "check_server", "sensor_csv",
           "triples"]
_UUID = re.compile(r"^[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12}$")
#: job states after which a job changes no more
FINISHED = ("succeeded", "failed", "cancelled")


def _is_uuid(s: str) -> bool:
    return bool(_UUID.match(s))


class Client(AssignmentCalls, ElementCalls, ImageCalls, ResultCalls):
    """A client of one LumenLink service (its connection, token and errors: `lumenlink.http.ServiceClient`).

    Parameters
    ----------
    server : str, optional
        Base URL (``http://host:port``); default ``$LUMENLINK_SERVER``, else http://127.0.0.1:8000.
    token : str, optional
        Bearer token; default ``$LUMENLINK_TOKEN``.
    timeout : float
        Seconds per request (a long simulation runs as a job and is polled, so no request waits on it).
    transport : httpx.BaseTransport, optional
        For tests.
    """

    def __init__(self, server: str | None = None, *, token: str | None = None, timeout: float = 120.0,
                 transport: httpx.BaseTransport | None = None) -> None:
        super().__init__(server, token=token, timeout=timeout, transport=transport)
        self._ids: dict[str, str] = {}

    def __enter__(self) -> Client:
        return self

    # ------------------------------------------------------------ plumbing

    def _sid(self, scene: str | dict) -> str:
        """A scene's id from its name, its id or its record."""
        if isinstance(scene, dict):
            return str(scene["id"])
        if scene in self._ids:
            return self._ids[scene]
        return str(self.scene(scene)["id"])

    # ------------------------------------------------------------ scenes and nodes

    def scenes(self) -> list[dict[str, Any]]:
        """Every scene: ``{id, name, revision}``."""
        return list(self._call("GET", "/scenes", "listing scenes"))

    def scene(self, name_or_id: str, create: bool = False) -> dict[str, Any]:
        """One scene's summary (``GET /scenes/{id}``: revision, counts, length unit, effects…), by name or id.

        A name no scene has is a :class:`LumenLinkError` naming the closest scene names, unless `create`
        (then the scene is made, empty, at revision 0)."""
        if not isinstance(name_or_id, str) or not name_or_id.strip():
            raise LumenLinkError("a scene is named by a non-empty name or id", usage=True)
        if _is_uuid(name_or_id):
            out = self._call("GET", f"/scenes/{name_or_id}", f"reading scene {name_or_id}")
        else:
            listed = self.scenes()
            found = next((s for s in listed if s.get("name") == name_or_id), None)
            if found is None:
                if not create:
                    names = [str(s.get("name")) for s in listed]
                    close = difflib.get_close_matches(name_or_id, names, n=5, cutoff=0.5)
                    hint = (f"; did you mean {', '.join(repr(c) for c in close)}?" if close
                            else f"; the scenes are {', '.join(repr(n) for n in names[:10])}" if names
                            else "; the service has no scenes yet")
                    raise LumenLinkError(f"no scene is called {name_or_id!r}{hint} (create it with create=True, "
                                         "or --create)", usage=True, problem={"did_you_mean": close})
                found = self._call("POST", "/scenes", f"creating scene {name_or_id!r}", json={"name": name_or_id})
            out = self._call("GET", f"/scenes/{found['id']}", f"reading scene {name_or_id!r}")
            self._ids[name_or_id] = str(found["id"])
        return dict(out)

    def push(self, file: str | Path, scene: str, *, linear: float | None = None, angular: float | None = None,
             relative: bool = False, dry_run: bool = False) -> dict[str, Any]:
        """Push a STEP file to the scene named `scene` (made if no scene has that name), as ``lumenlink push``
        does: its nodes are recognised in what the scene holds (a "Save As" or a re-export keeps every UUID),
        the parts are tessellated (``linear`` deflection in the document's unit, default 0.1 mm; ``angular``,
        rad, default 0.5; ``relative``: ``linear`` is a fraction of each part's size) and only the meshes the
        service lacks are uploaded. Answers the service's answer to the push: the diff by UUID (``added``,
        ``moved``, ``geometry_changed``…), what was rebuilt, the seconds of each stage. ``dry_run``: the diff only.
        The bearer token is this client's (its ``token``, else ``$LUMENLINK_TOKEN``). Raises `LumenLinkError` (``usage``
        for an unreadable or non-STEP file; status 409 when the scene changed meanwhile: push again) or
        `ServiceUnreachable`."""
        from cad_adapter.errors import CadAdapterError, CadImportError, TessellationError
        from cad_adapter.push import default_cache_dir, push_file
        from cad_adapter.tessellate import TessellationCache

        try:
            result = push_file(Path(file), scene, self.server, linear, angular, relative, dry_run=dry_run,
                               cache=TessellationCache(default_cache_dir()), token=self.token)[0]
        except LumenLinkError:   # the adapter's PushError family is ours (ServiceUnreachable, 409) as it is
            raise
        except (CadImportError, TessellationError) as exc:
            raise LumenLinkError(f"{file}: {exc}", usage=True) from exc
        except CadAdapterError as exc:
            raise LumenLinkError(str(exc)) from exc
        self._ids.pop(scene, None)   # a scene the push made is looked up again by name
        return dict(result.answer)

    def nodes(self, scene: str | dict, name: str | None = None) -> list[dict[str, Any]]:
        """The scene's nodes in document order, each with its ``path`` and ``uuid``; `name`: a glob on node names
        (a pattern with ``/`` matches whole paths)."""
        params = {"name": name} if name is not None else None
        sid = self._sid(scene)
        return list(self._call("GET", f"/scenes/{sid}/nodes", "listing nodes", params=params))

    def node(self, scene: str | dict, path: str) -> dict[str, Any]:
        """The node at `path`; a 404 :class:`LumenLinkError` whose ``did_you_mean`` lists close paths if none."""
        sid = self._sid(scene)
        return dict(self._call("GET", f"/scenes/{sid}/nodes", f"finding node {path!r}", params={"path": path}))

    def materials(self, scene: str | dict) -> list[dict[str, Any]]:
        return list(self._call("GET", f"/scenes/{self._sid(scene)}/materials", "listing materials"))

    def lights(self, scene: str | dict) -> list[dict[str, Any]]:
        return list(self._call("GET", f"/scenes/{self._sid(scene)}/lights", "listing lights"))

    def sensors(self, scene: str | dict) -> list[dict[str, Any]]:
        return list(self._call("GET", f"/scenes/{self._sid(scene)}/sensors", "listing sensors"))

    # ------------------------------------------------------------ simulation

    def _sensor_ids(self, sid: str, sensor: str) -> list[dict[str, Any]]:
        listed = self.sensors(sid)
        if sensor == "all":
            if not listed:
                raise LumenLinkError(f"scene {sid} has no sensors: add one first (add_sensor, lumenlink sensor)",
                                     usage=True)
            return listed
        found = [s for s in listed if s["id"] == sensor.lower() or s["body"].get("name") == sensor]
        if not found:
            names = [s["body"].get("name") or s["id"] for s in listed]
            close = difflib.get_close_matches(sensor, names, n=5, cutoff=0.5)
            hint = f"; did you mean {', '.join(map(repr, close))}?" if close else \
                (f"; its sensors are {', '.join(map(repr, names))}" if names else "; it has no sensors")
            raise LumenLinkError(f"scene {sid} has no sensor {sensor!r}{hint}", usage=True,
                                 problem={"did_you_mean": close})
        return found[:1]

    def simulate(self, scene: str | dict, sensor: str = "all", *, target: float | None = None,
                 max_seconds: float | None = None, max_photons: int | None = None, seed: int = 0,
                 progress: Callable[[dict[str, Any], dict[str, Any]], None] | None = None,
                 poll: float = 0.25, force_effects_off: Sequence[str] | None = None,
                 tessellation_estimate: bool = False, **extra: Any) -> dict[str, dict[str, Any]]:
        """Simulate one sensor (by id or name) or ``"all"``, each as an async job followed to its end.

        `target` is the relative error to stop at (``target_relative_error``), `max_seconds` and `max_photons`
        the budgets. `progress(sensor, job)` is called at each poll with the sensor's record and the job
        (``job["progress"]``: photons, worst_relative_error, seconds, seconds_left). Answers ``{sensor id: the
        sensor's result}`` (its kind's answer: lux, stderr, photons, seconds, stop_reason, grid geometry…,
        ``effect_reasons``: why each effect is on or off). `force_effects_off`: effects the physics turned on that the
        query leaves out (e.g. ``["polarization"]``). `tessellation_estimate`: where the scene has curved mirror or
        glass meshes, also estimate their tessellation's error (``error_budget.tessellation_estimate``, lx, beside
        the bound ``error_budget.tessellation``; 3 to 4 times the query's time, stated in
        ``error_budget.tessellation_estimate_seconds``). Interrupted (Ctrl-C), the running job is cancelled on the
        service."""
        sid = self._sid(scene)
        query: dict[str, Any] = {"seed": seed, **extra}
        if tessellation_estimate:
            query["tessellation_estimate"] = True
        if force_effects_off:
            query["force_effects_off"] = list(force_effects_off)
        for key, value in (("target_relative_error", target), ("max_seconds", max_seconds),
                           ("max_photons", max_photons)):
            if value is not None:
                query[key] = value
        out: dict[str, dict[str, Any]] = {}
        for s in self._sensor_ids(sid, sensor):
            accepted = self._call("POST", f"/scenes/{sid}/sensors/{s['id']}/simulate", f"simulating sensor {s['id']}",
                                  ok=(202,), params={"mode": "async"}, json=query)
            follow: Callable[[dict[str, Any]], None] | None = None
            if progress is not None:
                def follow(j: dict[str, Any], s: dict[str, Any] = s) -> None:
                    progress(s, j)
            job = self.follow(accepted["url"], progress=follow, poll=poll)
            if job["status"] != "succeeded":
                raise LumenLinkError(f"the simulation of sensor {s['id']} {job['status']}: {job.get('error') or ''}",
                                     problem=job)
            out[s["id"]] = job["result"]
        return out

    def follow(self, url: str, progress: Callable[[dict[str, Any]], None] | None = None,
               poll: float = 0.25) -> dict[str, Any]:
        """Poll a job (``/jobs/{id}``) until it has finished; answers its last state. Ctrl-C cancels it."""
        try:
            while True:
                job = self._call("GET", url, "following a job")
                if progress is not None:
                    progress(job)
                if job["status"] in FINISHED:
                    return dict(job)
                time.sleep(poll)
        except KeyboardInterrupt:
            try:
                self._request("DELETE", url)
            finally:
                raise

    def illuminance(self, scene: str | dict, points: Any, normals: Any, *, radius: float | None = None,
                    target: float | None = None, max_seconds: float | None = None, max_photons: int | None = None,
                    seed: int = 0, force_effects_off: Sequence[str] | None = None, tessellation_estimate: bool = False,
                    **extra: Any) -> dict[str, Any]:
        """Illuminance (lx) ± standard error at `points` ([[x, y, z], …], metres) on receivers facing `normals`
        (one per point). Answers the service's ``{lux, stderr, photons, seconds, effects, effect_reasons, revision,
        …}``; `force_effects_off` leaves out effects the physics turned on (e.g. ``["polarization"]``);
        `tessellation_estimate` adds ``error_budget.tessellation_estimate`` where the scene has curved mirror or
        glass meshes (see `simulate`)."""
        pts, nrm = triples(points, "points"), triples(normals, "normals")
        if len(pts) != len(nrm):
            raise LumenLinkError(f"give one normal per point: {len(pts)} points, {len(nrm)} normals", usage=True)
        body: dict[str, Any] = {"points": pts, "normals": nrm, "seed": seed, **extra}
        if tessellation_estimate:
            body["tessellation_estimate"] = True
        if force_effects_off:
            body["force_effects_off"] = list(force_effects_off)
        for key, value in (("radius", radius), ("target_relative_error", target), ("max_seconds", max_seconds),
                           ("max_photons", max_photons)):
            if value is not None:
                body[key] = value
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/illuminance", "querying illuminance",
                               json=body))
