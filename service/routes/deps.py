"""Dependencies shared by the routes: the scene manager of the app."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from service.state import SceneManager


def get_manager(request: Request) -> SceneManager:
    return request.app.state.manager


Manager = Annotated[SceneManager, Depends(get_manager)]
