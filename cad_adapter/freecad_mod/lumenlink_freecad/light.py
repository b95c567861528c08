"""The light shown back on the model: a surface sensor's illuminance as false colour on the parts' B-rep faces.

A surface sensor (``{"type": "surface", "node": ...}``) answers the illuminance on every triangle of its node's
instances (lx, with its standard error and area). Each triangle belongs to one B-rep face of the part (the face ids
the export carried), so each face gets the area-weighted mean of its triangles, ``sum(a E) / sum(a)``, with the
standard error ``sqrt(sum((a s)^2)) / sum(a)`` (triangles tallied by independent photons). Colours run from the
smallest face mean to the largest (viridis), so that a non-uniformity shows whatever its level. The simulation is
asked of the service with standard-library HTTP; painting is `gui`'s (it needs FreeCAD's view providers).
"""

from __future__ import annotations

import base64
import json
import math
import os
import urllib.error
import urllib.parse
import urllib.request
from array import array

#: viridis at 0, 1/8 ... 1 (matplotlib's table), linear RGB enough for a legend
VIRIDIS = ((0.267, 0.005, 0.329), (0.283, 0.141, 0.458), (0.254, 0.265, 0.530), (0.207, 0.372, 0.553),
           (0.164, 0.471, 0.558), (0.128, 0.567, 0.551), (0.135, 0.659, 0.518), (0.267, 0.749, 0.441),
           (0.478, 0.821, 0.318), (0.741, 0.873, 0.150), (0.993, 0.906, 0.144))


class ServiceError(Exception):
    """The service cannot be reached, or refused, or holds no such result: the message says which and what to do."""


def _get(settings, path: str, body: dict | None = None) -> dict | list:
    """GET ``path`` (POST ``body`` as JSON where given) on the settings' service, with its bearer token."""
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(settings.server.rstrip("/") + path, data=data,
                                     headers={"Accept": "application/json", "Content-Type": "application/json"})
    token = settings.token or os.environ.get("LUMENLINK_TOKEN")
    if token:
        request.add_header("Authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(request, timeout=60) as answer:
            return json.loads(answer.read())
    except urllib.error.HTTPError as exc:
        try:
            detail = json.loads(exc.read()).get("detail")
        except ValueError:
            detail = exc.reason
        raise ServiceError(f"{request.get_method()} {path}: {exc.code} {detail}") from exc
    except (urllib.error.URLError, OSError) as exc:
        raise ServiceError(f"the service at {settings.server} cannot be reached ({exc})") from exc


def simulate_surface(settings, scene: str, sensor: str, max_seconds: float) -> dict:
    """Simulate the surface sensor named (or with id) ``sensor`` in the scene named ``scene`` for at most
    ``max_seconds`` s: its answer, each instance's ``node``, ``lux``, ``stderr`` and ``area`` per triangle."""
    scenes = _get(settings, "/scenes")
    found = [s for s in scenes if scene in (s.get("name"), s.get("id"))]
    if not found:
        raise ServiceError(f"no scene {scene!r} on {settings.server}: push the document first")
    sid = urllib.parse.quote(str(found[0]["id"]))
    listed = _get(settings, f"/scenes/{sid}/sensors")   # [{id, body: {type, name, ...}, orphaned}]
    sensors = [s for s in listed if sensor in (s["body"].get("name"), s["id"])]
    if not sensors or sensors[0]["body"].get("type") != "surface":
        names = [s["body"].get("name") or s["id"] for s in listed if s["body"].get("type") == "surface"]
        raise ServiceError(f"scene {scene!r} has no surface sensor {sensor!r} (its surface sensors: "
                           f"{', '.join(map(str, names)) or 'none'}; add one with POST /scenes/{{id}}/sensors "
                           '{"type": "surface", "node": ...})')
    sensor_id = urllib.parse.quote(str(sensors[0]["id"]))
    return _get(settings, f"/scenes/{sid}/sensors/{sensor_id}/simulate", {"max_seconds": max_seconds, "seed": 0})


def face_ids(part: dict) -> list[int]:
    """Each triangle's B-rep face index, from an export's part (`document.mesh`)."""
    ids = array("I")
    ids.frombytes(base64.b64decode(part["face_ids"]))
    return list(ids)


def face_values(lux: list, stderr: list, area: list, faces: list[int]) -> list[tuple[float, float] | None]:
    """Per B-rep face: (area-weighted mean lux, its standard error), None for a face no triangle tallies."""
    if not (len(lux) == len(stderr) == len(area) == len(faces)):
        raise ValueError(f"the result has {len(lux)} triangles, the part {len(faces)}: push the document again and "
                         "simulate before showing its light")
    n = max(faces) + 1 if faces else 0
    weight, total, var = [0.0] * n, [0.0] * n, [0.0] * n
    for e, s, a, f in zip(lux, stderr, area, faces, strict=True):
        if e is None or a is None or not math.isfinite(e):
            continue
        weight[f] += a
        total[f] += a * e
        var[f] += (a * (s or 0.0)) ** 2
    return [(total[f] / weight[f], math.sqrt(var[f]) / weight[f]) if weight[f] > 0 else None for f in range(n)]


def colour(value: float, low: float, high: float) -> tuple[float, float, float]:
    """Viridis at ``value`` between ``low`` and ``high`` (clipped)."""
    t = 0.0 if high <= low else min(1.0, max(0.0, (value - low) / (high - low)))
    x = t * (len(VIRIDIS) - 1)
    i = min(int(x), len(VIRIDIS) - 2)
    w = x - i
    return tuple(VIRIDIS[i][k] * (1 - w) + VIRIDIS[i + 1][k] * w for k in range(3))


def face_colours(export: dict, result: dict) -> tuple[dict[str, list], dict]:
    """``({object Name: [(r, g, b) per B-rep face]}, legend)`` for a surface result over the export's document;
    ``legend``: ``{low, high, stderr (the median face's), faces, skipped (instances with no object of their own)}``.
    Faces no photon tallied are grey."""
    by_uuid = {n["uuid"]: n for n in export["nodes"]}
    values: dict[str, list] = {}
    skipped = 0
    for instance in result.get("instances") or []:
        node = by_uuid.get(instance.get("node"))
        if node is None or not node.get("object") or not node.get("part"):
            skipped += 1
            continue
        faces = face_ids(export["parts"][node["part"]])
        values[node["object"]] = face_values(instance["lux"], instance["stderr"], instance["area"], faces)
    means = [v for per in values.values() for v in per if v is not None]
    if not means:
        raise ValueError("the result tallies no face of this document's objects: is it this document's scene?")
    low, high = min(m for m, _ in means), max(m for m, _ in means)
    errors = sorted(s for _, s in means)
    colours = {name: [colour(v[0], low, high) if v is not None else (0.5, 0.5, 0.5) for v in per]
               for name, per in values.items()}
    return colours, {"low": low, "high": high, "stderr": errors[len(errors) // 2], "faces": len(means),
                     "skipped": skipped}


def legend_html(legend: dict, sensor: str) -> str:
    """The legend as rich text for a label over the 3D view: the colour scale and its values, the error bar."""
    rows = []
    for k in range(5, -1, -1):
        value = legend["low"] + (legend["high"] - legend["low"]) * k / 5
        r, g, b = (int(255 * c) for c in colour(value, legend["low"], legend["high"]))
        rows.append(f"<tr><td style='background-color:#{r:02x}{g:02x}{b:02x}'>&nbsp;&nbsp;&nbsp;&nbsp;</td>"
                    f"<td>&nbsp;{value:,.0f} lx</td></tr>")
    return (f"<b>{sensor}</b>: illuminance per face<table>{''.join(rows)}</table>"
            f"± {legend['stderr']:,.0f} lx (median face's standard error), {legend['faces']} faces")
