"""The service itself: liveness, readiness (GL context and warm-up frame), and what it offers."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from renderer.animation import MUSEUM_KINDS
from renderer.limits import MAX_IMAGE_SIDE
from renderer.profiles import PROFILES
from renderer.settings import FORMATS, METHODS, MODES
from renderer.tree_update import UPDATE_SCHEMES

from ... import metrics
from ...models import HealthOut, InfoOut, LimitsOut, ReadyOut
from ...service import info_extras
from ..deps import ServiceDep, WorkerDep

router = APIRouter()

READY_RETRY_AFTER_S = 1   # the warm-up frame takes about a second on llvmpipe


@router.get("/health", response_model=HealthOut, summary="Liveness")
def health() -> HealthOut:
    return HealthOut(status="ok")


@router.get("/ready", response_model=ReadyOut, responses={503: {"model": ReadyOut, "description": "not ready"}},
            summary="Readiness: GL context created, warm-up render done, session store read and written")
def ready(request: Request, worker: WorkerDep, service: ServiceDep) -> Any:
    info = worker.info or {}
    drain = getattr(request.app.state, "drain", None)
    draining = (drain is not None and drain.draining.is_set()) or worker.closing
    saturated = worker.saturated
    # The store is checked the way requests use it: a write and a read of a probe record (SQLite: on
    # the file that was opened, still a database) — a ping would pass on a deleted or overwritten file.
    store_fault = service.store.probe() if worker.ready.is_set() else None
    out = ReadyOut(ready=not draining and not saturated and worker.ready.is_set() and store_fault is None,
                   gl_renderer=info.get("renderer"), gl_version=info.get("version"))
    if out.ready:
        return out
    retry = READY_RETRY_AFTER_S
    if draining:   # shutdown has begun: a balancer takes this process out of rotation
        out.detail = "draining: the process is shutting down"
    elif saturated:             # the work queued ahead is more than a render may wait
        retry = worker.retry_after()
        out.detail = (f"saturated: {worker.queued_ms() / 1e3:,.1f} s of GL work queued, over the render timeout "
                      f"of {worker.render_timeout_s:g} s (POCKETRAY_RENDER_TIMEOUT_S)")
    else:
        out.detail = worker.error or (f"state backend: {store_fault}" if worker.ready.is_set() else
                                      "starting: creating the GL context and rendering the warm-up frame")
    metrics.unavailable("draining" if draining else "saturated" if saturated else "not_ready")
    return JSONResponse(out.model_dump(), status_code=503, headers={"Retry-After": str(retry)})


@router.get("/info", response_model=InfoOut, summary="Methods, modes, formats and limits of this service")
def info(service: ServiceDep) -> InfoOut:
    c = service.config
    return InfoOut(methods=list(METHODS), modes=list(MODES), formats=list(FORMATS), state_backend=c.state_backend,
                   profiles=PROFILES, update_schemes=list(UPDATE_SCHEMES), museum_kinds=list(MUSEUM_KINDS),
                   limits=LimitsOut(max_work=c.max_work, max_frame_cost=c.max_frame_cost, slice_ms=c.slice_ms,
                                    max_spheres=c.max_spheres, max_triangles=c.max_triangles,
                                    max_body_bytes=c.max_body_bytes,
                                    max_image_side=MAX_IMAGE_SIDE, queue_size=c.queue_size,
                                    session_ttl_s=c.session_ttl_s),
                   **info_extras(c))
