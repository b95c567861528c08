"""Units stated and checked (issue 22): positions far outside the model are warned about, never refused.

Lights, sensors and query points are in world **metres**, whatever the document's ``length_unit``; a position
given in the document's unit by mistake (a light at [90, 75, 500], millimetres meant, over a 1 m model) lies
hundreds of model sizes away and lights nothing, and a query there answers 0 ± 0 lx. `far_warnings` names each
position that lies more than `FAR_FACTOR` times the model's diagonal outside its bounding box, says the unit the
document was drawn in and what the position would be if it was meant in that unit.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from service.live import LiveScene
from service.schemas import LENGTH_UNITS
from service.sensor_kinds import kind_of_type

#: A position this many bounding-box diagonals outside the model's box is warned about.
FAR_FACTOR = 100.0
#: The disk receiver radius of a point query that gives none, m (`tracer.simulate.DEFAULT_RADIUS`; a test holds
#: them equal): each value is the mean illuminance over that disk.
DEFAULT_RADIUS_M = 0.05


def model_box(live: LiveScene) -> np.ndarray | None:
    """(2, 3) world box ``[lo, hi]`` of the model's surfaces (metres), or None for a scene without geometry."""
    boxes = []
    for instance in set(live.instance_of_node.values()):
        try:
            if live.tracer.is_sensor(instance):
                continue
            box = np.asarray(live.tracer.instance_bounds(instance), float)
        except (ValueError, KeyError, IndexError, RuntimeError):   # gone or not committed: not part of the model
            continue
        if box.shape == (2, 3) and np.all(np.isfinite(box)) and np.all(box[0] <= box[1]):
            boxes.append(box)
    if not boxes:
        return None
    stacked = np.stack(boxes)
    return np.stack([stacked[:, 0].min(axis=0), stacked[:, 1].max(axis=0)])


def _fmt(p: Iterable[float]) -> str:
    return "[" + ", ".join(f"{0.0 if abs(c) < 1e-9 else c:.4g}" for c in p) + "]"   # no -1e-12 from a box


def far_warnings(live: LiveScene, positions: Iterable[tuple[str, Any]], *, box: np.ndarray | None = None,
                 limit: int = 5) -> list[str]:
    """A warning per position (``(what, [x, y, z])``, world metres) farther than `FAR_FACTOR` diagonals outside
    the model's box; at most `limit` named, then a count."""
    box = model_box(live) if box is None else box
    if box is None:
        return []
    lo, hi = box
    diagonal = float(np.linalg.norm(hi - lo))
    if diagonal <= 0.0:
        return []
    unit = str((live.extras or {}).get("length_unit") or "m")
    scale = LENGTH_UNITS.get(unit)
    far = []
    for what, p in positions:
        q = np.asarray(p, float)
        if q.shape != (3,) or not np.all(np.isfinite(q)):
            continue
        distance = float(np.linalg.norm(np.maximum(np.maximum(lo - q, q - hi), 0.0)))
        if distance > FAR_FACTOR * diagonal:
            far.append((what, q, distance))
    out = []
    for what, q, distance in far[:limit]:
        hint = (f"; if it was meant in the document's unit ({unit}), it is {_fmt(q * scale)} m"
                if scale is not None and scale != 1.0 else "")
        out.append(f"{what} at {_fmt(q)} m lies {distance:.4g} m outside the model (its box {_fmt(lo)} to "
                   f"{_fmt(hi)} m, diagonal {diagonal:.4g} m; more than {FAR_FACTOR:g} diagonals away). Positions "
                   f"are world metres; the scene's document unit is {unit}{hint}")
    if len(far) > limit:
        out.append(f"… and {len(far) - limit} more positions that far outside the model")
    return out


def light_positions(live: LiveScene, ids: Iterable[str] | None = None) -> list[tuple[str, Any]]:
    """``(what, position)`` of the scene's lights that have a position (all, or those in `ids`)."""
    wanted = None if ids is None else set(ids)
    out = []
    for light in live.lights:
        if (wanted is None or str(light.get("id")) in wanted) and light.get("position") is not None:
            out.append((f"light {light.get('id')}", light["position"]))
    return out


def sensor_positions(live: LiveScene, ids: Iterable[str] | None = None) -> list[tuple[str, Any]]:
    """``(what, centre)`` of the scene's sensors (a grid's centre, a disk's centre)."""
    wanted = None if ids is None else set(ids)
    out = []
    for s in live.sensors:
        if wanted is not None and str(s.get("id")) not in wanted:
            continue
        centre = kind_of_type(s.get("type")).centre(s)
        if centre is None:
            continue
        out.append((f"sensor {s.get('id')}", centre))
    return out
