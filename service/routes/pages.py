"""Pages for people (docs/DESIGN.md, "For people") and the API docs, all served by the service itself.

- ``GET /``: the scenes, each a link to its view;
- ``GET /scenes/{id}/view``: the model in 3D (three.js): instances placed by their world transforms, grid sensors as
  false-colour planes from their latest results (legend, linear/log), the model's own surfaces coloured per triangle
  by a surface sensor's latest result (same scale), lights as markers, the last push's changes highlighted, job
  progress, live updates; a click names the node, its material and, on a sensor cell or a coloured triangle,
  lux ± error (``service/web/src/*.js``);
- ``GET /scenes/{id}/view/state``: everything that page draws, in one JSON answer;
- ``GET /scenes/{id}/events``: server-sent events when the scene changes, a job moves or a result lands
  (`service.events`);
- ``GET /docs``, ``GET /redoc``: Swagger UI and ReDoc with their scripts and styles served from ``/static``;
- ``GET /sign-in``, ``POST /sign-in``, ``GET /sign-out``: where a service has a token (``LUMENLINK_TOKEN``), a person
  signs in once with it and the browser keeps a cookie that stands for it (`service.middleware.BearerToken`).

No CDN at run time: the browser code comes from npm packages pinned by ``service/web/package-lock.json`` and
installed by ``make web`` (``npm ci``) into ``service/web/node_modules``, mounted read-only under ``/static``. When
they are missing the pages answer 503 saying how to install them; the API itself does not need them.
"""

from __future__ import annotations

import hmac
import html
import re
import time
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs

from fastapi import APIRouter, FastAPI, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html, get_swagger_ui_oauth2_redirect_html
from fastapi.responses import HTMLResponse, Response, StreamingResponse
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool

from service.errors import Unavailable
from service.events import EventHub, PageEventsMiddleware
from service.middleware import SESSION_COOKIE, session_value
from service.routes.deps import SceneId
from service.sensor_kinds import kind_of

WEB_DIR = Path(__file__).resolve().parents[1] / "web"
SRC_DIR = WEB_DIR / "src"
NODE_MODULES = WEB_DIR / "node_modules"

#: URL prefix -> the directory served there (read-only; nothing outside these directories is reachable)
STATIC_DIRS = {
    "/static/app": SRC_DIR,
    "/static/three/build": NODE_MODULES / "three" / "build",
    "/static/three/addons": NODE_MODULES / "three" / "examples" / "jsm",
    "/static/swagger-ui": NODE_MODULES / "swagger-ui-dist",
}
#: the file each page cannot do without, per npm package
REQUIRED = {
    "three": NODE_MODULES / "three" / "build" / "three.module.js",
    "swagger-ui-dist": NODE_MODULES / "swagger-ui-dist" / "swagger-ui-bundle.js",
    "redoc": NODE_MODULES / "redoc" / "bundles" / "redoc.standalone.js",
}
FAVICON = "/static/app/favicon.svg"
#: finished jobs of a scene the view shows besides the running ones
RECENT_JOBS = 5

router = APIRouter(tags=["pages"])


def install(app: FastAPI, responses: dict[int | str, dict[str, Any]]) -> None:
    """Add the pages, the docs, their static files and the event streams to `app` (``app.state.events``).

    Call before the other middleware is added: the page events' watcher then runs innermost, after the token
    check. Build the app with ``docs_url=None, redoc_url=None``: the docs routes here replace FastAPI's.
    """
    events = EventHub(app.state.live, jobs=lambda: _jobs_of(app))
    app.state.events = events
    for prefix, directory in STATIC_DIRS.items():
        app.mount(prefix, StaticFiles(directory=directory, check_dir=False), name="static" + prefix.replace("/", "-"))
    app.include_router(router, responses=responses)
    app.add_middleware(PageEventsMiddleware, events=events)


def _jobs_of(app: FastAPI) -> list[dict[str, Any]]:
    hub = getattr(app.state, "simulation_hub", None)
    return hub.jobs.jobs() if hub is not None else []


def _need(package: str) -> None:
    if not REQUIRED[package].is_file():
        raise Unavailable(f"the page's scripts are not installed (npm package {package!r} missing from "
                          f"{NODE_MODULES}): run `make web` (npm ci in service/web)")


def _page(page: str, **values: str) -> HTMLResponse:
    """An HTML file of ``service/web/src`` with its ``{{key}}`` markers replaced by escaped values."""
    text = (SRC_DIR / page).read_text(encoding="utf-8")
    for key, value in values.items():
        text = text.replace("{{" + key + "}}", html.escape(value, quote=True))
    return HTMLResponse(text, headers={"Cache-Control": "no-store"})


HTML_200: dict[int | str, dict[str, Any]] = {
    200: {"content": {"text/html": {"schema": {"type": "string"}}}, "description": "An HTML page."}}


# -------------------------------------------------------------------------------------------- pages


@router.get("/", response_class=HTMLResponse, responses={**HTML_200})
def index(request: Request) -> HTMLResponse:
    """The page for people: every scene, with its revision, each a link to its 3D view; links to the API docs."""
    scenes = request.app.state.manager.list_scenes()
    rows = "\n".join(
        f'<li><a href="/scenes/{html.escape(s["id"])}/view">{html.escape(s["name"])}</a> '
        f'<span class="muted">revision {int(s["revision"])}</span></li>' for s in scenes)
    text = (SRC_DIR / "index.html").read_text(encoding="utf-8")
    text = text.replace("{{scenes}}", rows or '<li class="muted">No scenes yet: push a model (lumenlink push) '
                                             'or run lumenlink demo --serve.</li>')
    return HTMLResponse(text, headers={"Cache-Control": "no-store"})


def _local(target: str) -> str:
    """`target` where it is a path of this service, else "/": signing in never sends anyone to another site."""
    return target if target.startswith("/") and not target.startswith(("//", "/\\")) else "/"


@router.get("/sign-in", response_class=HTMLResponse, include_in_schema=False)
def sign_in_page(request: Request, next: str = "/") -> Response:
    """The sign-in form (a service without a token needs none: straight on to `next`)."""
    if not request.app.state.settings.token:
        return Response(status_code=303, headers={"Location": _local(next)})
    return _page("sign-in.html", next=_local(next), problem="")


@router.post("/sign-in", response_class=HTMLResponse, include_in_schema=False)
async def sign_in(request: Request) -> Response:
    """Check the form's token: on a match, the cookie and on to `next`; otherwise the form again with a 401."""
    form = parse_qs((await request.body()).decode("utf-8", "replace"))
    given, target = form.get("token", [""])[0], _local(form.get("next", ["/"])[0])
    token = request.app.state.settings.token
    if not token:
        return Response(status_code=303, headers={"Location": target})
    if not hmac.compare_digest(given.encode(), token.encode()):
        page = _page("sign-in.html", next=target, problem="That is not this service's token (LUMENLINK_TOKEN).")
        page.status_code = 401
        return page
    answer = Response(status_code=303, headers={"Location": target})
    answer.set_cookie(SESSION_COOKIE, session_value(token), httponly=True, samesite="strict", path="/",
                      secure=request.url.scheme == "https")
    return answer


@router.get("/sign-out", include_in_schema=False)
def sign_out() -> Response:
    """Forget the cookie; back to the sign-in form."""
    answer = Response(status_code=303, headers={"Location": "/sign-in"})
    answer.delete_cookie(SESSION_COOKIE, path="/")
    return answer


@router.get("/scenes/{scene_id}/view", response_class=HTMLResponse, responses={**HTML_200, 503: {}})
def view(scene_id: SceneId, request: Request) -> HTMLResponse:
    """The scene in 3D (three.js, served by this service): 404 for an unknown scene, 503 if the page's scripts
    are not installed (`make web`)."""
    summary = request.app.state.manager.summary(scene_id)  # 404 first
    _need("three")
    return _page("view.html", scene_id=scene_id, name=str(summary["name"]))


@router.get("/scenes/{scene_id}/view/state", responses={200: {"description": (
    "What the 3D view draws (all lengths in metres, world frame: the service's): `scene` (id, name, revision, "
    "length_unit); `instances` (instance id, `node` UUID or `object` id, `geometry` id (GET /geometries/{gid}), "
    "`matrix`: world_from_mesh, 16 numbers row-major, `material`: the effective body); `nodes` (uuid, parent, "
    "name, path, color); `lights` (bodies in world metres, with id and name; a goniometric light's file text "
    "left out); "
    "`sensors` (bodies in world metres with id, name and `result`: the latest grid result at the current scene "
    "state — `lux` and `stderr` as nv rows of nu cells, lx; for a surface sensor `instances` instead: instance, "
    "node, path, geometry, `lux` and `stderr` per triangle, lx — or null); `last_push` (the changes of the last push "
    "through this process: UUID lists `added`, `moved`, `geometry_changed`, `removed`, `renamed`, capped at "
    "10,000 each, and their exact `counts`; null if none); `jobs` (running and recent jobs of the scene, without "
    "results); `elements` (the optical elements with an inside on its parts: assignment id, element id, node, "
    "model, and whether it is applied, or why not).")}})
def view_state(scene_id: SceneId, request: Request) -> dict[str, Any]:
    """Everything the 3D view of a scene draws, in one answer (see the 200 response)."""
    app = request.app
    manager, registry = app.state.manager, app.state.live
    from service.simulation import hub_for

    hub = hub_for(app)
    with registry.lock(scene_id):  # 404 for an unknown scene; no push changes the scene while we read it
        live = registry.get(scene_id)
        nodes = manager.nodes(scene_id)
        owner = {inst: key for key, inst in live.instance_of_node.items()}
        instances = []
        for inst in live.tracer.instances():
            if live.tracer.is_sensor(inst) or inst not in owner:
                continue
            key = owner[inst]
            is_object = key in live.extras.get("objects", {})
            instances.append({
                "instance": inst, "node": None if is_object else key, "object": key if is_object else None,
                "geometry": live.tracer.instance_geometry(inst),
                "matrix": [float(x) for x in live.tracer.instance_transform(inst).ravel()],
                "material": live.materials.get(inst, live.default_material)})
        objects = {oid: {"id": oid, "name": body.get("name"), "attached_to": body.get("attached_to")}
                   for oid, body in live.extras.get("objects", {}).items()}
        names = {kind: {a["id"]: a["body"].get("name") for a in manager.list_assignments(scene_id, kind)}
                 for kind in ("light", "sensor")}
        lights = [{**{k: v for k, v in light.items() if k != "data"}, "name": names["light"].get(light.get("id"))}
                  for light in live.lights]
        sensors = []
        for sensor in live.sensors:
            sid = str(sensor.get("id"))
            kind = kind_of(sensor)
            shown = kind.KEEP == "map" and kind.QUANTITY == "lux"   # the page simulates it and shows its lux
            result = hub.grid_result(scene_id, sid) if shown else None
            # a surface's result: per instance (`instances`: node, path, geometry, lux and stderr per triangle)
            keys = ("instances",) if "instances" in kind.ANSWER.model_fields else ("lux", "stderr")
            sensors.append({**sensor, "name": names["sensor"].get(sid), "simulate": shown, "packs": kind.PACKS,
                            "result": None if result is None else {
                k: result.get(k) for k in (*keys, "revision", "photons", "seconds", "estimator",
                                           "stop_reason", "min_lux", "mean_lux", "max_lux")}})
        scene = {"id": scene_id, "name": manager.summary(scene_id)["name"], "revision": live.revision,
                 "length_unit": live.extras.get("length_unit")}
    jobs = [{k: v for k, v in j.items() if k not in ("result", "generation")}
            for j in hub.jobs.jobs() if j.get("scene_id") == scene_id]
    running = [j for j in jobs if j["status"] in ("queued", "running")]
    finished = [j for j in jobs if j["status"] not in ("queued", "running")][-RECENT_JOBS:]
    return {"scene": scene, "instances": instances, "objects": list(objects.values()),
            "nodes": [{k: n[k] for k in ("uuid", "parent", "name", "path", "color")} for n in nodes],
            "lights": lights, "sensors": sensors, "last_push": app.state.events.last_push(scene_id),
            "jobs": running + finished, "elements": manager.assignments.list_elements(scene_id), "time": time.time()}


@router.get("/scenes/{scene_id}/events", response_class=StreamingResponse, responses={
    200: {"content": {"text/event-stream": {"schema": {"type": "string"}}}, "description": (
        "Server-sent events (stays open up to 300 s; a browser's EventSource reconnects by itself): `hello` "
        "{revision} first; `scene` {revision} after a push or an assignment change; `push` {revision, counts} "
        "after a push through this process (GET view/state has its change lists); `job` (a job's state, without "
        "result) when its status or progress changes; `result` {sensor} when a sensor's result lands; `resync` "
        "when events were lost (read the state again); `deleted` when the scene is deleted (the stream ends). "
        "Every data line is JSON.")},
    503: {"description": "Too many event streams are open: retry later."}})
async def scene_events(scene_id: SceneId, request: Request) -> StreamingResponse:
    """Live updates of one scene as server-sent events (see the 200 response); 404 for an unknown scene."""
    revision = await run_in_threadpool(request.app.state.live.revision, scene_id)
    events: EventHub = request.app.state.events
    if not events.has_room():
        raise Unavailable("too many event streams are open (or the service is stopping): retry later",
                          retry_after_seconds=5)
    return StreamingResponse(events.stream(scene_id, {"revision": revision}), media_type="text/event-stream",
                             headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"})


# -------------------------------------------------------------------------------------------- API docs


@router.get("/docs", include_in_schema=False)
def swagger_ui(request: Request) -> HTMLResponse:
    _need("swagger-ui-dist")
    return get_swagger_ui_html(
        openapi_url=request.app.openapi_url, title=f"{request.app.title} — Swagger UI",
        swagger_js_url="/static/swagger-ui/swagger-ui-bundle.js", swagger_css_url="/static/swagger-ui/swagger-ui.css",
        swagger_favicon_url=FAVICON, oauth2_redirect_url="/docs/oauth2-redirect",
        swagger_ui_parameters={"validatorUrl": None})   # no badge fetched from validator.swagger.io


@router.get("/docs/oauth2-redirect", include_in_schema=False)
def swagger_ui_redirect() -> HTMLResponse:
    return get_swagger_ui_oauth2_redirect_html()


@router.get("/redoc", include_in_schema=False)
def redoc(request: Request) -> HTMLResponse:
    _need("redoc")
    return get_redoc_html(openapi_url=request.app.openapi_url, title=f"{request.app.title} — ReDoc",
                          redoc_js_url=REDOC_JS_URL, redoc_favicon_url=FAVICON, with_google_fonts=False)


REDOC_JS_URL = "/static/redoc/redoc.standalone.js"
#: ReDoc 2's bundle draws Redocly's logo from their host under its menu, unconditionally; served here with an empty
#: inline image instead (any host's URL of that logo), so that the page makes no request beyond this service
REDOC_LOGO = re.compile(rb"https://[\w.-]+/redoc/logo-mini\.svg")
EMPTY_IMAGE = b"data:image/svg+xml,%3Csvg xmlns='http://www.w3.org/2000/svg'/%3E"
_redoc_js: list[bytes] = []


@router.get(REDOC_JS_URL, include_in_schema=False)
def redoc_js() -> Response:
    _need("redoc")
    if not _redoc_js:
        _redoc_js.append(REDOC_LOGO.sub(EMPTY_IMAGE, REQUIRED["redoc"].read_bytes()))
    return Response(_redoc_js[0], media_type="text/javascript", headers={"Cache-Control": "max-age=3600"})

