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
import math
import re
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

import httpx

from lumenlink.errors import LumenLinkError, ServiceUnreachable
from lumenlink.http import DEFAULT_SERVER, ServiceClient, check_server

__all__ = ["DEFAULT_SERVER", "Client", "LumenLinkError", "ServiceUnreachable", "check_server", "sensor_csv",
           "triples"]
_UUID = re.compile(r"^[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12}$")
#: job states after which a job changes no more
FINISHED = ("succeeded", "failed", "cancelled")


def _is_uuid(s: str) -> bool:
    return bool(_UUID.match(s))


def triples(values: Any, what: str) -> list[list[float]]:
    """`values` as a list of [x, y, z]; a flat list, or anything else, is a usage error that says the form."""
    example = f"{what}=[[0.0, 0.0, 1.0], [0.5, 0.0, 1.0]]"
    if hasattr(values, "tolist"):
        values = values.tolist()
    if not isinstance(values, Sequence) or isinstance(values, str | bytes):
        raise LumenLinkError(f"{what} must be a list of [x, y, z] triples (metres), e.g. {example}", usage=True)
    if values and all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        hint = (f" (group the {len(values)} numbers in threes)" if len(values) % 3 == 0 else "")
        raise LumenLinkError(f"{what} must be a list of [x, y, z] triples, e.g. {example}; got a flat list of "
                             f"{len(values)} numbers{hint}", usage=True)
    out = []
    for i, v in enumerate(values):
        if (not isinstance(v, Sequence) or isinstance(v, str | bytes) or len(v) != 3
                or not all(isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c) for c in v)):
            raise LumenLinkError(f"{what}[{i}] must be [x, y, z] (three finite numbers), got {v!r}; e.g. {example}",
                                 usage=True)
        out.append([float(c) for c in v])
    return out


class Client(ServiceClient):
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

    # ------------------------------------------------------------ assignments

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

    # ------------------------------------------------------------ optical files (ray files, BRDF tables)

    def upload_optical_file(self, path: str | Path, format: str | None = None) -> dict[str, Any]:  # noqa: A002
        """Upload a ray file or a measured BRDF table once (``POST /optical-files``), streamed from disk; answers
        ``{id, format, bytes, ...}``. Name it by its id in a light (``{"type": "rayfile", "file": id, ...}``) or a
        material (``{"type": "measured_brdf", "file": id}``). `format`: ``tm25``, ``rays`` (text columns) or
        ``brdf``; by default TM-25 where the file begins with ``TM25``, a BRDF table where its first words name
        ``theta_i_deg``, else a text ray file."""
        p = Path(path)
        if not p.is_file():
            raise LumenLinkError(f"no file {str(p)!r} to upload", usage=True)
        fmt = format or _optical_format(p)

        def chunks():
            with open(p, "rb") as fh:
                while block := fh.read(1 << 20):
                    yield block
        return dict(self._call("POST", "/optical-files", f"uploading {p.name}", params={"format": fmt},
                               content=chunks(), headers={"Content-Type": "application/octet-stream"}))

    def optical_files(self) -> list[dict[str, Any]]:
        """Every uploaded optical file's summary."""
        return list(self._call("GET", "/optical-files", "listing optical files"))

    # ------------------------------------------------------------ elements with an inside

    def add_element(self, body: dict[str, Any]) -> dict[str, Any]:
        """Prepare an element into the library (docs/DESIGN.md "Optical elements with an inside"): answers ``{id,
        features, bytes, prepare_seconds}``; the same body answers the same id, preparing nothing."""
        if not isinstance(body, dict):
            raise LumenLinkError("an element is a JSON object {\"type\": \"microstructure\", \"feature\", "
                                 "\"layout\"}", usage=True)
        return dict(self._call("POST", "/elements", "preparing an element", json=body))

    def elements(self) -> list[dict[str, Any]]:
        """The library: every prepared element with its size and preparation time."""
        return list(self._call("GET", "/elements", "listing the element library"))

    def put_element(self, scene: str | dict, path_or_uuid: str, element: str | dict[str, Any], *,
                    facing: Sequence[float] | None = None, faces: Sequence[int] | None = None,
                    model: str | None = None) -> dict[str, Any]:
        """Put an element (its library id, or a body, prepared first) onto the faces of a node that face `facing`
        (its own frame), or onto its B-rep `faces`; `model` "exact" (default) or "bsdf" (its tabulated BSDF). Answers
        ``{id, body, orphaned, applied, problem, model, support}``."""
        eid = element if isinstance(element, str) else self.add_element(element)["id"]
        body: dict[str, Any] = {"element": eid, "node": path_or_uuid}
        if facing is not None:
            body["facing"] = triples([list(facing)], "facing")[0]
        if faces is not None:
            body["faces"] = [int(f) for f in faces]
        if model is not None:
            body["model"] = model
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/elements", f"putting an element on "
                                                                              f"{path_or_uuid!r}", json=body))

    def scene_elements(self, scene: str | dict) -> list[dict[str, Any]]:
        return list(self._call("GET", f"/scenes/{self._sid(scene)}/elements", "listing the scene's elements"))

    def remove_element(self, scene: str | dict, assignment: str) -> None:
        """Take an element off its part (the part's faces are plain again)."""
        self._call("DELETE", f"/scenes/{self._sid(scene)}/elements/{assignment}", "taking an element off")

    def switch_element(self, scene: str | dict, assignment: str, element: str) -> dict[str, Any]:
        """Switch an element assignment to another library element in one call (a packed pattern, say)."""
        return dict(self._call("PUT", f"/scenes/{self._sid(scene)}/elements/{assignment}", "switching an element",
                               json={"element": element}))

    def pack(self, element: str, scene: str | dict, assignment: str, sensor: str, *, wait: bool = True,
             progress: Callable[[dict[str, Any]], None] | None = None, poll: float = 0.5,
             **options: Any) -> dict[str, Any]:
        """Pack a density element against the grid `sensor` over the lit face of the part that `assignment` puts it
        on (``POST /elements/{id}/pack``); options: target, figure, photons, max_photons, max_iterations,
        max_seconds, damping, max_fill, pitch_mm, seed. With `wait`, follows the job (Ctrl-C cancels it; a cancelled
        pack keeps what it measured) and answers its last state, whose ``result`` names the packed ``element``;
        otherwise the 202 answer (``url``). `sensor`: the grid's id or its name."""
        sid = self._sid(scene)
        if sensor == "all":
            raise LumenLinkError("a pack measures one grid sensor: name it (its id or its name), not 'all'",
                                 usage=True)
        body = {"scene": sid, "assignment": assignment, "sensor": self._sensor_ids(sid, sensor)[0]["id"], **options}
        accepted = dict(self._call("POST", f"/elements/{element}/pack", "starting a pack", ok=(202,), json=body))
        if not wait:
            return accepted
        return self.follow(accepted["url"], progress=progress, poll=poll)

    def pack_record(self, element: str) -> dict[str, Any]:
        """How a packed element was found: target, stop, history (uniformity ± error and seconds per iteration)."""
        return dict(self._call("GET", f"/elements/{element}/pack", "reading a pack's history"))

    def pack_png(self, element: str) -> bytes:
        """A packed element's ``pack.png``: density map, the map it measured, uniformity against iterations."""
        return self._bytes(f"/elements/{element}/pack.png", f"reading the pack plot of {element}")

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
        sensor's result}`` (``SensorPublic``: lux, stderr, photons, seconds, stop_reason, grid geometry…,
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

    def map_png(self, scene: str | dict, sensor_id: str, vmax: float | None = None) -> bytes:
        """The false-colour PNG of a grid sensor's latest result (the scene as it is now)."""
        params = {"vmax": vmax} if vmax is not None else None
        return self._bytes(f"/scenes/{self._sid(scene)}/sensors/{sensor_id}/map.png",
                           f"reading the map of sensor {sensor_id}", params)

    def image(self, scene: str | dict, sensor_id: str, format: str = "exr") -> bytes:
        """A camera's latest image (the scene as it is now): ``"exr"``, OpenEXR with the luminance (channel ``Y``,
        cd/m²) and its standard error (``stderr.Y``); ``"png"``, tone-mapped (Reinhard on luminance), one pixel per
        pixel; ``"map"``, the false-colour map with its cd/m² legend."""
        names = {"exr": "image.exr", "png": "image.png", "map": "map.png"}
        if format not in names:
            raise LumenLinkError(f"format must be one of {sorted(names)}, got {format!r}", usage=True)
        return self._bytes(f"/scenes/{self._sid(scene)}/sensors/{sensor_id}/{names[format]}",
                           f"reading the image of sensor {sensor_id}", None)

    def ugr(self, scene: str | dict, sensor: str, *, background: float | None = None,
            threshold: float | None = None) -> dict[str, Any]:
        """The unified glare rating (CIE 117-1995) an observer at a camera's position (by id or name) sees along its
        line of sight, from the camera's latest image (simulate it first): ``{ugr, stderr, background,
        background_stderr, threshold, source_pixels, …}``. `background`: L_b in cd/m² (default: the image's
        non-source pixels); `threshold`: cd/m² from which a pixel above the line of sight is a luminaire."""
        sid = self._sid(scene)
        s = self._sensor_ids(sid, sensor)[0]
        params = {k: v for k, v in (("background", background), ("threshold", threshold)) if v is not None}
        return dict(self._call("GET", f"/scenes/{sid}/sensors/{s['id']}/ugr", f"rating the glare seen by {sensor}",
                               params=params or None))

    def uniformity(self, scene: str | dict, *, direction: Any, points: Any = None, nine_points: Any = None,
                   distance: float | None = None, aperture_deg: float | None = None, target: float | None = None,
                   max_seconds: float | None = None, max_photons: int | None = None, seed: int = 0,
                   **extra: Any) -> dict[str, Any]:
        """Luminance meters looking along `direction` at `points` ([[x, y, z], …] m) or at the 9-point figure of a
        rectangle (`nine_points`: (origin, u, v), each [x, y, z] m), each `distance` m back from its point, measured
        together: ``{luminance, stderr (cd/m², one per point), uniformity: {min, max, mean, min_max,
        min_max_stderr, min_mean, min_mean_stderr}, photons, seconds, …}``."""
        if (points is None) == (nine_points is None):
            raise LumenLinkError("give either points or nine_points", usage=True)
        body: dict[str, Any] = {"direction": triples([direction], "direction")[0], "seed": seed, **extra}
        if points is not None:
            body["points"] = triples(points, "points")
        else:
            if isinstance(nine_points, dict):
                nine_points = [nine_points.get(k) for k in ("origin", "u", "v")]
            o, u, v = triples(nine_points, "nine_points (origin, u, v)")
            body["nine_points"] = {"origin": o, "u": u, "v": v}
        for key, value in (("distance", distance), ("aperture_deg", aperture_deg), ("target_relative_error", target),
                           ("max_seconds", max_seconds), ("max_photons", max_photons)):
            if value is not None:
                body[key] = value
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/luminance/uniformity",
                               "measuring luminance uniformity", json=body))

    def export(self, scene: str | dict, sensor: str, format: str = "ies", *,
               out: str | Path | None = None) -> str:
        """A far-field sensor's (by id or name) latest result as photometric file text: `format` ``"ies"`` (IES
        LM-63-2002) or ``"ldt"`` (EULUMDAT); written to `out` too where given. The service answers 404 while the
        sensor has no result (simulate it first) and 422 for a sensor of another kind."""
        if format not in ("ies", "ldt"):
            raise LumenLinkError(f"the export format is 'ies' (IES LM-63) or 'ldt' (EULUMDAT), got {format!r}",
                                 usage=True)
        sid = self._sid(scene)
        s = self._sensor_ids(sid, sensor)[0]
        text = self._bytes(f"/scenes/{sid}/sensors/{s['id']}/export", f"exporting sensor {sensor}",
                           {"format": format}).decode("utf-8")
        if out is not None:
            path = Path(out)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text, encoding="utf-8", newline="")
            except OSError as exc:
                raise LumenLinkError(f"cannot write {path}: {exc}", usage=True) from exc
        return text

    # ------------------------------------------------------------ kept results and comparisons

    def results(self, scene: str | dict, sensor: str) -> list[dict[str, Any]]:
        """A sensor's kept results (by id or name), newest first: ``{key, revision, edit, created_at, photons,
        seconds, min_lux, mean_lux, max_lux, …}``. A key is ``R.k``: the scene revision R and the k-th state at it
        (an assignment keeps the revision); ``R`` alone names the latest state kept at R."""
        sid = self._sid(scene)
        s = self._sensor_ids(sid, sensor)[0]
        return list(self._call("GET", f"/scenes/{sid}/sensors/{s['id']}/results",
                               f"listing the results of sensor {sensor}")["results"])

    def result(self, scene: str | dict, sensor: str, key: str | int, csv: bool = False) -> Any:
        """One kept result with its cells (``lux``, ``stderr``); `csv`: its CSV text (one row per cell)."""
        sid = self._sid(scene)
        s = self._sensor_ids(sid, sensor)[0]
        url = f"/scenes/{sid}/sensors/{s['id']}/results/{quote(str(key), safe='.')}"
        if csv:
            return self._bytes(url, f"reading result {key} of sensor {sensor}", {"format": "csv"}).decode()
        return dict(self._call("GET", url, f"reading result {key} of sensor {sensor}"))

    def compare(self, scene: str | dict, sensor: str = "all", from_key: str | int | None = None,
                to_key: str | int | None = None, *, out: str | Path | None = None) -> dict[str, dict[str, Any]]:
        """What changed between two kept results of each sensor (one by id or name, or ``"all"``): ``{sensor id:
        {from, to, difference, stderr (combined), lux_from, lux_to, summary, warnings, …}}``, lx per cell.

        `from_key`, `to_key`: result keys (``R`` or ``R.k``; see :meth:`results`); default the two newest kept.
        `out`: a directory to write ``<sensor>_<from>_to_<to>.csv`` (one row per cell: centre in world metres, lux
        before and after, difference, standard error) and, for a grid, the ``.png`` difference map; the paths
        written are in each answer's ``files``."""
        sid = self._sid(scene)
        sensors = self._sensor_ids(sid, sensor)
        answers: dict[str, dict[str, Any]] = {}
        for s in sensors:
            base = f"/scenes/{sid}/sensors/{s['id']}"
            label = s["body"].get("name") or s["id"]
            frm, to = from_key, to_key
            if frm is None or to is None:
                kept = [r["key"] for r in self._call("GET", f"{base}/results", f"listing results of {label}")
                        ["results"]]
                if len(kept) < 2 and (frm is None and to is None):
                    if sensor == "all" and len(sensors) > 1:
                        continue
                    raise LumenLinkError(f"sensor {label!r} has {len(kept)} kept result(s): simulate it, edit the "
                                         "scene, simulate again, then compare", usage=True)
                to = to if to is not None else kept[0]
                frm = frm if frm is not None else next((k for k in kept if k != str(to)), None)
                if frm is None:
                    raise LumenLinkError(f"sensor {label!r} has no kept result besides {to}", usage=True)
            params = {"from": str(frm), "to": str(to)}
            diff = dict(self._call("GET", f"{base}/difference", f"comparing results of sensor {label}",
                                   params=params))
            if out is not None:
                folder = Path(out)
                folder.mkdir(parents=True, exist_ok=True)
                stem = re.sub(r"[^A-Za-z0-9._-]+", "_", str(label)).strip("._") or s["id"]
                stem = f"{stem}_{diff['from']}_to_{diff['to']}"
                files = [folder / f"{stem}.csv"]
                files[0].write_bytes(self._bytes(f"{base}/difference", f"comparing sensor {label}",
                                                 {**params, "format": "csv"}))
                if diff.get("type") == "grid":
                    files.append(folder / f"{stem}.png")
                    files[1].write_bytes(self._bytes(f"{base}/difference.png", f"drawing the change of {label}",
                                                     params))
                diff["files"] = [str(f) for f in files]
            answers[s["id"]] = diff
        if not answers:
            raise LumenLinkError("no sensor has two kept results: simulate, edit the scene, simulate again, then "
                                 "compare", usage=True)
        return answers

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


def sensor_csv(result: dict[str, Any]) -> str:
    """A sensor result as CSV, one row per cell: its indices, its centre (world metres), lux and standard error.

    Grid: ``i`` (along u, 0..nu-1), ``j`` (along v), the cell centre origin + (i+½)/nu·u + (j+½)/nv·v.
    Disk: one row (i = j = 0) at the disk's centre where the result names it, else blank coordinates.
    Far field: ``i,j,c_deg,gamma_deg,cd,stderr_cd``, one row per bin (i along C, j along γ).
    Luminance meter, camera: ``row,col,cd_m2,stderr_cd_m2``, one row per pixel (row 0 the top; a meter: one row)."""
    if result.get("type") in ("luminance", "camera"):
        values = result["luminance"]
        grid = values if values and isinstance(values[0], list) else [values]
        errs = result["stderr"] if grid is values else [result["stderr"]]
        rows = ["row,col,cd_m2,stderr_cd_m2"]
        rows += [f"{j},{i},{_num(a)},{_num(b)}" for j, (line, line_err) in enumerate(zip(grid, errs, strict=True))
                 for i, (a, b) in enumerate(zip(line, line_err, strict=True))]
        return "\n".join(rows) + "\n"
    if result.get("type") == "far_field":
        rows = ["i,j,c_deg,gamma_deg,cd,stderr_cd"]
        for j, g in enumerate(result["gamma_deg"]):
            for i, c in enumerate(result["c_deg"]):
                rows.append(f"{i},{j},{c:.9g},{g:.9g},{_num(result['candela'][j][i])},{_num(result['stderr'][j][i])}")
        return "\n".join(rows) + "\n"
    lines = ["i,j,x_m,y_m,z_m,lux,stderr_lux"]
    lux, err = result["lux"], result["stderr"]
    if result.get("type") == "grid" and result.get("origin") is not None:
        o, u, v = result["origin"], result["u"], result["v"]
        nu, nv = int(result["nu"]), int(result["nv"])
        for j in range(nv):
            for i in range(nu):
                s, t = (i + 0.5) / nu, (j + 0.5) / nv
                c = [o[k] + s * u[k] + t * v[k] for k in range(3)]
                lines.append(f"{i},{j},{c[0]:.9g},{c[1]:.9g},{c[2]:.9g},{_num(lux[j][i])},{_num(err[j][i])}")
    else:
        flat_lux = list(_flatten(lux))
        flat_err = list(_flatten(err))
        for k, (a, b) in enumerate(zip(flat_lux, flat_err, strict=False)):
            lines.append(f"{k},0,,,,{_num(a)},{_num(b)}")
    return "\n".join(lines) + "\n"


def _num(x: Any) -> str:
    return "" if x is None else f"{float(x):.9g}"


def _flatten(x: Any) -> Iterable[Any]:
    if isinstance(x, list):
        for y in x:
            yield from _flatten(y)
    else:
        yield x


ZEMAX_HEADS = ("Source", "Symmetry", "SpectralContent", "ScatterType", "SampleRotation", "AngleOfIncidence")


def _optical_format(path: Path) -> str:
    """An optical file's format from its first bytes: ``tm25``, ``brdf`` or ``rays``."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if head[:4] == b"TM25":
        return "tm25"
    words = [line.split("#", 1)[0].split() for line in head.decode("utf-8", errors="replace").splitlines()]
    first = next((w[0] for w in words if w), "")
    return "brdf" if first in ("theta_i_deg", "theta_o_deg", "dphi_deg") + ZEMAX_HEADS else "rays"
