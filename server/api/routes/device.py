"""On-device rendering: what a browser needs to run the very same tracer.

Two routes; the browser client's ``client_web/js/device/device.js`` uses both.

``GET /api/sessions/{id}/device-data``
    The session's scene and the chosen method's acceleration data as one blob of
    :mod:`server.frames.device_data`'s format, wrapped to the device's ``max_texture_size``.
    The tree is built for this request, as for every frame. Query
    (:class:`~server.api.schemas.DeviceDataQuery`): the render settings the data is for
    (missing: the session's; ``integrator=path`` gives the path integrator's variant and
    uniforms, ``tone_map``, ``exposure`` and ``samples_per_pixel`` go to the header for its
    display; ``denoise`` other than ``off`` gives the variant that writes the denoiser's guides,
    which the device's à-trous filter reads), ``max_texture_size`` and ``float_textures``
    (false → 422: the tracer cannot run there). Multi-pass methods (``rayengine``, ``hre``) draw several
    passes on the server and are a 422, as are scenes whose arrays do not fit the device's
    textures. Headers: ``X-Session-Version``, ``X-Method``, ``X-Stats``, ``Server-Timing``
    (``build``, ``pack``, ``total``).

``GET /api/shader``
    The fragment shader of one variant exactly as the server compiles it
    (:func:`renderer.frame.shader_source.tracer_source`: ``raytrace.frag`` + the layout
    header + the variant's defines + ``method_<name>.glsl``), or with
    ``stage=vertex`` the vertex shader; ``text/plain``. The device-data header names
    the variant (its ``shader`` entry, with a ready ``url``).

The pack is NumPy only (no GL), so it runs in FastAPI's thread pool, not on the GL
thread; it still takes a slot of the render queue while it runs, so a busy service
answers 503 + ``Retry-After`` here as everywhere.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Annotated, Any, TypeVar
from urllib.parse import urlencode

from fastapi import APIRouter, Query, Response
from fastapi.responses import PlainTextResponse

from renderer.accel.base import AccelerationMethod
from renderer.config.methods import METHODS, not_on_gpu
from renderer.frame.plan import plan_frame, plan_method
from renderer.frame.shader_source import tracer_source, vertex_source
from renderer.geometry.scene import SceneError
from renderer.gpu import gpu_layout, texture_layout
from renderer.modes import SINGLE_PASS_MODES

from ...faults import InputError, Where, input_error
from ...frames.device_data import (
    FEATURE_DEFINES,
    device_header,
    device_stats,
    device_uniforms,
    encode_blob,
    surface_info,
)
from ...frames.encode import EXPOSED, stats_header
from ...frames.pipeline import render_settings
from ...sessions.scenes import tree_primitives
from ..deps import FramesDep, ServiceDep, SessionId
from ..errors import documented, located
from ..schemas import DeviceDataQuery, ShaderQuery

router = APIRouter(tags=["device"])
T = TypeVar("T")

_DATA_DOC: dict[str, Any] = {
    "description": "the packed scene and acceleration data (binary; format in server/frames/device_data.py)",
    "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    "headers": {
        "X-Session-Version": {"description": "the session version the data shows", "schema": {"type": "string"}},
        "X-Method": {"description": "acceleration method packed", "schema": {"type": "string"}},
        "X-Stats": {"description": "compact JSON of the build's statistics", "schema": {"type": "string"}},
        "Server-Timing": {"description": "build, pack, total as name;dur=ms", "schema": {"type": "string"}},
    },
}
_SHADER_DOC: dict[str, Any] = {
    "description": "GLSL ES 3.00 source",
    "content": {"text/plain": {"schema": {"type": "string"}}},
}


# ---- the variant --------------------------------------------------------------------------------
def device_methods() -> list[str]:
    """Methods whose whole frame is one pass of raytrace.frag (what a browser can run)."""
    return [n for n, m in METHODS.items() if m.capabilities.device]


def single_pass_method(name: str, where: tuple[str, ...]) -> AccelerationMethod:
    """The method object, or a 422 when it cannot run in one fragment-shader pass on a device."""
    method = METHODS.get(name)
    if method is None:
        raise InputError(where, f"unknown method {name!r}")
    if not method.capabilities.device:
        able = ", ".join(device_methods())
        raise InputError(
            where,
            f"method {name!r} draws several passes on the server and cannot run on the "
            f"device; device mode supports {able} (or use server mode)",
        )
    return method


def check_single_pass_mode(mode: str) -> None:
    """A 422 for a mode only the multi-pass ray engines draw."""
    if mode not in SINGLE_PASS_MODES:
        raise InputError(
            ("query", "mode"),
            f"mode {mode!r} is not a mode of the one-pass tracer; one of {', '.join(SINGLE_PASS_MODES)}",
        )


def parse_features(features: str | None) -> tuple[str, ...]:
    """``"NO_LIGHTS,NO_REFLECTION"`` → the defines in renderer.frame.features' order (422 for others)."""
    given = [f.strip() for f in (features or "").split(",") if f.strip()]
    for f in given:
        if f not in FEATURE_DEFINES:
            raise InputError(("query", "features"), f"unknown feature {f!r}; any of {', '.join(FEATURE_DEFINES)}")
    return tuple(f for f in FEATURE_DEFINES if f in given)


def shader_url(method: str, mode: str, depth: int, features: tuple[str, ...]) -> str:
    """The GET /api/shader URL of one variant."""
    q: dict[str, Any] = {"method": method, "mode": mode, "max_recursion_depth": depth}
    if features:
        q["features"] = ",".join(features)
    return "/api/shader?" + urlencode(q)


def _planned(plan: Callable[[], T]) -> T:
    """``plan()``, its refusal (:class:`SceneError`) a 422 at the query's setting."""
    with located(Where.QUERY):
        try:
            return plan()
        except SceneError as e:
            raise input_error(e) from None


# ---- routes ----------------------------------------------------------------------------------
@router.get(
    "/sessions/{session_id}/device-data",
    response_class=Response,
    responses={200: _DATA_DOC, **documented(404, 503)},
    summary="The session's scene and acceleration data packed for a device (WebGL2)",
)
def device_data(
    session_id: SessionId, service: ServiceDep, frames: FramesDep, query: Annotated[DeviceDataQuery, Query()]
) -> Response:
    t0 = time.perf_counter()
    if not query.float_textures:
        raise InputError(
            ("query", "float_textures"),
            "the tracer reads RGBA32F textures and writes two RGBA32F targets (WebGL2 needs "
            "EXT_color_buffer_float); this device cannot run it: use server mode",
        )
    state = service.get(session_id)
    with located(Where.QUERY):
        settings = service.caps.merge_settings(state.settings, query.given())
    chosen = render_settings(settings)
    n_triangles = state.scene_info.get("n_triangles", 0)
    at_rest = tree_primitives(state.scene_info)  # auto's choice, as every frame of the session makes it
    method_name = _planned(lambda: plan_method(chosen, at_rest))
    meth = single_pass_method(method_name, ("query", "method"))
    if n_triangles and not meth.capabilities.meshes_on_gpu:
        # The device runs the server's shader on the server's layout: what the GPU cannot trace
        # with this method (Capabilities.meshes_on_gpu), a device cannot either.
        raise InputError(
            ("query", "meshes"),
            f"method {method_name!r}: {not_on_gpu()}: a device cannot trace this "
            f"scene's {n_triangles:,} triangles with it",
        )
    check_single_pass_mode(settings["mode"])
    width = 1 << (int(query.max_texture_size).bit_length() - 1)  # the power of two at most the device's
    with frames.admit():  # a queue slot for back-pressure; the work is NumPy, on this thread
        # An animated scene is posed here; the tree is rebuilt (updates between frames
        # belong to the GL thread's renders, whose tree caches are not shared with this thread).
        scene, update = frames.posed(service.scene(state), chosen.time)
        # The variant the server's frame of these settings compiles (renderer.frame.plan): Whitted's tree, or
        # with integrator 'path' the path integrator (its depth: segments of a path, up to
        # MAX_PATH_DEPTH); with a denoiser it writes the guides too (two more targets): a device filters
        # with à-trous whichever denoiser is named (OIDN does not run in a browser).
        plan = _planned(lambda: plan_frame(scene, chosen, tree_primitives=at_rest))
        t_built0 = time.perf_counter()
        try:
            prepared = meth.prepare(scene, settings["max_prims"], settings["max_tree_depth"], width, update)
            prims = gpu_layout.pack_primitives(scene, width)
            # Textures larger than the device's side are halved (a notice in the header), never refused.
            surface = texture_layout.pack_surface_data(scene, width, query.max_array_texture_layers)
        except ValueError as e:
            raise InputError(
                ("query", "max_texture_size"), f"the scene does not fit this device's textures ({e}); use server mode"
            ) from None
    uniforms = device_uniforms(scene, prims, prepared)
    stats = device_stats(plan, prepared)
    t_packed = time.perf_counter()
    header = device_header(
        plan,
        settings,
        uniforms,
        stats,
        session={"id": state.id, "version": state.version, "scene_rev": state.scene_rev},
        camera=state.camera,
        home_camera=state.home_camera,
        max_texture_size=width,
        shader_url=shader_url(method_name, settings["mode"], plan.recursion_depth, plan.defines),
        build_ms=prepared.build_ms,
        pack_ms=(t_packed - t_built0) * 1e3 - prepared.build_ms,
    )
    header["surface"] = surface_info(surface)
    blob = encode_blob(header, {**prims.textures, **prepared.packed.textures, **surface.packed.textures})
    total = (time.perf_counter() - t0) * 1e3
    timing = f"build;dur={prepared.build_ms:.2f}, pack;dur={header['pack_ms']:.2f}, total;dur={total:.2f}"
    return Response(
        content=blob,
        media_type="application/octet-stream",
        headers={
            "X-Session-Version": str(state.version),
            "X-Method": method_name,
            "X-Stats": stats_header(stats),
            "Server-Timing": timing,
            "Cache-Control": "no-store",
            "Access-Control-Expose-Headers": ", ".join(EXPOSED),
        },
    )


@router.get(
    "/shader",
    response_class=PlainTextResponse,
    responses={200: _SHADER_DOC},
    summary="The tracer's GLSL ES 3.00 source of one variant, as the server compiles it",
)
def shader(query: Annotated[ShaderQuery, Query()]) -> PlainTextResponse:
    if query.stage == "vertex":
        return PlainTextResponse(vertex_source(), headers={"Cache-Control": "no-cache"})
    if query.method == "auto":
        raise InputError(("query", "method"), "name a concrete method (auto is resolved per scene by device-data)")
    single_pass_method(query.method, ("query", "method"))
    check_single_pass_mode(query.mode)
    src = tracer_source(query.method, query.mode, query.max_recursion_depth, parse_features(query.features))
    return PlainTextResponse(src, headers={"Cache-Control": "no-cache"})
