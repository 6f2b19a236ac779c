"""Frames (the View) and what the Controller's gestures ask for: a gesture (optionally
answered with the new frame), a session's frame, its build statistics, a stateless render.

Frame routes ask the session service for a frame request and run it through the frame pipeline
(:meth:`server.frames.pipeline.FramePipeline.run`) on a worker thread, watching the connection
meanwhile: a client that goes away cancels its frame between slices (docs/API.md, "Cancellation").
With ``progressive=1`` the answer is ``multipart/mixed``: the preview part as soon as it
exists, then the final part (docs/API.md, "Progressive frames"). With ``refine=1`` it is the
session's refinement stream, one part per frame (:mod:`server.sessions.refine`; docs/API.md,
"Refinement").
"""

from __future__ import annotations

import asyncio
import json
import secrets
import threading
from collections.abc import Callable, Iterator
from typing import Annotated, Any

from fastapi import APIRouter, Body, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, StreamingResponse

from renderer.config.settings import SettingValues

from ...faults import Where
from ...frames.encode import FRAME_RESPONSE_DOC, Frame, frame_headers
from ...frames.pipeline import FramePipeline, FrameRequest, final
from ...sessions.refine import RefineStep, refine
from ...sessions.service import SessionService
from ..body import JSONBodyRoute
from ..deps import FramesDep, ServiceDep, SessionId
from ..errors import documented, located
from ..schemas import (
    CameraModel,
    CameraOut,
    Gesture,
    GestureQuery,
    RenderRequest,
    SessionFrameQuery,
    StatsOut,
    StatsQuery,
)

router = APIRouter(route_class=JSONBodyRoute)  # JSON bodies strict, large ones off the event loop
WATCH_S = 0.1  # how often a waiting route looks whether its client is still there


def frame_response(frame: Frame) -> Response:
    """An encoded frame with the headers that describe it (docs/API.md, "Frames")."""
    return Response(content=frame.body, media_type=frame.media_type, headers=frame_headers(frame))


async def watched(request: Request, cancel: threading.Event, work: Any) -> Any:
    """Await ``work`` (a future of a worker thread) while watching the connection: when the
    client disconnects (or this request is cancelled) ``cancel`` is set, so the frame stops
    between slices."""
    task = asyncio.ensure_future(work)
    try:
        while True:
            done, _ = await asyncio.wait({task}, timeout=WATCH_S)
            if done:
                return task.result()
            if await request.is_disconnected():
                cancel.set()
    except asyncio.CancelledError:
        cancel.set()
        raise


MakeRequest = Callable[[threading.Event], FrameRequest]  # the request, given the event that cancels it


def located_parts(where: Where, frames: FramePipeline, make: MakeRequest, cancel: threading.Event) -> Iterator[Frame]:
    """The parts of the frame request ``make(cancel)``, its refused inputs placed at ``where`` (the
    part of the request that holds the frame's settings)."""
    with located(where):
        yield from frames.run(make(cancel))


async def frame_answer(request: Request, frames: FramePipeline, where: Where, make: MakeRequest) -> Response:
    """The final image of the frame request ``make(cancel)``: made and run on a worker thread,
    watched (:func:`watched`)."""
    cancel = threading.Event()
    parts = located_parts(where, frames, make, cancel)  # a generator: nothing has run yet
    return frame_response(await watched(request, cancel, run_in_threadpool(final, parts)))


async def progressive_response(request: Request, frames: FramePipeline, where: Where, make: MakeRequest) -> Response:
    """The parts of a progressive frame as ``multipart/mixed``, each with the frame headers
    (Content-Type, Server-Timing, X-Frame-Part, …). An error before the first part is an
    ordinary error answer; the first part starts the stream."""
    cancel = threading.Event()
    with located(where):
        request_ = make(cancel)  # the session read and the settings checked, as the route is called
    parts = located_parts(where, frames, lambda _: request_, cancel)  # a generator: nothing has run yet
    first = await watched(request, cancel, run_in_threadpool(next, parts))
    boundary = "pocketray-" + secrets.token_hex(8)

    def encode(frame: Frame) -> bytes:
        return part_bytes(boundary, frame, {})

    async def body():
        try:
            yield encode(first)
            while True:
                frame = await watched(request, cancel, run_in_threadpool(next, parts, None))
                if frame is None:
                    break
                yield encode(frame)
            yield f"--{boundary}--\r\n".encode()
        except BaseException:
            cancel.set()  # the client went away mid-stream: stop the frame
            raise

    return multipart(body(), boundary, frame_headers(first))


def multipart(body: Any, boundary: str, first: dict[str, str]) -> StreamingResponse:
    """A multipart/mixed answer of ``body``'s parts, with the headers of its first part that hold for all."""
    headers = {k: v for k, v in first.items() if k in ("Access-Control-Expose-Headers", "Cache-Control", "X-Method")}
    return StreamingResponse(body, media_type=f"multipart/mixed; boundary={boundary}", headers=headers)


def part_bytes(boundary: str, frame: Frame, extra: dict[str, str]) -> bytes:
    """One part: the frame with its headers (and ``extra``)."""
    head = {"Content-Type": frame.media_type, "Content-Length": str(len(frame.body)), **frame_headers(frame), **extra}
    lines = "".join(f"{k}: {v}\r\n" for k, v in head.items())
    return f"--{boundary}\r\n{lines}\r\n".encode() + frame.body + b"\r\n"


async def refine_response(request: Request, service: SessionService, session_id: str, patch: SettingValues) -> Response:
    """The session's refinement stream as ``multipart/mixed``: one part per frame, ``X-Frame-Part:
    refine`` before the last (``final``), each with ``X-Refine`` (JSON: samples, targets, elapsed ms,
    done, reason). An error before the first part is an ordinary error answer; a client that goes
    away (the next gesture) stops the stream at once."""
    cancel = threading.Event()

    def steps() -> Iterator[RefineStep]:
        with located(Where.QUERY):
            yield from refine(service, session_id, patch, cancel=cancel)

    parts = steps()
    with located(Where.QUERY):
        service.frame_settings(service.get(session_id), patch)  # a refused setting: 422, not a stream
    first = await watched(request, cancel, run_in_threadpool(next, parts, None))
    if first is None:  # stopped before its first frame (the session changed): nothing to stream
        return Response(status_code=204)
    boundary = "pocketray-" + secrets.token_hex(8)

    def encode(step: RefineStep) -> bytes:
        extra = {"X-Frame-Part": "final" if step.done else "refine", "X-Refine": json.dumps(step.progress())}
        return part_bytes(boundary, step.frame, extra)

    async def body():
        try:
            step: RefineStep | None = first
            while step is not None:
                yield encode(step)
                if step.done:
                    break
                step = await watched(request, cancel, run_in_threadpool(next, parts, None))
            yield f"--{boundary}--\r\n".encode()
        finally:
            cancel.set()  # done, or the client went away mid-stream: the stream stops at its next slice

    return multipart(body(), boundary, frame_headers(first.frame))


@router.post(
    "/sessions/{session_id}/gesture",
    response_model=CameraOut,
    responses={200: FRAME_RESPONSE_DOC, **documented(404, 409, 413, 503)},
    summary="Apply pan / pinch / reset; with ?frame=1 answer with the new frame",
)
async def gesture(
    request: Request,
    session_id: SessionId,
    body: Annotated[Gesture, Body()],
    service: ServiceDep,
    frames: FramesDep,
    query: Annotated[GestureQuery, Query()],
) -> Any:
    # The frame parameters are validated even without ?frame=1, as they always were.
    patch = query.given()
    if query.frame:
        progressive = query.progressive
        return await (progressive_response if progressive else frame_answer)(
            request,
            frames,
            Where.QUERY,
            lambda cancel: service.gesture_request(session_id, body, patch, cancel=cancel, progressive=progressive),
        )
    state = await run_in_threadpool(service.gesture, session_id, body)
    return CameraOut(version=state.version, camera=CameraModel(**state.camera))


@router.get(
    "/sessions/{session_id}/frame",
    response_class=Response,
    responses={200: FRAME_RESPONSE_DOC, **documented(404, 409, 503)},
    summary="Render the session's current view",
)
async def session_frame(
    request: Request,
    session_id: SessionId,
    service: ServiceDep,
    frames: FramesDep,
    query: Annotated[SessionFrameQuery, Query()],
) -> Response:
    patch, progressive, accumulate = query.given(), query.progressive, query.accumulate
    if query.refine:
        return await refine_response(request, service, session_id, patch)
    return await (progressive_response if progressive else frame_answer)(
        request,
        frames,
        Where.QUERY,
        lambda cancel: service.frame_request(
            session_id, patch, cancel=cancel, progressive=progressive, accumulate=accumulate
        ),
    )


@router.get(
    "/sessions/{session_id}/stats",
    response_model=StatsOut,
    responses=documented(404, 503),
    summary="Statistics of the acceleration structure for the current (or given) settings",
)
def session_stats(session_id: SessionId, service: ServiceDep, query: Annotated[StatsQuery, Query()]) -> Any:
    with located(Where.QUERY):
        return JSONResponse(service.stats(session_id, query.given()))


@router.post(
    "/render",
    response_class=Response,
    responses={200: FRAME_RESPONSE_DOC, **documented(413, 503)},
    summary="Stateless render of a scene with settings (docs/FORMATS.md)",
)
async def render(request: Request, body: RenderRequest, service: ServiceDep, frames: FramesDep) -> Response:
    patch = body.settings.given()
    return await frame_answer(
        request, frames, Where.BODY, lambda cancel: service.stateless_request(body.scene, patch, cancel=cancel)
    )
