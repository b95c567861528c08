"""Sensor results that outlive an edit (issue 22): the last results of each sensor, kept in the database (and
the latest result of each far-field sensor, which its IES / EULUMDAT export reads: `keep_far`, `far`).

Every sensor simulation that still describes the scene when it ends is kept (`ResultStore.keep`, called by
`service.simulation.SimulationHub.run_grid`): per scene, sensor and **key**. A key is ``R`` or ``R.k``:

- ``R`` is the scene revision the result was computed at (what the answer's ``revision`` says);
- ``k`` (``edit``) counts the states the scene went through at that revision: an assignment (a material, a light,
  a sensor changed) keeps the revision, so the first state simulated at revision R is ``R.0``, the next different
  one ``R.1``… Simulating the same state again (more photons, another seed) replaces its result.

Asking for ``R`` means the latest state kept at revision R. At most ``keep`` results (``LUMENLINK_KEEP_RESULTS``)
are kept per sensor; the oldest go first. Results outlive the sensor (its deletion leaves them readable) but not
the scene. Only what a map, a CSV or a difference needs is kept: lux and standard error per cell (exact float64),
the grid's frame, photons, seconds, estimator, stop reason and effects.

Luminance meters and cameras (issue 37) are kept the same way, their values in cd/m² in the same columns (the
``lux`` bytes and ``min_lux``/``mean_lux``/``max_lux`` of the table; ``meta.quantity`` is ``"luminance"``): read
back they answer ``luminance`` and ``min_luminance``/``mean_luminance``/``max_luminance`` instead, a camera's as
``height`` rows of ``width`` pixels, and their differences are per pixel (``luminance_from``, ``luminance_to``).
`current` finds the kept result that still describes the scene as it is (its revision and state): a camera's
images outlive a restart of the service through it.

Differences (`difference`) are ``to − from`` per cell with the combined standard error √(σ_from² + σ_to²); cells
are compared by index (a sensor attached to a node that moved compares the same cells on the part).
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
from datetime import UTC, datetime
from typing import Any

import numpy as np
from sqlalchemy import Engine, and_, delete, func, insert, select
from sqlalchemy.exc import SQLAlchemyError

from service import db
from service.errors import Invalid, NotFound
from service.live import LiveScene
from service.maps import SIGNIFICANCE_SIGMAS
from service.sensor_kinds import kind_of_type

log = logging.getLogger("lumenlink.service")

#: ``R`` or ``R.k``: a scene revision, optionally one state at it
KEY_PATTERN = r"^[0-9]{1,9}(\.[0-9]{1,9})?$"
_KEY = re.compile(KEY_PATTERN)
#: what the JSON of a kept result carries besides the per-cell values
_META = ("type", "nu", "nv", "origin", "u", "v", "center", "normal", "radius", "estimator", "stop_reason",
         "effects", "seed", "width", "height", "position", "look_at", "fov_deg", "strategy")


def state_digest(live: LiveScene, sensor: dict[str, Any]) -> str:
    """A digest of what a sensor's result depends on besides geometry: materials, lights and the sensor. The lights
    are a set: a service that reloads them (by creation time, then id) may list two made in the same instant in
    another order than the process that made them, and the digest must not change with it."""
    lights = sorted(json.dumps(b, sort_keys=True, default=str) for b in live.lights)
    payload = json.dumps([sorted((int(k), v) for k, v in live.materials.items()), live.default_material,
                          lights, sensor], sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()


def parse_key(key: str) -> tuple[int, int | None]:
    """``"R"`` → (R, None), ``"R.k"`` → (R, k); a 422 naming the form otherwise."""
    if not _KEY.match(key):
        raise Invalid(f"a result is named by its scene revision R or R.k (the k-th state at revision R), got {key!r}")
    rev, _, edit = key.partition(".")
    return int(rev), (int(edit) if edit else None)


def key_of(revision: int, edit: int) -> str:
    return f"{revision}.{edit}"


def _bytes(a: Any) -> bytes:
    return np.ascontiguousarray(np.asarray(a, dtype="<f8")).tobytes()


class ResultStore:
    """The kept results of one database (see the module docstring).

    Parameters
    ----------
    engine : Engine
        The service's database (``app.state.engine``).
    keep : int
        Results kept per sensor (``Settings.keep_results``).
    """

    def __init__(self, engine: Engine, keep: int) -> None:
        self.engine = engine
        self.keep_count = int(keep)

    # -- writing ------------------------------------------------------------------------------

    def keep(self, live: LiveScene, sensor: dict[str, Any], payload: dict[str, Any]) -> str | None:
        """Keep one sensor result (``service.simulation.SimulationHub.run_grid``'s payload); answers its key.

        A failure to store is logged and answers None: the result itself is still good, only its keeping failed.
        """
        try:
            return self._keep(live, sensor, payload)
        except SQLAlchemyError:
            log.exception("could not keep the result of sensor %s of scene %s", sensor.get("id"), live.scene_id)
            return None

    def _keep(self, live: LiveScene, sensor: dict[str, Any], payload: dict[str, Any]) -> str:
        t = db.sensor_results
        scene_id, sensor_id, revision = live.scene_id, str(sensor["id"]), int(payload["revision"])
        state = state_digest(live, sensor)
        meta = {k: payload[k] for k in _META if payload.get(k) is not None}
        kind = kind_of_type(sensor.get("type"))
        meta.update(kind.kept(sensor))
        if kind.QUANTITY == "luminance":
            values = np.asarray(payload["luminance"], float)
            meta["quantity"] = "luminance"
            low, mean, high = float(values.min()), float(values.mean()), float(values.max())
        else:
            values = np.asarray(payload["lux"], float)
            low, mean, high = float(payload["min_lux"]), float(payload["mean_lux"]), float(payload["max_lux"])
        row = dict(scene_id=scene_id, sensor_id=sensor_id, revision=revision, state=state,
                   created_at=datetime.now(UTC), photons=int(payload["photons"]), seconds=float(payload["seconds"]),
                   min_lux=low, mean_lux=mean, max_lux=high, meta=meta, lux=_bytes(values),
                   stderr=_bytes(payload["stderr"]))
        mine = and_(t.c.scene_id == scene_id, t.c.sensor_id == sensor_id)
        with self.engine.begin() as conn:
            latest = conn.execute(select(t.c.edit, t.c.state).where(mine, t.c.revision == revision)
                                  .order_by(t.c.edit.desc()).limit(1)).first()
            if latest is not None and latest.state == state:   # the same state again: replace its result
                edit = int(latest.edit)
                conn.execute(delete(t).where(mine, t.c.revision == revision, t.c.edit == edit))
            else:
                edit = 0 if latest is None else int(latest.edit) + 1
            conn.execute(insert(t).values(edit=edit, **row))
            kept = conn.execute(select(t.c.revision, t.c.edit).where(mine)
                                .order_by(t.c.created_at.desc(), t.c.revision.desc(), t.c.edit.desc())).all()
            for old in kept[self.keep_count:]:
                conn.execute(delete(t).where(mine, t.c.revision == old.revision, t.c.edit == old.edit))
        return key_of(revision, edit)

    def keep_far(self, scene_id: str, sensor_id: str, payload: dict[str, Any]) -> None:
        """Keep the latest result of a far-field sensor (its export reads it), replacing the one before; a failure
        to store is logged, as for `keep`."""
        t = db.far_field_results
        mine = and_(t.c.scene_id == scene_id, t.c.sensor_id == sensor_id)
        try:
            with self.engine.begin() as conn:
                conn.execute(delete(t).where(mine))
                conn.execute(insert(t).values(scene_id=scene_id, sensor_id=sensor_id, created_at=datetime.now(UTC),
                                              payload=payload))
        except SQLAlchemyError:
            log.exception("could not keep the far-field result of sensor %s of scene %s", sensor_id, scene_id)

    # -- reading ------------------------------------------------------------------------------

    def far(self, scene_id: str, sensor_id: str) -> dict[str, Any] | None:
        """The kept latest result of a far-field sensor, or None."""
        t = db.far_field_results
        with self.engine.connect() as conn:
            row = conn.execute(select(t.c.payload).where(t.c.scene_id == scene_id, t.c.sensor_id == sensor_id)
                               ).first()
        return None if row is None else dict(row.payload)

    def list(self, scene_id: str, sensor_id: str) -> list[dict[str, Any]]:
        """The sensor's kept results, newest first, without their cells."""
        t = db.sensor_results
        cols = [t.c.revision, t.c.edit, t.c.created_at, t.c.photons, t.c.seconds, t.c.min_lux, t.c.mean_lux,
                t.c.max_lux, t.c.meta]
        with self.engine.connect() as conn:
            rows = conn.execute(select(*cols).where(t.c.scene_id == scene_id, t.c.sensor_id == sensor_id)
                                .order_by(t.c.created_at.desc(), t.c.revision.desc(), t.c.edit.desc())).all()
        return [_summary(r) for r in rows]

    def count(self, scene_id: str, sensor_id: str) -> int:
        t = db.sensor_results
        with self.engine.connect() as conn:
            return int(conn.execute(select(func.count()).select_from(t)
                                    .where(t.c.scene_id == scene_id, t.c.sensor_id == sensor_id)).scalar_one())

    def get(self, scene_id: str, sensor_id: str, key: str) -> dict[str, Any]:
        """One kept result with its cells (lux, stderr: nv rows of nu cells for a grid); `NotFound` naming the
        kept keys if there is none."""
        revision, edit = parse_key(key)
        t = db.sensor_results
        where = [t.c.scene_id == scene_id, t.c.sensor_id == sensor_id, t.c.revision == revision]
        if edit is not None:
            where.append(t.c.edit == edit)
        with self.engine.connect() as conn:
            row = conn.execute(select(t).where(*where).order_by(t.c.edit.desc()).limit(1)).first()
        if row is None:
            kept = [r["key"] for r in self.list(scene_id, sensor_id)]
            raise NotFound(f"sensor {sensor_id} has no kept result {key!r}; "
                           + (f"kept: {', '.join(kept)}" if kept else "none is kept: simulate it first"),
                           kept=kept)
        return _with_cells(row)

    def current(self, live: LiveScene, sensor: dict[str, Any]) -> dict[str, Any] | None:
        """The kept result (with its cells) that still describes the scene as it is now: computed at its revision,
        in its present state of materials, lights and this sensor; None if there is none."""
        t = db.sensor_results
        try:
            with self.engine.connect() as conn:
                row = conn.execute(select(t).where(t.c.scene_id == live.scene_id, t.c.sensor_id == str(sensor["id"]),
                                                   t.c.revision == int(live.revision),
                                                   t.c.state == state_digest(live, sensor))
                                   .order_by(t.c.edit.desc()).limit(1)).first()
        except SQLAlchemyError:
            log.exception("could not read the kept results of sensor %s of scene %s", sensor.get("id"),
                          live.scene_id)
            return None
        return None if row is None else _with_cells(row)


def _with_cells(row: Any) -> dict[str, Any]:
    """A kept row as its summary with its cells: ``lux`` (or ``luminance``) and ``stderr``, shaped as the sensor
    (nv × nu for a grid, height × width for a camera)."""
    out = _summary(row)
    values = np.frombuffer(row.lux, dtype="<f8")
    err = np.frombuffer(row.stderr, dtype="<f8")
    meta = row.meta
    shape = kind_of_type(meta.get("type")).layout(meta)
    if shape is not None:
        values, err = values.reshape(shape), err.reshape(shape)
    out.update({"luminance" if _is_luminance(meta) else "lux": values.tolist(), "stderr": err.tolist()})
    return out


def _is_luminance(r: Any) -> bool:
    return r.get("quantity") == "luminance" or kind_of_type(r.get("type")).QUANTITY == "luminance"


def _summary(r: Any) -> dict[str, Any]:
    meta = dict(r.meta)
    created = r.created_at if r.created_at.tzinfo else r.created_at.replace(tzinfo=UTC)  # SQLite drops the zone
    name = "luminance" if _is_luminance(meta) else "lux"
    return {"key": key_of(r.revision, r.edit), "revision": int(r.revision), "edit": int(r.edit),
            "created_at": created.isoformat(), "photons": int(r.photons), "seconds": float(r.seconds),
            f"min_{name}": float(r.min_lux), f"mean_{name}": float(r.mean_lux), f"max_{name}": float(r.max_lux),
            **meta}


def _shape(result: dict[str, Any]) -> tuple[int, int] | None:
    """(rows, columns) of a kept result's cells (its kind's `layout`); None for a flat list of values (a disk's one
    value, a surface's one per triangle), taken as one row."""
    return kind_of_type(result.get("type")).layout(result)


def _cells(result: dict[str, Any], name: str) -> np.ndarray:
    values = np.asarray(result[name], float)
    return values.reshape(_shape(result) or (1, values.size))


def _cell_centres(result: dict[str, Any], shape: tuple[int, ...]) -> np.ndarray:
    """World centre (m) of each of the (rows, columns) cells, as its kind places them: a grid's own, a disk's one
    centre repeated, NaN (unknown) for a surface's triangles."""
    return kind_of_type(result.get("type")).centres(result, (int(shape[0]), int(shape[1])))


def _luminance_csv(values: np.ndarray, columns: list[tuple[str, np.ndarray]]) -> str:
    lines = ["row,col," + ",".join(name for name, _ in columns)]
    for j in range(values.shape[0]):
        for i in range(values.shape[1]):
            lines.append(f"{j},{i}," + ",".join(repr(float(a[j, i])) for _, a in columns))
    return "\n".join(lines) + "\n"


def result_csv(result: dict[str, Any]) -> str:
    """One row per cell: ``i,j,x_m,y_m,z_m,lux,stderr_lux`` (the cell centre in world metres; as the CLI's); the
    values exact (shortest round-tripping float). A luminance meter or camera: ``row,col,cd_m2,stderr_cd_m2``, one
    row per pixel (row 0 the top; a meter: one row), as the client's `sensor_csv`."""
    if _is_luminance(result):
        lum = _cells(result, "luminance")
        return _luminance_csv(lum, [("cd_m2", lum), ("stderr_cd_m2", _cells(result, "stderr"))])
    lux, err = _cells(result, "lux"), _cells(result, "stderr")
    c = _cell_centres(result, lux.shape)
    lines = ["i,j,x_m,y_m,z_m,lux,stderr_lux"]
    for j in range(lux.shape[0]):
        for i in range(lux.shape[1]):
            x, y, z = (("" if not np.isfinite(v) else f"{v:.9g}") for v in c[j, i])
            lines.append(f"{i},{j},{x},{y},{z},{float(lux[j, i])!r},{float(err[j, i])!r}")
    return "\n".join(lines) + "\n"


def difference(before: dict[str, Any], after: dict[str, Any]) -> dict[str, Any]:
    """``after − before`` per cell with the combined standard error, and where it changed beyond noise.

    Refuses (422) two results whose cells cannot be paired (another type or grid size)."""
    dims = ("type", "nu", "nv", "width", "height")
    name = "luminance" if _is_luminance(after) else "lux"
    if tuple(before.get(k) for k in dims) != tuple(after.get(k) for k in dims) or \
            np.size(before.get(name, [])) != np.size(after.get(name, [])):
        def size(r: dict[str, Any]) -> str:
            return kind_of_type(r.get("type")).size(r, int(np.size(r.get(name, []))))
        raise Invalid(f"results {before['key']} and {after['key']} cannot be compared cell by cell: the sensor was "
                      f"{size(before)} at {before['key']} and {size(after)} at {after['key']}")
    if _is_luminance(after):
        return _luminance_difference(before, after)
    lux_b, lux_a = _cells(before, "lux"), _cells(after, "lux")
    se_b, se_a = _cells(before, "stderr"), _cells(after, "stderr")
    delta, sigma = lux_a - lux_b, np.hypot(se_b, se_a)
    warnings = []
    frame = ("origin", "u", "v", "center", "normal", "radius")
    if any(before.get(k) != after.get(k) for k in frame):
        warnings.append(f"the sensor moved between {before['key']} and {after['key']}: cells are compared by index, "
                        f"placed as at {after['key']}")
    out: dict[str, Any] = {
        "from": before["key"], "to": after["key"], "type": after.get("type"),
        "difference": delta.tolist(), "stderr": sigma.tolist(), "lux_from": lux_b.tolist(), "lux_to": lux_a.tolist(),
        "significance_sigmas": SIGNIFICANCE_SIGMAS, "warnings": warnings,
        **{k: after[k] for k in ("nu", "nv", "origin", "u", "v", "center", "normal", "radius") if k in after},
    }
    own = kind_of_type(after.get("type")).change(lux_b, lux_a, se_b, se_a, after)
    if own is not None:
        out["summary"] = own
    else:
        significant = np.abs(delta) > SIGNIFICANCE_SIGMAS * sigma
        out["summary"] = {"cells": int(delta.size), "significant": int(significant.sum()),
                          "increased": int((significant & (delta > 0)).sum()),
                          "decreased": int((significant & (delta < 0)).sum()),
                          "mean_before_lux": float(lux_b.mean()), "mean_after_lux": float(lux_a.mean())}
    return out


def _luminance_difference(before: dict[str, Any], after: dict[str, Any]) -> dict[str, Any]:
    """`difference` of two kept luminance results (a meter's one value, a camera's pixels), cd/m²."""
    lb, la = _cells(before, "luminance"), _cells(after, "luminance")
    delta, sigma = la - lb, np.hypot(_cells(before, "stderr"), _cells(after, "stderr"))
    frame = ("position", "look_at", "fov_deg", "direction", "aperture_deg")
    warnings = []
    if any(before.get(k) != after.get(k) for k in frame):
        warnings.append(f"the sensor moved between {before['key']} and {after['key']}: pixels are compared by index")
    significant = np.abs(delta) > SIGNIFICANCE_SIGMAS * sigma
    return {"from": before["key"], "to": after["key"], "type": after.get("type"), "quantity": "luminance",
            "difference": delta.tolist(), "stderr": sigma.tolist(), "luminance_from": lb.tolist(),
            "luminance_to": la.tolist(), "significance_sigmas": SIGNIFICANCE_SIGMAS, "warnings": warnings,
            "summary": {"cells": int(delta.size), "significant": int(significant.sum()),
                        "increased": int((significant & (delta > 0)).sum()),
                        "decreased": int((significant & (delta < 0)).sum()),
                        "mean_before_cd_m2": float(lb.mean()), "mean_after_cd_m2": float(la.mean())},
            **{k: after[k] for k in ("width", "height", *frame) if k in after}}


def difference_csv(diff: dict[str, Any]) -> str:
    """One row per cell: ``i,j,x_m,y_m,z_m,lux_from,lux_to,difference_lux,stderr_lux``; luminance:
    ``row,col,cd_m2_from,cd_m2_to,difference_cd_m2,stderr_cd_m2``."""
    if diff.get("quantity") == "luminance":
        shape = _shape(diff) or (1, -1)
        cols = [(name, np.asarray(diff[key], float).reshape(shape)) for name, key in (
            ("cd_m2_from", "luminance_from"), ("cd_m2_to", "luminance_to"), ("difference_cd_m2", "difference"),
            ("stderr_cd_m2", "stderr"))]
        return _luminance_csv(cols[0][1], cols)
    d, se, b, a = (_cells(diff, k) for k in ("difference", "stderr", "lux_from", "lux_to"))
    nv, nu = d.shape
    c = _cell_centres(diff, d.shape)
    lines = ["i,j,x_m,y_m,z_m,lux_from,lux_to,difference_lux,stderr_lux"]
    for j in range(nv):
        for i in range(nu):
            x, y, z = (("" if not np.isfinite(v) else f"{v:.9g}") for v in c[j, i])
            values = ",".join(repr(float(m[j, i])) for m in (b, a, d, se))
            lines.append(f"{i},{j},{x},{y},{z},{values}")
    return "\n".join(lines) + "\n"
