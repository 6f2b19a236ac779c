"""The service itself: liveness, readiness (GL context, warm-up frame, its own store), and what it offers."""

from __future__ import annotations

from typing import Any

import anyio
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from renderer.config.methods import AUTO_LABEL, AUTO_METHOD, METHODS, resolve_method
from renderer.config.settings import FORMATS, METHOD_NAMES, MODES, SETTINGS, IntegratorValues, setting
from renderer.frame.cost import PATH_SEGMENTS_LIMIT, PATH_SEGMENTS_RATE
from renderer.frame.profiles import PROFILES
from renderer.integrators import Integrator
from renderer.limits import (
    MAX_IMAGE_SIDE,
)
from renderer.modes import AVERAGED_MODES, HEAT_SCALE, MODE_LABELS, RECURSION_COLOR_NAMES, RECURSION_COLORS
from renderer.scenes.animation import MUSEUM_KINDS, MUSEUM_ROOM_SPHERES
from renderer.scenes.scenarios import DEMO_SCENES
from renderer.scenes.tree_update import UPDATE_SCHEMES

from ...config import ServerConfig
from ...http import metrics
from ..deps import ServiceDep
from ..schemas import HealthOut, InfoOut, LimitsOut, ReadyOut

router = APIRouter()


def method_settings(name: str) -> dict[str, Any]:
    """What a client needs to show only the settings that apply to method ``name``: its label, the
    settings its build or passes read, its modes, its update schemes, whether a browser can
    trace it and whether it traces meshes on the GPU (``auto`` answers for the BIH it picks
    above the crossover)."""
    caps = METHODS[resolve_method(name, 1 << 30)].capabilities
    return {
        "label": AUTO_LABEL if name == AUTO_METHOD else METHODS[name].label,
        "settings": list(caps.settings),
        "modes": list(caps.modes),
        "update_schemes": list(caps.update_schemes),
        "device": caps.device,
        "tests_every_sphere": caps.tests_every_sphere,
        "auto": name == AUTO_METHOD,
        "primitives": list(caps.primitives),
        "meshes_on_gpu": caps.meshes_on_gpu,
    }


def _values(name: str, integrator: Integrator) -> IntegratorValues:
    by = setting(name).by_integrator
    assert by is not None, f"{name}: declared per integrator"
    return by[integrator]


def info_extras(config: ServerConfig) -> dict[str, Any]:
    """The parts of GET /api/info a client's settings form needs beyond the lists and limits (the
    integrators' samples and depths as ``settings`` declares them, under their older names too)."""
    whitted_spp, path_spp = (_values("samples_per_pixel", i) for i in (Integrator.WHITTED, Integrator.PATH))
    whitted_depth, path_depth = (_values("max_recursion_depth", i) for i in (Integrator.WHITTED, Integrator.PATH))
    assert whitted_spp.choices and path_spp.bounds and whitted_depth.bounds and path_depth.bounds
    return {
        "samples_per_pixel": list(whitted_spp.choices),
        "max_recursion_depth": whitted_depth.bounds[1],
        "path": {
            "samples_per_pixel": list(path_spp.listed() or ()),
            "max_samples": path_spp.bounds[1],
            "max_depth": path_depth.bounds[1],
            "segments_limit": PATH_SEGMENTS_LIMIT,
            "segments_rate": PATH_SEGMENTS_RATE,
        },
        "render_timeout_s": config.render_timeout_s,
        "museum_room_spheres": MUSEUM_ROOM_SPHERES,
        "method_settings": {name: method_settings(name) for name in METHOD_NAMES},
        "settings": [s.metadata() for s in SETTINGS],
        "scenes": [d.to_json() for d in DEMO_SCENES],
    }


READY_RETRY_AFTER_S = 1  # the warm-up frame takes about a second on llvmpipe
SHARED_BACKENDS = {"redis"}  # session stores every process shares: not one process's readiness


@router.get("/health", response_model=HealthOut, summary="Liveness")
def health() -> HealthOut:
    return HealthOut(status="ok")


# The probe of a store that is this process's own (SQLite) runs on a thread of its own: requests waiting for the
# store may hold every thread of the default pool, and the balancer's check must still be answered.
_PROBE_LIMITER = anyio.CapacityLimiter(1)


@router.get(
    "/ready",
    response_model=ReadyOut,
    responses={503: {"model": ReadyOut, "description": "not ready"}},
    summary="Readiness of this process: GL context created, warm-up render done, not draining or "
    "saturated, and its own session store (SQLite) read and written",
)
async def ready(request: Request) -> Any:
    # From the event loop, with no dependency that needs a thread: a balancer's health check is answered
    # while every thread of the pool waits (for a stalled Redis, say), and says what this process can do.
    worker, service = request.app.state.worker, request.app.state.service
    info = worker.info or {}
    drain = getattr(request.app.state, "drain", None)
    draining = (drain is not None and drain.draining.is_set()) or worker.closing
    saturated = worker.saturated
    # A store of this process alone (SQLite) is checked the way requests use it: a write and a read of a probe
    # record, on the file that was opened, still a database (a ping would pass on a deleted or overwritten
    # file). A shared store (Redis) is not: its fault is every process's at once, and taking them all out of
    # the balancer would turn the service's own 503 + Retry-After into the balancer's "no server".
    own_store = service.config.state_backend not in SHARED_BACKENDS
    store_fault = (
        await anyio.to_thread.run_sync(service.store.probe, limiter=_PROBE_LIMITER)
        if own_store and worker.ready.is_set()
        else None
    )
    out = ReadyOut(
        ready=not draining and not saturated and worker.ready.is_set() and store_fault is None,
        gl_renderer=info.get("renderer"),
        gl_version=info.get("version"),
    )
    if out.ready:
        return out
    retry = READY_RETRY_AFTER_S
    if draining:  # shutdown has begun: a balancer takes this process out of rotation
        out.detail = "draining: the process is shutting down"
    elif saturated:  # the work queued ahead is more than a render may wait
        retry = worker.retry_after()
        out.detail = (
            f"saturated: {worker.queued_ms() / 1e3:,.1f} s of GL work queued, over the render timeout "
            f"of {worker.render_timeout_s:g} s (POCKETRAY_RENDER_TIMEOUT_S)"
        )
    else:
        out.detail = worker.error or (
            f"state backend: {store_fault}"
            if worker.ready.is_set()
            else "starting: creating the GL context and rendering the warm-up frame"
        )
    metrics.unavailable("draining" if draining else "saturated" if saturated else "not_ready")
    return JSONResponse(out.model_dump(), status_code=503, headers={"Retry-After": str(retry)})


@router.get("/info", response_model=InfoOut, summary="Methods, modes, formats and limits of this service")
def info(service: ServiceDep) -> InfoOut:
    c = service.config
    return InfoOut(
        methods=list(METHOD_NAMES),
        modes=list(MODES),
        mode_labels=MODE_LABELS,
        averaged_modes=list(AVERAGED_MODES),
        formats=list(FORMATS),
        state_backend=c.state_backend,
        profiles=PROFILES,
        update_schemes=list(UPDATE_SCHEMES),
        museum_kinds=list(MUSEUM_KINDS),
        limits=LimitsOut(
            max_work=c.max_work,
            max_frame_cost=c.max_frame_cost,
            slice_ms=c.slice_ms,
            max_spheres=c.max_spheres,
            max_triangles=c.max_triangles,
            max_body_bytes=c.max_body_bytes,
            max_image_side=MAX_IMAGE_SIDE,
            queue_size=c.queue_size,
            session_ttl_s=c.session_ttl_s,
        ),
        recursion_colors=[
            {"rgb": tuple(rgb), "name": name}
            for rgb, name in zip(RECURSION_COLORS.tolist(), RECURSION_COLOR_NAMES, strict=True)
        ],
        heat_scale=HEAT_SCALE,
        **info_extras(c),
    )
