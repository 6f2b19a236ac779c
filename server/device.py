"""On-device rendering (issue #10): what a browser needs to run the very same tracer.

Two endpoints; the browser client's ``client_web/js/device.js`` uses both.

``GET /api/sessions/{id}/device-data``
    The session's scene and the chosen method's acceleration data, packed by
    :mod:`renderer.gpu_layout` — the one layout the moderngl renderer uploads
    too — wrapped to the device's ``max_texture_size`` (a power of two; many
    phones: 4,096). The tree is built for this request, as for every frame.
    Query: ``method``, ``max_prims``, ``max_tree_depth``, ``mode``,
    ``max_recursion_depth`` (missing: the session's), ``max_texture_size``
    (default 4096), ``float_textures`` (default true: the device can render
    to RGBA32F, WebGL2's ``EXT_color_buffer_float``; false → 422, the tracer
    cannot run there). Multi-pass methods (``rayengine``, ``hre``) draw several
    passes on the server and are a 422, as are scenes whose arrays do not fit
    the device's textures.

``GET /api/shader``
    The fragment shader of one variant exactly as the server compiles it
    (:func:`renderer.shader_source.tracer_source`: ``raytrace.frag`` + the layout
    header + the variant's defines + ``method_<name>.glsl``), or with
    ``stage=vertex`` the vertex shader; ``text/plain``. Query: ``method``,
    ``mode``, ``max_recursion_depth``, ``features`` (comma-separated ``NO_*``
    defines of :mod:`renderer.features`). The device-data header names the
    variant (its ``shader`` entry, with a ready ``url``).

The blob's format is :mod:`server.device_data`'s.

The pack is NumPy only (no GL), so it runs in FastAPI's thread pool, not on the
GL thread; it still takes a slot of the render queue while it runs, so a busy
service answers 503 + ``Retry-After`` here as everywhere.
"""

from __future__ import annotations

import time
from typing import Annotated, Any
from urllib.parse import urlencode

from fastapi import APIRouter, Depends, Path, Query, Response
from fastapi.responses import PlainTextResponse
from starlette.requests import HTTPConnection

from renderer import gpu_layout
from renderer.animation import MAX_TIME
from renderer.features import scene_features
from renderer.methods import METHODS, resolve_method
from renderer.modes import SINGLE_PASS_MODES
from renderer.shader_source import tracer_source as shader_source, vertex_source
from renderer.settings import MAX_RECURSION_DEPTH_LIMIT, MAX_TREE_DEPTH_LIMIT

from .device_data import (DEFAULT_MAX_TEXTURE_SIZE, FEATURE_DEFINES, FORMAT_VERSION, camera_uniforms, encode_blob,
                          jsonable as _jsonable, jsonable_stats as _jsonable_stats)
from .models import ErrorOut, MethodName, ModeName
from .service import InputError, SessionService
from .view import EXPOSED, stats_header


def _service(conn: HTTPConnection) -> SessionService:
    return conn.app.state.service


ServiceDep = Annotated[SessionService, Depends(_service)]
SessionId = Annotated[str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_-]+$",
                                description="session token from POST /api/sessions")]

_ERRORS = {404: {"model": ErrorOut, "description": "no such session (unknown, deleted or expired)"},
           503: {"model": ErrorOut, "description": "render queue full or session store not available; "
                                                   "see Retry-After",
                 "headers": {"Retry-After": {"description": "seconds", "schema": {"type": "string"}}}}}
_DATA_DOC: dict[str, Any] = {
    "description": "the packed scene and acceleration data (binary; format in server/device_data.py)",
    "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    "headers": {
        "X-Session-Version": {"description": "the session version the data shows", "schema": {"type": "string"}},
        "X-Method": {"description": "acceleration method packed", "schema": {"type": "string"}},
        "X-Stats": {"description": "compact JSON of the build's statistics", "schema": {"type": "string"}},
        "Server-Timing": {"description": "build, pack, total as name;dur=ms", "schema": {"type": "string"}},
    },
}
_SHADER_DOC: dict[str, Any] = {"description": "GLSL ES 3.00 source",
                               "content": {"text/plain": {"schema": {"type": "string"}}}}

router = APIRouter(prefix="/api", tags=["device"])


# ---- the variant and the pack ----------------------------------------------------------------
def single_pass_method(name: str, where: tuple[str, ...]) -> Any:
    """The method object, or a 422 when it cannot run in one fragment-shader pass on a device."""
    method = METHODS.get(name)
    if method is None:
        raise InputError(where, f"unknown method {name!r}")
    if not method.capabilities.device:
        able = ", ".join(device_methods())
        raise InputError(where, f"method {name!r} draws several passes on the server and cannot run on the "
                                f"device; device mode supports {able} (or use server mode)")
    return method


def device_methods() -> list[str]:
    """Methods whose whole frame is one pass of raytrace.frag (what a browser can run)."""
    return [n for n, m in METHODS.items() if m.capabilities.device]


def parse_features(features: str | None) -> tuple[str, ...]:
    """``"NO_LIGHTS,NO_REFLECTION"`` → the defines in renderer.features' order (422 for others)."""
    given = [f.strip() for f in (features or "").split(",") if f.strip()]
    for f in given:
        if f not in FEATURE_DEFINES:
            raise InputError(("query", "features"), f"unknown feature {f!r}; any of {', '.join(FEATURE_DEFINES)}")
    return tuple(f for f in FEATURE_DEFINES if f in given)


def shader_url(method: str, mode: str, depth: int, features: tuple[str, ...]) -> str:
    q = {"method": method, "mode": mode, "max_recursion_depth": depth}
    if features:
        q["features"] = ",".join(features)
    return "/api/shader?" + urlencode(q)


# ---- routes ----------------------------------------------------------------------------------
@router.get("/sessions/{session_id}/device-data", response_class=Response,
            responses={200: _DATA_DOC, **_ERRORS},
            summary="The session's scene and acceleration data packed for a device (WebGL2)")
def device_data(
    session_id: SessionId, service: ServiceDep,
    method: Annotated[MethodName | None, Query(description="default: the session's")] = None,
    mode: Annotated[ModeName | None, Query(description="names the shader variant; default: the session's")] = None,
    max_prims: Annotated[int | None, Query(ge=1, le=1 << 24)] = None,
    max_tree_depth: Annotated[int | None, Query(ge=1, le=MAX_TREE_DEPTH_LIMIT)] = None,
    max_recursion_depth: Annotated[int | None, Query(ge=1, le=MAX_RECURSION_DEPTH_LIMIT)] = None,
    time_s: Annotated[float | None, Query(alias="time", ge=0.0, le=MAX_TIME, allow_inf_nan=False,
                                          description="seconds: an animated scene's pose; default: the session's")
                      ] = None,
    max_texture_size: Annotated[int, Query(ge=1, le=1 << 16,
                                           description="the device's MAX_TEXTURE_SIZE")] = DEFAULT_MAX_TEXTURE_SIZE,
    float_textures: Annotated[bool, Query(description="the device renders to RGBA32F "
                                                      "(WebGL2: EXT_color_buffer_float)")] = True,
) -> Response:
    t0 = time.perf_counter()
    if not float_textures:
        raise InputError(("query", "float_textures"),
                         "the tracer reads RGBA32F textures and writes two RGBA32F targets (WebGL2 needs "
                         "EXT_color_buffer_float); this device cannot run it: use server mode")
    state = service.get(session_id)
    patch = {k: v for k, v in (("method", method), ("mode", mode), ("max_prims", max_prims),
                               ("max_tree_depth", max_tree_depth),
                               ("max_recursion_depth", max_recursion_depth), ("time", time_s)) if v is not None}
    settings = service.merge_settings(state.settings, patch, "query")
    n = state.scene_info.get("n_spheres", 0)
    method_name = resolve_method(settings["method"], n)
    meth = single_pass_method(method_name, ("query", "method"))
    if settings["mode"] not in SINGLE_PASS_MODES:
        raise InputError(("query", "mode"), f"mode {settings['mode']!r} is not a mode of the one-pass tracer; "
                                            f"one of {', '.join(SINGLE_PASS_MODES)}")
    width = 1 << (int(max_texture_size).bit_length() - 1)
    with service.admit():  # a queue slot for back-pressure; the work is NumPy, on this thread
        # An animated scene is posed here; the tree is rebuilt (updates between frames
        # belong to the GL thread's renders, whose tree caches are not shared with this thread).
        scene, update = service.posed(service.scene(state), settings)
        t_built0 = time.perf_counter()
        try:
            prepared = meth.prepare(scene, settings["max_prims"], settings["max_tree_depth"], width, update)
            t_built = time.perf_counter()
            prims = gpu_layout.pack_primitives(scene, width)
        except ValueError as e:
            raise InputError(("query", "max_texture_size"),
                             f"the scene does not fit this device's textures ({e}); use server mode") from None
    features = scene_features(scene)
    depth = features.recursion_depth(settings["max_recursion_depth"])
    defines = features.defines()
    uniforms = {k: _jsonable(v) for k, v in {**prims.uniforms, **prepared.packed.uniforms}.items()}
    uniforms.update(camera_uniforms(scene.camera))
    uniforms["u_min_weight"] = 0.0
    stats = {**prepared.stats, "method": method_name, "recursion_depth": depth,
             "features_removed": list(defines)}
    t_packed = time.perf_counter()
    header = {
        "format": "pocketray-device-data", "format_version": FORMAT_VERSION,
        "session": {"id": state.id, "version": state.version, "scene_rev": state.scene_rev},
        "method": method_name,
        "settings": {**{k: settings[k] for k in ("mode", "max_prims", "max_tree_depth", "max_recursion_depth",
                                                 "width", "height")},
                     "time": settings.get("time", 0.0)},   # sessions stored before animation have no time
        "shader": {"method": method_name, "mode": settings["mode"], "max_recursion_depth": depth,
                   "features": list(defines), "url": shader_url(method_name, settings["mode"], depth, defines)},
        "max_texture_size": width,
        "camera": state.camera, "home_camera": state.home_camera,
        "uniforms": uniforms,
        "stats": _jsonable_stats(stats), "build_ms": prepared.build_ms,
        "pack_ms": ((t_packed - t_built0) * 1e3 - prepared.build_ms),
    }
    blob = encode_blob(header, {**prims.textures, **prepared.packed.textures})
    total = (time.perf_counter() - t0) * 1e3
    timing = f"build;dur={prepared.build_ms:.2f}, pack;dur={header['pack_ms']:.2f}, total;dur={total:.2f}"
    return Response(content=blob, media_type="application/octet-stream", headers={
        "X-Session-Version": str(state.version), "X-Method": method_name, "X-Stats": stats_header(stats),
        "Server-Timing": timing, "Cache-Control": "no-store",
        "Access-Control-Expose-Headers": ", ".join(EXPOSED)})


@router.get("/shader", response_class=PlainTextResponse, responses={200: _SHADER_DOC},
            summary="The tracer's GLSL ES 3.00 source of one variant, as the server compiles it")
def shader(
    method: Annotated[MethodName, Query()] = "bih",
    mode: Annotated[ModeName, Query()] = "color",
    max_recursion_depth: Annotated[int, Query(ge=1, le=MAX_RECURSION_DEPTH_LIMIT)] = 5,
    features: Annotated[str | None, Query(max_length=200, description="comma-separated: "
                                          + ", ".join(FEATURE_DEFINES))] = None,
    stage: Annotated[str, Query(pattern="^(fragment|vertex)$")] = "fragment",
) -> PlainTextResponse:
    if stage == "vertex":
        return PlainTextResponse(vertex_source(), headers={"Cache-Control": "no-cache"})
    if method == "auto":
        raise InputError(("query", "method"), "name a concrete method (auto is resolved per scene by device-data)")
    single_pass_method(method, ("query", "method"))
    if mode not in SINGLE_PASS_MODES:
        raise InputError(("query", "mode"), f"mode {mode!r} is not a mode of the one-pass tracer; "
                                            f"one of {', '.join(SINGLE_PASS_MODES)}")
    src = shader_source(method, mode, max_recursion_depth, parse_features(features))
    return PlainTextResponse(src, headers={"Cache-Control": "no-cache"})
