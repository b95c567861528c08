"""`lumenlink.Client`'s calls for what a simulation draws or exports: maps, camera images, glare (UGR),
luminance uniformity, photometric files. A mixin: the connection, the scene lookup and the errors are `Client`'s."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from lumenlink.client_base import ClientBase
from lumenlink.client_values import triples
from lumenlink.errors import LumenLinkError


class ImageCalls(ClientBase):
    """Maps, images, UGR, uniformity, exports (`Client` is made of it)."""

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
                   thirteen_points: Any = None, distance: float | None = None, aperture_deg: float | None = None,
                   target: float | None = None, max_seconds: float | None = None, max_photons: int | None = None,
                   seed: int = 0, **extra: Any) -> dict[str, Any]:
        """Luminance meters looking along `direction` at `points` ([[x, y, z], …] m), at the 9-point figure of a
        rectangle (`nine_points`: (origin, u, v), each [x, y, z] m) or at its 13-point figure (`thirteen_points`:
        the same, or a dict with an ``inset`` in m, default 10 mm), each `distance` m back from its point, measured
        together: ``{luminance, stderr (cd/m², one per point), uniformity: {min, max, mean, min_max,
        min_max_stderr, min_mean, min_mean_stderr}, photons, seconds, …}``."""
        if sum(x is not None for x in (points, nine_points, thirteen_points)) != 1:
            raise LumenLinkError("give one of points, nine_points or thirteen_points", usage=True)
        body: dict[str, Any] = {"direction": triples([direction], "direction")[0], "seed": seed, **extra}
        if points is not None:
            body["points"] = triples(points, "points")
        for name, rect in (("nine_points", nine_points), ("thirteen_points", thirteen_points)):
            if rect is not None:
                inset = rect.get("inset") if isinstance(rect, dict) else None
                if isinstance(rect, dict):
                    rect = [rect.get(k) for k in ("origin", "u", "v")]
                o, u, v = triples(rect, f"{name} (origin, u, v)")
                body[name] = {"origin": o, "u": u, "v": v, **({} if inset is None else {"inset": inset})}
        for key, value in (("distance", distance), ("aperture_deg", aperture_deg), ("target_relative_error", target),
                           ("max_seconds", max_seconds), ("max_photons", max_photons)):
            if value is not None:
                body[key] = value
        return dict(self._call("POST", f"/scenes/{self._sid(scene)}/luminance/uniformity",
                               "measuring luminance uniformity", json=body))

    def conoscope(self, scene: str | dict, point: Any, normal: Any, *, theta_max_deg: float | None = None,
                  rings: int | None = None, azimuths: int | None = None, phi_zero: Any = None,
                  distance: float | None = None, aperture_deg: float | None = None, target: float | None = None,
                  max_seconds: float | None = None, max_photons: int | None = None, seed: int = 0,
                  png: bool = False, **extra: Any) -> dict[str, Any] | bytes:
        """The luminance one point of a lit face (`point`, [x, y, z] m) shows against viewing angle: meters on a
        polar grid around `normal` (`rings` polar angles up to `theta_max_deg`, `azimuths` per ring from
        `phi_zero`), measured in one run: ``{luminance[ring][azimuth], stderr, on_axis, flatness, photons, seconds,
        …}`` (cd/m²); `png`: its polar plot instead."""
        body: dict[str, Any] = {"point": triples([point], "point")[0], "normal": triples([normal], "normal")[0],
                                "seed": seed, **extra}
        if phi_zero is not None:
            body["phi_zero"] = triples([phi_zero], "phi_zero")[0]
        for key, value in (("theta_max_deg", theta_max_deg), ("rings", rings), ("azimuths", azimuths),
                           ("distance", distance), ("aperture_deg", aperture_deg), ("target_relative_error", target),
                           ("max_seconds", max_seconds), ("max_photons", max_photons)):
            if value is not None:
                body[key] = value
        url = f"/scenes/{self._sid(scene)}/luminance/conoscope"
        if png:
            resp = self._request("POST", url, json=body, params={"format": "png"})
            if resp.status_code != 200:
                self._answer(resp, "drawing a conoscopic view")   # raises, saying why
            return resp.content
        return dict(self._call("POST", url, "measuring a conoscopic view", json=body))

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
