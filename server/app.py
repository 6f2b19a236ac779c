"""The FastAPI application: routes, error mapping, lifespan (``server.app:app``).

Lifespan: opens the state backend, starts the GL thread (context + warm-up
render, in the background: /api/ready turns 200 once both succeeded) and closes
both at shutdown. Handlers get the service through ``Depends(get_service)``
(it lives on ``app.state``), never through globals. docs/API.md describes the API.
"""

from __future__ import annotations

import json
import logging
import sqlite3
from contextlib import asynccontextmanager
from typing import Annotated, Any

import redis
from fastapi import APIRouter, Body, Depends, FastAPI, Path, Query, Response, WebSocket, WebSocketDisconnect
from fastapi.concurrency import run_in_threadpool
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, StreamingResponse
from fastapi.staticfiles import StaticFiles
from pydantic import TypeAdapter, ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.requests import HTTPConnection, Request

from renderer.animation import MAX_TIME, MUSEUM_KINDS
from renderer.scenarios import scenario
from renderer.scene import SceneError
from renderer.tree_update import UPDATE_SCHEMES
from renderer.settings import FORMATS, MAX_IMAGE_SIDE, METHODS, MODES, RenderSettings

from .body_limit import BodyLimit
from . import device
from .config import ServerConfig
from .gl_worker import GLNotReady, GLWorker, QueueFull
from renderer.profiles import PROFILES

from .models import (CameraModel, CameraOut, ErrorOut, FormatName, FullSettings, Gesture, HealthOut, InfoOut,
                     LimitsOut, MethodName, ModeName, ReadyOut, RenderRequest, SceneInfo, SceneModel, SessionCreate,
                     SessionOut, SettingsOut, SettingsPatch, StatsOut, UpdateScheme, VersionOut)
from .scenes import scene_json_chunks
from .service import InputError, NotFound, RenderTimeout, SessionService, field_path, info_extras
from .store import SessionState, open_store
from .view import FRAME_RESPONSE_DOC, Frame, frame_headers

log = logging.getLogger("pocketray.server")


# ---- dependencies ----------------------------------------------------------------------------
def get_service(conn: HTTPConnection) -> SessionService:
    """The process's SessionService (created by the lifespan)."""
    return conn.app.state.service


def get_worker(conn: HTTPConnection) -> GLWorker:
    return conn.app.state.worker


ServiceDep = Annotated[SessionService, Depends(get_service)]
SessionId = Annotated[str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_-]+$",
                                description="session token from POST /api/sessions")]


def frame_query(
    width: Annotated[int | None, Query(ge=1, le=MAX_IMAGE_SIDE, description="pixels")] = None,
    height: Annotated[int | None, Query(ge=1, le=MAX_IMAGE_SIDE, description="pixels")] = None,
    method: Annotated[MethodName | None, Query()] = None,
    mode: Annotated[ModeName | None, Query()] = None,
    max_prims: Annotated[int | None, Query(ge=1, le=1 << 24)] = None,
    max_tree_depth: Annotated[int | None, Query(ge=1, le=64)] = None,
    max_recursion_depth: Annotated[int | None, Query(ge=1, le=8)] = None,
    format: Annotated[FormatName | None, Query()] = None,
    quality: Annotated[int | None, Query(ge=1, le=100, description="JPEG quality")] = None,
    samples_per_pixel: Annotated[int | None, Query(ge=1, le=16, description="1, 4, 9 or 16: supersampling")] = None,
    min_weight: Annotated[float | None, Query(ge=0.0, le=1.0, allow_inf_nan=False,
                                              description="ε cut-off of secondary rays")] = None,
    specialize: Annotated[bool | None, Query(description="scene-specialised shader variant")] = None,
    tile_size: Annotated[int | None, Query(ge=2, le=64, description="hre tile edge")] = None,
    time: Annotated[float | None, Query(ge=0.0, le=MAX_TIME, allow_inf_nan=False,
                                        description="seconds: the pose of an animated scene")] = None,
    update: Annotated[UpdateScheme | None, Query(description="rebuild, refit or selective: how bvh/twolevel "
                                                             "follow the motion from this session's last frame")] = None,
    update_threshold: Annotated[float | None, Query(ge=0.0, le=100.0, allow_inf_nan=False,
                                                    description="selective: SAH cost growth, 0.3 = +30 %")] = None,
) -> dict[str, Any]:
    """Frame parameters of the query; missing ones come from the session's defaults."""
    given = {"width": width, "height": height, "method": method, "mode": mode, "max_prims": max_prims,
             "max_tree_depth": max_tree_depth, "max_recursion_depth": max_recursion_depth, "format": format,
             "quality": quality, "samples_per_pixel": samples_per_pixel, "min_weight": min_weight,
             "specialize": specialize, "tile_size": tile_size, "time": time, "update": update,
             "update_threshold": update_threshold}
    return {k: v for k, v in given.items() if v is not None}


FrameQuery = Annotated[dict, Depends(frame_query)]

ERR_404 = {404: {"model": ErrorOut, "description": "no such session (unknown, deleted or expired)"}}
ERR_413 = {413: {"model": ErrorOut, "description": "request body too large (POCKETRAY_MAX_BODY_BYTES)"}}
ERR_503 = {503: {"model": ErrorOut, "description": "render queue full, GL or session store not available; "
                                                   "see Retry-After",
                 "headers": {"Retry-After": {"description": "seconds", "schema": {"type": "string"}}}}}

ERR_SESSION = {**ERR_404, **ERR_503}
ERR_SESSION_BODY = {**ERR_404, **ERR_413, **ERR_503}


def _session_out(state: SessionState) -> SessionOut:
    return SessionOut(id=state.id, version=state.version, settings=FullSettings(**state.settings),
                      scene_info=SceneInfo(**state.scene_info), camera=CameraModel(**state.camera))


def _frame_response(frame: Frame) -> Response:
    return Response(content=frame.body, media_type=frame.media_type, headers=frame_headers(frame))


# ---- routes ----------------------------------------------------------------------------------
router = APIRouter(prefix="/api")


@router.post("/sessions", status_code=201, response_model=SessionOut, responses={**ERR_413, **ERR_503},
             summary="Create a session from a thesis scenario, an animated museum or a full scene")
def create_session(body: SessionCreate, service: ServiceDep) -> SessionOut:
    return _session_out(service.create(body))


@router.get("/sessions/{session_id}", response_model=SessionOut, responses=ERR_SESSION,
            summary="A session: version, render defaults, scene info, camera")
def read_session(session_id: SessionId, service: ServiceDep) -> SessionOut:
    return _session_out(service.get(session_id))


@router.delete("/sessions/{session_id}", status_code=204, response_class=Response, responses=ERR_SESSION,
               summary="Delete a session")
def delete_session(session_id: SessionId, service: ServiceDep) -> Response:
    service.delete(session_id)
    return Response(status_code=204)


@router.get("/sessions/{session_id}/scene", response_model=SceneModel, responses=ERR_SESSION,
            summary="The session's scene (SPEC JSON) with its current camera")
def read_scene(session_id: SessionId, service: ServiceDep) -> Response:
    state = service.get(session_id)
    return StreamingResponse(scene_json_chunks(service.scene(state)), media_type="application/json")


@router.put("/sessions/{session_id}/scene", response_model=VersionOut, responses=ERR_SESSION_BODY,
            summary="Replace the scene (its camera becomes the current and the reset camera)")
def replace_scene(session_id: SessionId, scene: Annotated[SceneModel, Body()], service: ServiceDep) -> VersionOut:
    return VersionOut(version=service.replace_scene(session_id, scene).version)


@router.put("/sessions/{session_id}/camera", response_model=CameraOut, responses=ERR_SESSION_BODY,
            summary="Set the camera")
def set_camera(session_id: SessionId, camera: Annotated[CameraModel, Body()], service: ServiceDep) -> CameraOut:
    state = service.set_camera(session_id, camera)
    return CameraOut(version=state.version, camera=CameraModel(**state.camera))


@router.patch("/sessions/{session_id}/settings", response_model=SettingsOut, responses=ERR_SESSION_BODY,
              summary="Change render defaults (all of them or some)")
def patch_settings(session_id: SessionId, patch: Annotated[SettingsPatch, Body()],
                   service: ServiceDep) -> SettingsOut:
    state = service.patch_settings(session_id, patch)
    return SettingsOut(**state.settings, version=state.version)


@router.post("/sessions/{session_id}/gesture", response_model=CameraOut,
             responses={200: FRAME_RESPONSE_DOC, **ERR_SESSION_BODY},
             summary="Apply pan / pinch / reset; with ?frame=1 answer with the new frame")
def gesture(session_id: SessionId, body: Annotated[Gesture, Body()], service: ServiceDep, params: FrameQuery,
            frame: Annotated[bool, Query(description="answer with the new frame (image) instead of JSON")] = False,
            ) -> Any:
    if frame:
        return _frame_response(service.gesture_frame(session_id, body, params))
    state = service.gesture(session_id, body)
    return CameraOut(version=state.version, camera=CameraModel(**state.camera))


@router.get("/sessions/{session_id}/frame", response_class=Response,
            responses={200: FRAME_RESPONSE_DOC, **ERR_SESSION},
            summary="Render the session's current view")
def session_frame(session_id: SessionId, service: ServiceDep, params: FrameQuery) -> Response:
    return _frame_response(service.session_frame(session_id, params))


@router.get("/sessions/{session_id}/stats", response_model=StatsOut, responses=ERR_SESSION,
            summary="Statistics of the acceleration structure for the current (or given) settings")
def session_stats(session_id: SessionId, service: ServiceDep,
                  method: Annotated[MethodName | None, Query()] = None,
                  max_prims: Annotated[int | None, Query(ge=1, le=1 << 24)] = None,
                  max_tree_depth: Annotated[int | None, Query(ge=1, le=64)] = None,
                  time: Annotated[float | None, Query(ge=0.0, le=MAX_TIME, allow_inf_nan=False,
                                                      description="an animated scene's pose, seconds")] = None
                  ) -> Any:
    patch = {k: v for k, v in (("method", method), ("max_prims", max_prims),
                               ("max_tree_depth", max_tree_depth), ("time", time)) if v is not None}
    return JSONResponse(service.stats(session_id, patch))


@router.post("/render", response_class=Response, responses={200: FRAME_RESPONSE_DOC, **ERR_413, **ERR_503},
             summary="Stateless render of a scene with settings (SPEC JSON)")
def render(body: RenderRequest, service: ServiceDep) -> Response:
    return _frame_response(service.render_stateless(body.scene, body.settings.given()))


@router.get("/health", response_model=HealthOut, summary="Liveness")
def health() -> HealthOut:
    return HealthOut(status="ok")


@router.get("/ready", response_model=ReadyOut, responses={503: {"model": ReadyOut, "description": "not ready"}},
            summary="Readiness: GL context created and warm-up render done")
def ready(worker: Annotated[GLWorker, Depends(get_worker)], service: ServiceDep) -> Any:
    info = worker.info or {}
    out = ReadyOut(ready=worker.ready.is_set() and service.store.ping(),
                   gl_renderer=info.get("renderer"), gl_version=info.get("version"))
    if out.ready:
        return out
    out.detail = worker.error or ("state backend not answering" if worker.ready.is_set() else
                                  "starting: creating the GL context and rendering the warm-up frame")
    return JSONResponse(out.model_dump(), status_code=503, headers={"Retry-After": "1"})


@router.get("/info", response_model=InfoOut, summary="Methods, modes, formats and limits of this service")
def info(service: ServiceDep) -> InfoOut:
    c = service.config
    return InfoOut(methods=list(METHODS), modes=list(MODES), formats=list(FORMATS), state_backend=c.state_backend,
                   profiles=PROFILES, update_schemes=list(UPDATE_SCHEMES), museum_kinds=list(MUSEUM_KINDS),
                   **info_extras(c),
                   limits=LimitsOut(max_work=c.max_work, max_bruteforce_work=c.max_bruteforce_work,
                                    max_spheres=c.max_spheres, max_body_bytes=c.max_body_bytes,
                                    max_image_side=MAX_IMAGE_SIDE, queue_size=c.queue_size,
                                    session_ttl_s=c.session_ttl_s))


_gesture_adapter = TypeAdapter(Gesture)
_patch_adapter = TypeAdapter(SettingsPatch)


@router.websocket("/sessions/{session_id}/ws")
async def session_socket(websocket: WebSocket, session_id: str, service: ServiceDep) -> None:
    """Gestures in, frames out, on one connection (measured against ?frame=1, see docs/API.md).

    Client → text JSON: a gesture (``{"type": "pan", "dx", "dy"}`` …, or
    ``{"type": "frame"}`` for a frame without a gesture) with an optional
    ``"frame": {settings}``. Server → text JSON ``{"version", "camera",
    "timings", "stats", "media_type"}`` then the frame as one binary message; on
    an error one text JSON ``{"status", "detail"}`` (and ``"retry_after"`` on 503).
    """
    await websocket.accept()
    try:
        while True:
            try:
                msg = json.loads(await websocket.receive_text())
                if not isinstance(msg, dict):
                    raise InputError(("body",), "expected a JSON object")
                patch = _patch_adapter.validate_python(msg.pop("frame", None) or {}).given()
                if msg.get("type") == "frame":
                    frame = await run_in_threadpool(service.session_frame, session_id, patch)
                else:
                    g = _gesture_adapter.validate_python(msg)
                    frame = await run_in_threadpool(service.gesture_frame, session_id, g, patch)
                state = await run_in_threadpool(service.get, session_id)
                await websocket.send_text(json.dumps({
                    "version": frame.version, "camera": state.camera, "timings": frame.timings,
                    "stats": frame.stats, "media_type": frame.media_type}))
                await websocket.send_bytes(frame.body)
            except (ValidationError, json.JSONDecodeError) as e:
                await websocket.send_text(json.dumps({"status": 422, "detail": str(e)}))
            except SceneError as e:
                await websocket.send_text(json.dumps({"status": 422, "detail": f"{e.field}: {e.message}"}))
            except NotFound:
                await websocket.send_text(json.dumps({"status": 404, "detail": _NOT_FOUND}))
            except QueueFull as e:
                await websocket.send_text(json.dumps({"status": 503, "detail": str(e),
                                                      "retry_after": e.retry_after_s}))
            except (GLNotReady, RenderTimeout) as e:
                await websocket.send_text(json.dumps({"status": 503, "detail": str(e), "retry_after": 5}))
    except WebSocketDisconnect:
        return


# ---- errors ----------------------------------------------------------------------------------
_NOT_FOUND = ("session: no session with this id (unknown, deleted, or expired after POCKETRAY_SESSION_TTL_S "
              "seconds idle); create one with POST /api/sessions")


def _loc_label(loc: list) -> str:
    inner = loc[1:] if loc and loc[0] in ("body", "query", "path", "header") else loc
    out = ""
    for part in inner:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or (str(loc[0]) if loc else "body")


def _validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
    errors = []
    for e in exc.errors():
        loc = [x if isinstance(x, (int, str)) else str(x) for x in e.get("loc", ())]
        msg = str(e.get("msg", "invalid value"))
        errors.append({"loc": loc, "msg": f"{_loc_label(loc)}: {msg}", "type": str(e.get("type", "value_error"))})
    return JSONResponse({"detail": errors}, status_code=422)


def _scene_error(request: Request, exc: SceneError) -> JSONResponse:
    loc = list(exc.loc) if isinstance(exc, InputError) else ["body", *field_path(exc.field)]
    return JSONResponse({"detail": [{"loc": loc, "msg": f"{exc.field}: {exc.message}", "type": "value_error"}]},
                        status_code=422)


async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
    """A body that is not even JSON (FastAPI says 400) is bad input like any other: 422."""
    if exc.status_code == 400:
        return JSONResponse({"detail": [{"loc": ["body"], "msg": f"body: not valid UTF-8 JSON ({exc.detail})",
                                         "type": "json_invalid"}]}, status_code=422)
    return await http_exception_handler(request, exc)


def _not_found(request: Request, exc: NotFound) -> JSONResponse:
    return JSONResponse({"detail": _NOT_FOUND}, status_code=404)


def _queue_full(request: Request, exc: QueueFull) -> JSONResponse:
    return JSONResponse({"detail": f"render queue full ({request.app.state.config.queue_size} admitted, "
                                   f"POCKETRAY_QUEUE_SIZE); retry after {exc.retry_after_s} s"},
                        status_code=503, headers={"Retry-After": str(exc.retry_after_s)})


def _store_unavailable(request: Request, exc: Exception) -> JSONResponse:
    log.error("state backend error: %s", exc)
    return JSONResponse({"detail": f"state: the session store is not answering ({type(exc).__name__}); retry"},
                        status_code=503, headers={"Retry-After": "1"})


def _internal(request: Request, exc: Exception) -> JSONResponse:
    log.exception("unexpected error in %s %s", request.method, request.url.path, exc_info=exc)
    return JSONResponse({"detail": f"internal error ({type(exc).__name__}); see the server log"}, status_code=500)


def _unavailable(request: Request, exc: Exception) -> JSONResponse:
    return JSONResponse({"detail": f"gl: {exc}"}, status_code=503, headers={"Retry-After": "5"})


# ---- the application -----------------------------------------------------------------------------
def warmup_render(renderer) -> None:
    """A tiny frame with the default settings' shader variant (compiles it once)."""
    defaults = RenderSettings()
    renderer.render(scenario(3, 16), defaults.with_(width=16, height=16))


def create_app(config: ServerConfig | None = None) -> FastAPI:
    """A new application for ``config`` (default: from POCKETRAY_* environment variables)."""
    config = config or ServerConfig()

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        store = open_store(config)
        worker = GLWorker(config.queue_size, warmup=warmup_render if config.warmup else None)
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
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(SceneError, _scene_error)
    app.add_exception_handler(NotFound, _not_found)
    app.add_exception_handler(QueueFull, _queue_full)
    app.add_exception_handler(GLNotReady, _unavailable)
    app.add_exception_handler(RenderTimeout, _unavailable)
    app.add_exception_handler(sqlite3.OperationalError, _store_unavailable)
    app.add_exception_handler(redis.RedisError, _store_unavailable)
    app.add_exception_handler(Exception, _internal)
    app.include_router(router)
    app.include_router(device.router)  # on-device rendering (issue #10): server/device.py
    config.client_dir.mkdir(parents=True, exist_ok=True)
    if config.shader_dir.is_dir():
        app.mount("/shaders", StaticFiles(directory=config.shader_dir), name="shaders")
    app.mount("/", StaticFiles(directory=config.client_dir, html=True), name="client")
    return app


app = create_app()
