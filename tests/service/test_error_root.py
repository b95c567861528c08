"""One error root for the service: every exception class a service module defines is a `ServiceError`, so it
carries its HTTP status and title and the one handler (`service.errors.install_handlers`) answers it."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import service
from service.errors import ServiceError


def test_every_error_the_service_defines_has_the_one_root():
    defined = []
    for info in pkgutil.walk_packages(service.__path__, "service."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if inspect.isclass(obj) and issubclass(obj, BaseException) and obj.__module__ == info.name:
                defined.append(obj)
    names = {c.__name__ for c in defined}
    assert {"TreeError", "MapError", "JobError", "JobNotFound", "QueueFull", "Raced"} <= names
    assert [c.__name__ for c in defined if not issubclass(c, ServiceError)] == []


def test_the_job_runner_s_errors_say_their_status():
    from service.jobs import JobNotFound, QueueFull
    from service.maps import MapError
    from service.store import Raced
    from service.tree import TreeError

    assert (JobNotFound("no job 'x'").status, QueueFull("full").status, MapError("bad").status) == (404, 503, 500)
    assert Raced("s1").status == 409 and "s1" in Raced("s1").detail
    err = TreeError("bad tree", [{"uuid": "u", "problem": "p"}] * 150)
    assert err.status == 422 and len(err.problems) == 150 and len(err.extensions["problems"]) == 100
