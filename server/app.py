"""The FastAPI application (``server.app:app``): the factory, its lifespan, middleware and
static files. The routes are in :mod:`server.api.routes`, the error answers in
:mod:`server.api.errors`; docs/API.md describes the API.

Lifespan: opens the state backend, starts the GL thread (context + warm-up render, in the
background: /api/ready turns 200 once both succeeded) and closes both at shutdown. Routes
get the service through ``Depends(get_service)`` (it lives on ``app.state``), never
through globals.
"""

from __future__ import annotations

import sys
from contextlib import asynccontextmanager
from typing import Any, AsyncIterator

from fastapi import FastAPI
from fastapi.concurrency import run_in_threadpool
from fastapi.staticfiles import StaticFiles

from renderer.scenarios import scenario
from renderer.settings import RenderSettings

from . import api
from .allow import AllowMethods
from .api import errors
from .body_limit import BodyLimit
from .config import ServerConfig
from .gl_worker import GLWorker, default_renderer
from .service import SessionService
from .store import open_store

WARMUP_SIDE = 16       # pixels: the warm-up frame only has to compile the default shader
WARMUP_SPHERES = 16


def warmup_render(renderer: Any) -> None:
    """A tiny frame with the default settings' shader variant (compiles it once)."""
    defaults = RenderSettings()
    renderer.render(scenario(3, WARMUP_SPHERES), defaults.with_(width=WARMUP_SIDE, height=WARMUP_SIDE))


def create_app(config: ServerConfig | None = None) -> FastAPI:
    """A new application for ``config`` (default: from POCKETRAY_* environment variables)."""
    config = config or ServerConfig()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        sys.setswitchinterval(config.switch_interval_s)   # the event loop's turn between busy threads (#17)
        store = open_store(config)
        worker = GLWorker(config.queue_size, warmup=warmup_render if config.warmup else None,
                          renderer_factory=lambda: default_renderer(config.max_target_bytes),
                          render_timeout_s=config.render_timeout_s)
        worker.start()
        app.state.config = config
        app.state.store = store
        app.state.worker = worker
        app.state.service = SessionService(config, store, worker)
        try:
            yield
        finally:
            await run_in_threadpool(worker.close)
            store.close()

    app = FastAPI(title="pocketray render service", version="0.1.0", lifespan=lifespan,
                  description="Sessions (Model), gestures (Controller) and frames (View) of the pocketray "
                              "ray tracer; see docs/API.md.")
    app.add_middleware(BodyLimit, max_bytes=config.max_body_bytes)
    app.add_middleware(AllowMethods)     # OPTIONS and 405 with the path's real Allow (server/allow.py)
    errors.install(app)
    app.include_router(api.api_router)
    config.client_dir.mkdir(parents=True, exist_ok=True)
    if config.shader_dir.is_dir():
        app.mount("/shaders", StaticFiles(directory=config.shader_dir), name="shaders")
    app.mount("/", StaticFiles(directory=config.client_dir, html=True), name="client")
    return app


app = create_app()
