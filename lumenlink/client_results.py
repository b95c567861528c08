"""`lumenlink.Client`'s calls for kept results and their comparisons. A mixin: the connection, the scene lookup and
the errors are `Client`'s."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any
from urllib.parse import quote

from lumenlink.client_base import ClientBase
from lumenlink.errors import LumenLinkError
from lumenlink.sensor_outputs import output_of


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
                if output_of(diff).DIFFERENCE_MAP:
                    files.append(folder / f"{stem}.png")
                    files[1].write_bytes(self._bytes(f"{base}/difference.png", f"drawing the change of {label}",
                                                     params))
                diff["files"] = [str(f) for f in files]
            answers[s["id"]] = diff
        if not answers:
            raise LumenLinkError("no sensor has two kept results: simulate, edit the scene, simulate again, then "
                                 "compare", usage=True)
        return answers
