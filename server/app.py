"""The FastAPI application (``server.app:app``): the factory, its lifespan, middleware and
static files. The routes are in :mod:`server.api.routes`, the error answers in
:mod:`server.api.errors`; docs/API.md describes the API.

Lifespan: opens the state backend, starts the GL thread (context + warm-up render, in the
background: /api/ready turns 200 once both succeeded) and closes both at shutdown. Routes
get the service through ``Depends(get_service)`` (it lives on ``app.state``), never
through globals.

``uvicorn server.app:app`` serves the module's app (configured from the environment);
``pocketray serve`` (:mod:`server.tools.cli`) runs ``server.app:create_app`` as a factory, so that
``--workers N`` works: each worker makes its own app, and with it its own GL context.

Middleware, outermost first: the security headers (:mod:`server.http.security`), request id /
session id / access log / HTTP metrics (:mod:`server.http.observability`), the refusal of requests
framed by both Content-Length and Transfer-Encoding (:mod:`server.http.framing`), CORS
(:mod:`server.http.cors_docs`), OPTIONS and 405 (:mod:`server.http.allow`), the body limit.
"""

from __future__ import annotations

import os
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.concurrency import run_in_threadpool
from fastapi.staticfiles import StaticFiles

from renderer.config.settings import RenderSettings
from renderer.scenes.scenarios import scenario

from .api import errors
from .api.routes import api_router, metrics as metrics_route
from .config import ServerConfig
from .frames.pipeline import FramePipeline
from .frames.trace import GLWorker, VariantRate, default_renderer
from .http import cors_docs, metrics
from .http.allow import AllowMethods
from .http.body_limit import BodyLimit
from .http.drain import Drain
from .http.framing import SingleFraming
from .http.observability import RequestContext, configure_logging
from .http.security import SecurityHeaders
from .sessions.service import SessionService
from .sessions.shared_refine import start_shared_refine
from .sessions.store import open_store

GPU_INDEX_ENV = "GLCONTEXT_DEVICE_INDEX"  # glcontext's EGL backend picks its GPU by this index

WARMUP_SIDE = 16  # pixels: the warm-up frame only has to compile the default shader
WARMUP_SPHERES = 16


def warmup_render(renderer: Any) -> None:
    """A tiny frame with the default settings' shader variant (compiles it once)."""
    defaults = RenderSettings()
    renderer.render(scenario(3, WARMUP_SPHERES), defaults.with_(width=WARMUP_SIDE, height=WARMUP_SIDE))


def create_app(config: ServerConfig | None = None) -> FastAPI:
    """A new application for ``config`` (default: from POCKETRAY_* environment variables)."""
    config = config or ServerConfig()
    configure_logging(config.log_level, config.log_format)
    drain = Drain(config.drain_s)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        if config.gpu is not None:
            os.environ[GPU_INDEX_ENV] = str(config.gpu)
        sys.setswitchinterval(config.switch_interval_s)  # the event loop's turn between busy threads
        store = open_store(config)
        worker = GLWorker(
            config.queue_size,
            warmup=warmup_render if config.warmup else None,
            renderer_factory=lambda: default_renderer(config.max_target_bytes, config.max_programs),
            render_timeout_s=config.render_timeout_s,
            variant_rate=VariantRate(config.new_variants_per_min, config.new_variants_burst),
        )
        worker.start()
        app.state.config = config
        app.state.store = store
        app.state.worker = worker
        app.state.frames = FramePipeline(config, worker)
        app.state.service = SessionService(config, store, app.state.frames)
        app.state.service.shared_refine = shared = start_shared_refine(config, store, app.state.service)
        app.state.drain = drain
        app.state.is_ready = lambda: worker.ready.is_set() and not drain.draining.is_set()
        drain.install()
        try:
            yield
        finally:
            drain.begin("lifespan shutdown")
            drain.uninstall()
            await run_in_threadpool(worker.close)  # (first: a helper's frame in flight ends with it)
            if shared is not None:
                await run_in_threadpool(shared.close)
            store.close()
            metrics.process_exit()

    app = FastAPI(
        title="pocketray render service",
        version="0.1.0",
        lifespan=lifespan,
        description="Sessions (Model), gestures (Controller) and frames (View) of the pocketray "
        "ray tracer; see docs/API.md.",
        docs_url=None,
        redoc_url=None,
        openapi_tags=cors_docs.OPENAPI_TAGS,
        generate_unique_id_function=cors_docs.operation_id,
    )
    # add_middleware wraps what is there: the last added runs first.
    app.add_middleware(BodyLimit, max_bytes=config.max_body_bytes)
    app.add_middleware(AllowMethods)  # OPTIONS and 405 with the path's real Allow (server/http/allow.py)
    cors_docs.install_cors(app, config.cors_origins)
    app.add_middleware(SingleFraming)  # before the body limit, which trusts Content-Length
    app.add_middleware(RequestContext)
    app.add_middleware(SecurityHeaders)
    errors.install(app)
    app.include_router(api_router)
    app.include_router(metrics_route.router)
    cors_docs.install_docs(app)
    if not config.client_dir.is_dir():
        config.client_dir.mkdir(parents=True, exist_ok=True)
    if config.shader_dir.is_dir():
        app.mount("/shaders", StaticFiles(directory=config.shader_dir), name="shaders")
    app.mount("/", StaticFiles(directory=config.client_dir, html=True), name="client")
    return app


app = create_app()
