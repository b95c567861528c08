"""The service's side of the sensor kinds that see (`tracer.sensors.luminance`, `tracer.sensors.camera`): what they
answer and where it is kept (the contract: `service.sensor_kinds`).

Both are answered by paths from the eye (`tracer.transport.radiance`): the forward estimator, observables, a
polarization reference and ``physics_left_out`` are refused (422) before anything runs. The answer holds
``luminance`` and ``stderr`` in cd/m² — one value for a meter (as a disk answers one lux), ``height`` rows of
``width`` pixels for a camera, top row first — with the estimator's ``strategy`` in words and ``unreachable``
(the lights paths from the eye cannot find here, or null).

``KEEP = "image"``: the latest result is kept in memory while the scene is unchanged (as a grid's, for
``image.exr``, ``image.png`` and ``map.png``), and in the result store (values in cd/m², `service.results`), which
keeps the differences between revisions and serves the images after a restart.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, Literal

import numpy as np
from pydantic import Field

from service.errors import Invalid, TooLarge
from service.payloads import finite_list, result_payload
from service.sensor_base import SensorAnswer, SensorKind

_COMMON = ("photons", "seconds", "effects", "estimator", "stop_reason", "compile_seconds", "backend", "cost",
           "effect_reasons")


def _refuse(sensor: dict, query: Any) -> None:
    sid, kind = sensor.get("id"), sensor.get("type")
    if query.estimator == "forward":
        raise Invalid(f"sensor {sid!r} is a {kind} sensor: the forward estimator cannot answer it (photons from the "
                      f"lights almost never pass through a pinhole or a meter's cone; luminance is answered by paths "
                      f"from the eye); use 'backward' or 'auto'")
    for field, given in (("observe", query.observe), ("reference", query.reference),
                         ("physics_left_out", query.physics_left_out)):
        if given:
            raise Invalid(f"sensor {sid!r} is a {kind} sensor: {field} is not available for it")


def _payload(result: Any, sensor: dict, live: Any) -> dict[str, Any]:
    """The answer's JSON: the run's common fields (`service.payloads.result_payload`), ``luminance`` for ``lux``."""
    flat = SimpleNamespace(**{name: getattr(result, name) for name in _COMMON})
    flat.lux, flat.stderr = np.atleast_1d(result.luminance), np.atleast_1d(result.stderr)
    payload = result_payload(flat, live.revision)
    payload["luminance"] = payload.pop("lux")
    share = result.through_specular
    payload.update(sensor=str(sensor["id"]), type=str(sensor["type"]), strategy=str(result.strategy),
                   unreachable=result.unreachable,
                   through_specular=finite_list(np.atleast_1d(share)) if share is not None else None)
    return payload


class LuminanceAnswer(SensorAnswer):
    """A luminance meter's answer: ``luminance``/``stderr`` [one value], cd/m²."""

    type: Literal["luminance"] = Field(description="The sensor's kind.")
    luminance: list[Any] = Field(description="[The mean luminance over its cone], cd/m²; `stderr` holds its "
                                             "standard error.")
    strategy: str = Field(description="The estimator that ran, in words (paths from the eye, next-event estimation, "
                                      "MIS, specular chains).")
    unreachable: dict[str, Any] | None = Field(None, description=(
        "The lights paths from the eye cannot find in this scene (`lights`: their indices, `why`, "
        "`through_specular`, `caustic_paths`): the value lacks their light; null where nothing is missing."))
    through_specular: list[Any] | None = Field(None, description=(
        "Per value, the share of its paths whose view ray went on through a mirror or glass before any diffuse "
        "surface (a fraction)."))


class CameraAnswer(LuminanceAnswer):
    """A camera's answer: ``luminance``/``stderr`` as ``height`` rows of ``width`` pixels, cd/m², top row first."""

    type: Literal["camera"] = Field(description="The sensor's kind.")  # type: ignore[assignment]
    luminance: list[Any] = Field(description="Height rows of width pixels, top row first, each the mean luminance "
                                             "over the pixel, cd/m²; `stderr` holds the standard errors.")
    bands: int = Field(description=(
        "The bands of whole rows it was traced in, each of at most `max_points` pixels with its own rounds, seed and "
        "stop rule, then assembled (1: one query); each pixel's `stderr` is its band's."))
    width: int = Field(description="Pixels across.")
    height: int = Field(description="Pixels down.")
    position: list[float] = Field(description="The eye, world metres.")
    look_at: list[float] = Field(description="The point the view's centre passes through, world metres.")
    fov_deg: float = Field(description="The vertical field of view, degrees.")
    map_url: str | None = Field(None, description="The false-colour PNG of this result.")
    image_url: str | None = Field(None, description="The HDR image of this result (OpenEXR, cd/m², its standard "
                                                    "error as a second layer); `image.png` beside it is the "
                                                    "tone-mapped view.")


class Luminance(SensorKind):
    """A luminance meter: ``luminance`` and ``stderr`` [one value], cd/m²."""

    TYPE = "luminance"
    KEEP = "image"
    ANSWER = LuminanceAnswer
    QUANTITY = "luminance"

    @staticmethod
    def kept(sensor: dict) -> dict[str, Any]:
        return {k: sensor[k] for k in ("position", "direction", "aperture_deg") if sensor.get(k) is not None}

    @staticmethod
    def check(sensor: dict, query: Any, limits: Any, live: Any) -> None:
        _refuse(sensor, query)

    @staticmethod
    def body(sensor: dict, live: Any) -> dict:
        out: dict[str, Any] = {"type": "luminance", "position": np.asarray(sensor["position"], float),
               "direction": np.asarray(sensor["direction"], float)}
        if sensor.get("aperture_deg") is not None:
            out["aperture_deg"] = float(sensor["aperture_deg"])
        return out

    @staticmethod
    def payload(result: Any, sensor: dict, live: Any) -> dict:
        return _payload(result, sensor, live)


#: the most bands of rows one image is traced in: each is a query of its own, so a low max_points with a tall camera
#: (thousands of one-row bands) would hold a worker for minutes of per-query overhead
MAX_CAMERA_BANDS = 64


def camera_refusal(sensor: dict, limits: Any) -> str | None:
    """Why this service cannot answer a camera (None: it can): more pixels than ``max_camera_pixels``, a row wider
    than ``max_points`` (a band is whole rows of at most ``max_points`` pixels), or more than `MAX_CAMERA_BANDS`
    bands. Said when the camera is made (422, nothing stored) and by a simulate of one made before a limit was
    lowered (413)."""
    from tracer.sensors.camera import band_rows

    w, h = int(sensor["width"]), int(sensor["height"])
    if w <= limits.max_points and w * h <= limits.max_camera_pixels:
        bands = len(band_rows(w, h, limits.max_points))
        if bands <= MAX_CAMERA_BANDS:
            return None
        rows = max(1, limits.max_points // w) * MAX_CAMERA_BANDS
        return (f"a camera of {w} × {h} pixels would be traced in {bands} bands of whole rows (this service's "
                f"max_points, {limits.max_points} pixels, holds {max(1, limits.max_points // w)} of its rows a band); "
                f"at most {MAX_CAMERA_BANDS} bands make one image: ask for at most {rows} rows at this width, or "
                f"fewer pixels per row, or raise max_points (LUMENLINK_MAX_POINTS)")
    most = min(limits.max_camera_pixels, limits.max_points * h)
    ratio = w / h
    side_h = max(1, int((most / ratio) ** 0.5))
    side_w = min(limits.max_points, max(1, int(side_h * ratio)))
    while side_w * side_h > most:
        side_h -= 1
    return (f"a camera of {w} × {h} = {w * h} pixels: this service answers at most {limits.max_camera_pixels} pixels "
            f"per camera (its max_camera_pixels setting, LUMENLINK_MAX_CAMERA_PIXELS; images of more than "
            f"{limits.max_points} pixels, its max_points, are traced in bands of whole rows) and at most "
            f"{limits.max_points} pixels per row; ask for width × height at most that, e.g. {side_w} × {side_h} at "
            f"this aspect ratio")


class Camera(SensorKind):
    """A pinhole camera: ``luminance`` and ``stderr`` as ``height`` rows of ``width`` pixels, cd/m², top row
    first."""

    TYPE = "camera"
    KEEP = "image"
    ANSWER = CameraAnswer
    QUANTITY = "luminance"

    @staticmethod
    def layout(meta: dict) -> tuple[int, int]:
        return int(meta["height"]), int(meta["width"])

    @staticmethod
    def refusal(sensor: dict, limits: Any) -> tuple[str, int] | None:
        why = camera_refusal(sensor, limits)
        return None if why is None else (why, limits.max_camera_pixels)

    @staticmethod
    def size(meta: dict, values: int) -> str:
        return f"a {meta['width']} x {meta['height']} camera"

    @staticmethod
    def check(sensor: dict, query: Any, limits: Any, live: Any) -> None:
        _refuse(sensor, query)
        refusal = camera_refusal(sensor, limits)
        if refusal is not None:   # made before a limit was lowered
            raise TooLarge(f"sensor {sensor.get('id')!r}: {refusal}", limit=limits.max_camera_pixels)

    @staticmethod
    def run(limits: Any, simulation: Any) -> Any:
        """`simulation.run` for an image of up to ``max_points`` pixels; above, the same answer traced in bands of
        whole rows of at most ``max_points`` pixels each (`tracer.sensors.camera.run_in_bands`)."""
        from tracer.sensors.camera import run_in_bands

        def run(body: dict, query: Any, progress: Any = None, cancel: Any = None) -> Any:
            if int(body["width"]) * int(body["height"]) <= limits.max_points:
                return simulation.run(body, query=query, progress=progress, cancel=cancel)
            return run_in_bands(simulation, body, limits.max_points, query, progress, cancel)
        return run

    @staticmethod
    def body(sensor: dict, live: Any) -> dict:
        out: dict[str, Any] = {k: np.asarray(sensor[k], float) for k in ("position", "look_at")}
        if sensor.get("up") is not None:
            out["up"] = np.asarray(sensor["up"], float)
        for name in ("lens_diameter_m", "focus_distance_m"):
            if sensor.get(name) is not None:
                out[name] = float(sensor[name])
        return {"type": "camera", **out, "fov_deg": float(sensor["fov_deg"]), "width": int(sensor["width"]),
                "height": int(sensor["height"])}

    @staticmethod
    def payload(result: Any, sensor: dict, live: Any) -> dict:
        payload = _payload(result, sensor, live)
        payload.update(bands=int(getattr(result, "bands", 1)), width=int(sensor["width"]),
                       height=int(sensor["height"]),
                       position=finite_list(sensor["position"]), look_at=finite_list(sensor["look_at"]),
                       fov_deg=float(sensor["fov_deg"]))
        return payload
