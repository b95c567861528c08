"""`lumenlink.Client`'s calls for kept results and their comparisons, and a result as CSV (`sensor_csv`).
A mixin: the connection, the scene lookup and the errors are `Client`'s."""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any
from urllib.parse import quote

from lumenlink.client_base import ClientBase
from lumenlink.errors import LumenLinkError


class ResultCalls(ClientBase):
    """Kept results and comparisons (`Client` is made of it)."""

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
