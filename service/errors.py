"""Domain errors of the service and their one mapping to HTTP (RFC 9457 problem details).

Domain code raises a `ServiceError` subclass; `install_handlers` maps every error the app can
meet (domain errors, request validation, unknown routes, oversize bodies, bugs) to an
``application/problem+json`` body with ``type``, ``title``, ``status``, ``detail`` and, where
useful, extension members (e.g. ``missing``, ``current_revision``, ``errors``).
"""

from __future__ import annotations

import difflib
import logging
import math
import types
import typing
import uuid
from collections.abc import Callable
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException

log = logging.getLogger("lumenlink.service")

PROBLEM_JSON = "application/problem+json"


class ServiceError(ValueError):
    """Root of the service's domain errors: an HTTP status, a short title, a detail, extensions."""

    status = 400
    title = "Bad request"
    headers: dict[str, str] = {}   # sent with the answer (a 503's Retry-After)

    def __init__(self, detail: str, **extensions: Any) -> None:
        super().__init__(detail)
        self.detail = detail
        self.extensions = extensions


class BadRequest(ServiceError):
    status = 400
    title = "Bad request"


class NotFound(ServiceError):
    status = 404
    title = "Not found"


class Conflict(ServiceError):
    status = 409
    title = "Conflict"


class Invalid(ServiceError):
    """The request is well formed but its content is impossible (422)."""

    status = 422
    title = "Unprocessable content"


class TooLarge(ServiceError):
    status = 413
    title = "Content too large"


class Unavailable(ServiceError):
    """A part the request needs is not there or not free (the light transport not built, the queue full, the
    budget of request bytes in flight taken)."""

    status = 503
    title = "Service unavailable"

    def __init__(self, detail: str, **extensions: Any) -> None:
        super().__init__(detail, **extensions)
        if "retry_after_seconds" in extensions:   # said in the body and, for clients that read it, the header
            self.headers = {"Retry-After": str(max(1, math.ceil(extensions["retry_after_seconds"])))}


def problem(status: int, title: str, detail: str, **extensions: Any) -> JSONResponse:
    """An RFC 9457 response; ``type`` is about:blank as the status code says it all."""
    body = {"type": "about:blank", "title": title, "status": status, "detail": detail}
    body.update(extensions)
    return JSONResponse(body, status_code=status, media_type=PROBLEM_JSON)


def fields_at(annotation: Any, loc: list[str]) -> list[str]:
    """The field names the model at `loc` (a body's error location after ``body``) allows, walking `annotation`
    through models, lists and (discriminated) unions, whose members the location names by tag; [] if unknown."""
    t = annotation
    rest = list(loc)
    for _ in range(64):
        origin = typing.get_origin(t)
        if origin is typing.Annotated:
            t = typing.get_args(t)[0]
        elif origin in (typing.Union, types.UnionType):
            members = [a for a in typing.get_args(t) if a is not type(None)]
            if len(members) == 1:
                t = members[0]
                continue
            tag = rest[0] if rest else None
            chosen = next((m for m in members if tag is not None and _tagged(m, tag)), None)
            if chosen is None:
                return []
            t = chosen
            rest = rest[1:]
        elif origin in (list, tuple, set):
            if not rest or not rest[0].isdigit():
                return []
            t = typing.get_args(t)[0] if typing.get_args(t) else Any
            rest = rest[1:]
        elif isinstance(t, type) and issubclass(t, BaseModel):
            if not rest:
                return [f.alias or name for name, f in t.model_fields.items()]
            field = t.model_fields.get(rest[0]) or next(
                (f for f in t.model_fields.values() if f.alias == rest[0]), None)
            if field is None:
                return []
            t = field.annotation
            rest = rest[1:]
        else:
            return []
    return []


def _tagged(model: Any, tag: str) -> bool:
    """Whether a union member is the one pydantic names `tag` in an error location (its ``type`` literal or name)."""
    if not (isinstance(model, type) and issubclass(model, BaseModel)):
        return getattr(model, "__name__", None) == tag
    field = model.model_fields.get("type")
    values = typing.get_args(field.annotation) if field is not None else ()
    return tag in values or model.__name__ == tag


def validation_problem(errors: list[dict[str, Any]],
                       allowed: Callable[[list[str]], list[str]] | None = None) -> JSONResponse:
    """Pydantic errors as a 422 (400 when the body is not JSON at all), naming each bad field; a field the body may
    not have gets the closest allowed name (``allowed(loc)``: the names allowed beside it; and any missing ones),
    said in the detail and listed in ``did_you_mean``."""
    clean = [
        {"loc": [str(p) for p in e.get("loc", ())], "msg": str(e.get("msg", "")), "type": str(e.get("type", ""))}
        for e in errors
    ]
    suggestions: list[str] = []
    for e in clean:
        if e["type"] != "extra_forbidden" or not e["loc"]:
            continue
        parent, name = e["loc"][:-1], e["loc"][-1]
        names = {m["loc"][-1] for m in clean if m["type"] == "missing" and m["loc"][:-1] == parent and m["loc"]}
        if allowed is not None:
            names.update(allowed(list(parent)))
        close = difflib.get_close_matches(name, sorted(names - {name}), n=1, cutoff=0.6)
        if close:
            e["msg"] = f"{name!r} is not a field here; did you mean {close[0]!r}?"
            e["did_you_mean"] = close[0]
            suggestions.append(close[0])
        elif names:
            e["msg"] = f"{name!r} is not a field here; allowed: {', '.join(sorted(names))}"
    # the missing field a typo stands for is the same mistake: said once, by the suggestion
    same = [bool(suggestions) and e["type"] == "missing" and bool(e["loc"]) and e["loc"][-1] in suggestions
            for e in clean]
    if any(e["type"] == "json_invalid" for e in clean):
        first = next(e for e in clean if e["type"] == "json_invalid")
        return problem(400, "Malformed JSON", f"the body is not valid JSON: {first['msg']}", errors=clean)
    # a list of vectors given flat ([x, y, z, x, y, z] for [[x, y, z], [x, y, z]]): one error per number said
    # nothing of the form; say it once, first
    flat = {tuple(c["loc"][:-1]) for e, c in zip(errors, clean, strict=True)
            if c["type"] == "tuple_type" and c["loc"] and c["loc"][-1].isdigit()
            and isinstance(e.get("input"), int | float) and not isinstance(e.get("input"), bool)}
    hints = [f"{'.'.join(f)}: give a list of [x, y, z] triples, e.g. [[0, 0, 1], [1, 0, 1]], not a flat list of "
             "numbers" for f in sorted(flat)]
    rest = [e for e, dup in zip(clean, same, strict=True)
            if not dup and not (e["type"] == "tuple_type" and tuple(e["loc"][:-1]) in flat)]
    shown = "; ".join(hints + [f"{'.'.join(e['loc']) or 'body'}: {e['msg']}" for e in rest][:max(0, 5 - len(hints))])
    more = f" (and {len(hints) + len(rest) - 5} more)" if len(hints) + len(rest) > 5 else ""
    extra = {"did_you_mean": suggestions} if suggestions else {}
    return problem(422, "Invalid request", shown + more,
                   errors=[e for e, dup in zip(clean, same, strict=True) if not dup][:100], **extra)


def install_handlers(app: FastAPI) -> None:
    """Register the one mapping from exceptions to problem+json responses."""

    @app.exception_handler(ServiceError)
    async def _domain(_: Request, exc: ServiceError) -> JSONResponse:
        response = problem(exc.status, exc.title, exc.detail, **exc.extensions)
        response.headers.update(exc.headers)
        return response

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        body_field = getattr(request.scope.get("route"), "body_field", None)
        annotation = getattr(getattr(body_field, "field_info", None), "annotation", None)

        def allowed(loc: list[str]) -> list[str]:
            if annotation is None or not loc or loc[0] != "body":
                return []
            return fields_at(annotation, loc[1:])

        return validation_problem(list(exc.errors()), allowed)

    @app.exception_handler(ValidationError)
    async def _pydantic(_: Request, exc: ValidationError) -> JSONResponse:
        return validation_problem([dict(e) for e in exc.errors(include_url=False, include_input=False)])

    @app.exception_handler(StarletteHTTPException)
    async def _http(_: Request, exc: StarletteHTTPException) -> JSONResponse:
        titles = {404: "Not found", 405: "Method not allowed", 413: "Content too large"}
        response = problem(exc.status_code, titles.get(exc.status_code, "HTTP error"), str(exc.detail))
        response.headers.update(exc.headers or {})   # a 405 keeps its Allow
        return response

    @app.exception_handler(Exception)
    async def _bug(request: Request, exc: Exception) -> JSONResponse:
        # the details (an SQL statement, a path) go to the log, not to the client; the server closes the
        # connection after a 500 (Starlette re-raises to it), so the answer says so
        incident = uuid.uuid4().hex[:12]
        log.exception("unhandled error (incident %s) on %s %s", incident, request.method, request.url.path)
        response = problem(500, "Internal server error", f"an unexpected {type(exc).__name__}; the service log "
                           f"has the details under incident {incident}", incident=incident)
        response.headers["Connection"] = "close"
        return response
