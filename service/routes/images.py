"""A camera's latest image (`service.images`, `service.view_kinds`):

- ``GET /scenes/{id}/sensors/{sid}/image.exr`` — HDR OpenEXR: ``Y``, the luminance in cd/m², and ``stderr.Y``, its
  standard error (cd/m²), as a second layer;
- ``GET /scenes/{id}/sensors/{sid}/image.png`` — tone-mapped 8-bit grey, one PNG pixel per image pixel (Reinhard's
  global operator on luminance, key 0.18).

(``map.png``, the false-colour map with its cd/m² legend, is the sensor map route's: `service.routes.simulation`.)
The image is that of the latest simulation while the scene is unchanged since (from memory, or after a restart from
the result store: `service.simulation.SimulationHub.view_result`); 404 until then, 422 for a sensor that is not a
camera.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response

from service.errors import Invalid, NotFound
from service.images import tone_mapped_png, write_exr
from service.routes.deps import ItemId, SceneId
from service.sensor_kinds import kind_of, types_where
from service.simulation import find_sensor, hub_for

router = APIRouter(tags=["simulation"])
EXR = "image/x-exr"


def camera_result(request: Request, scene_id: str, sensor_id: str) -> dict[str, Any]:
    """The latest result of camera `sensor_id` while the scene is unchanged: 404 without one, 422 for a sensor of
    another kind."""
    hub = hub_for(request.app)
    live = hub.live.get(scene_id)
    sensor = find_sensor(live, sensor_id)
    if "image_url" not in kind_of(sensor).ANSWER.model_fields:
        imaged = types_where(lambda k: "image_url" in k.ANSWER.model_fields)
        raise Invalid(f"sensor {sensor_id!r} is a {sensor.get('type')} sensor; images exist for {imaged} sensors")
    result = hub.view_result(scene_id, sensor)
    if result is None:
        raise NotFound(f"sensor {sensor_id!r} has no image of the scene as it is now (revision {live.revision}); "
                       f"POST /scenes/{scene_id}/sensors/{sensor_id}/simulate first", revision=live.revision)
    return result


def _headers(result: dict[str, Any], name: str) -> dict[str, str]:
    return {"X-Scene-Revision": str(result["revision"]), "Cache-Control": "no-store",
            "Content-Disposition": f'inline; filename="{name}"'}


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/image.exr", name="sensor_image_exr", response_class=Response,
            responses={200: {"content": {EXR: {}}, "description": "OpenEXR, channels Y and stderr.Y, cd/m²."},
                       404: {}})
def image_exr(scene_id: SceneId, sensor_id: ItemId, request: Request) -> Response:
    """The camera's latest image as OpenEXR (uncompressed FLOAT scanlines, row 0 the top): ``Y`` the luminance,
    cd/m², and ``stderr.Y`` its standard error, cd/m²; ``whiteLuminance`` 1 (a value of 1 is 1 cd/m²)."""
    result = camera_result(request, scene_id, sensor_id)
    note = (f"LumenLink scene {scene_id} revision {result['revision']} sensor {sensor_id}: Y luminance cd/m2, "
            f"stderr.Y its standard error; {result['photons']} paths, {result['estimator']}")
    return Response(write_exr(result["luminance"], result["stderr"], note), media_type=EXR,
                    headers=_headers(result, f"{sensor_id}.exr"))


@router.get("/scenes/{scene_id}/sensors/{sensor_id}/image.png", name="sensor_image_png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, 404: {}})
def image_png(scene_id: SceneId, sensor_id: ItemId, request: Request) -> Response:
    """The camera's latest image, tone-mapped: Reinhard's global operator on luminance (key 0.18 over the image's
    log-average luminance, Ld = Lm / (1 + Lm)), sRGB-encoded 8-bit grey, width × height pixels."""
    result = camera_result(request, scene_id, sensor_id)
    return Response(tone_mapped_png(result["luminance"]), media_type="image/png",
                    headers=_headers(result, f"{sensor_id}.png"))
