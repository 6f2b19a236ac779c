"""Gestures in, frames out, on one WebSocket (measured against ?frame=1, see docs/API.md).

Client → a text (or UTF-8 binary) JSON message: a gesture (``{"type": "pan", "dx", "dy"}``
…, or ``{"type": "frame"}`` for a frame without a gesture, ``{"type": "frame", "accumulate":
true}`` for one added to the session's accumulation, ``{"type": "refine", "target_samples"?,
"target_ms"?, "target_noise"?}`` for the session's refinement stream) with an optional ``"frame": {settings}`` — the
settings ``POST …/gesture?frame=1`` takes in its query.
Server → text JSON ``{"version", "camera", "settings", "timings", "stats", "media_type", "samples"}``
then the frame as one binary message: ``camera`` and ``settings`` are those the frame was rendered
with — its request's snapshot of the session, the one ``version`` names, never the session read again
after the frame (another client may have moved it meanwhile); a refinement stream's frames so,
each with ``"refine": {"samples", "target_samples", "target_ms", "elapsed_ms", "done", "reason",
"noise", "target_noise"}``, until its target (:mod:`server.sessions.refine`) or the connection's
next message, which stops it at once: no frame of the stream is sent after that message is read;
on an error one text JSON ``{"status", "detail"}`` (and ``"retry_after"``, seconds, where HTTP
sends Retry-After) — the very answer the HTTP route gives (:mod:`server.api.errors`), and the
connection stays open. While the client's address has more answer bytes not taken than
``POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT``, a message is answered ``{"status": 429, …}`` without
any work (:func:`server.http.wire.refusal`);
the connection's idle time, message rate and write timeout are :mod:`server.http.wire`'s.

A message is read and validated as FastAPI reads a request: its JSON as the body
(``loc`` ``["body", …]``: strict, an unknown field of any message type is a 422
``extra_forbidden`` naming it), its ``"frame"`` settings as the query (``["query", …]``), all
errors of both in one 422.
"""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import Generator
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from pydantic import TypeAdapter, ValidationError

from ...faults import Where
from ...frames.encode import Frame
from ...frames.pipeline import FramePipeline, FrameRequest, final
from ...http import wire
from ...sessions.refine import RefineStep, refine
from ...sessions.service import SessionService
from .. import body, errors
from ..deps import FramesDep, ServiceDep
from ..schemas import FrameMessage, Gesture, RefineMessage, SettingsPatch

router = APIRouter()

_gesture_adapter = TypeAdapter(Gesture)
_patch_adapter = TypeAdapter(SettingsPatch)
_frame_adapter = TypeAdapter(FrameMessage)
_refine_adapter = TypeAdapter(RefineMessage)


def parse_json(data: str | bytes, max_depth: int) -> Any:
    """The message's JSON, read as a request body is (:func:`server.api.body.parse_json`: UTF-8,
    each key once, bounded nesting), failing with the same 422."""
    try:
        return body.parse_json(data, max_depth)
    except body.BodyError as e:
        raise e.validation_error() from None


def _validated(adapter: TypeAdapter, value: Any, where: str, problems: list[dict[str, Any]]) -> Any:
    """``value`` validated, or None with its errors (located at ``where``) added to ``problems``."""
    try:
        return adapter.validate_python(value)
    except ValidationError as e:
        problems.extend({**err, "loc": (where, *err["loc"])} for err in e.errors())
        return None


def frame_view(request: FrameRequest) -> dict[str, Any]:
    """The camera and the settings a frame was rendered with: its request's snapshot of the session
    (the settings as the session's JSON has them: the engine's and ``quality``)."""
    settings = request.settings.render.to_json()
    if request.settings.quality is not None:
        settings["quality"] = request.settings.quality
    return {"camera": request.scene.camera.to_json(), "settings": settings}


async def answer_message(
    service: SessionService, frames: FramePipeline, session_id: str, data: str | bytes
) -> tuple[Frame, dict[str, Any]]:
    """The frame one message asks for and the view it was rendered with (:func:`frame_view`)."""
    msg = parse_json(data, service.config.max_json_depth)
    frame_settings = (msg.pop("frame", None) if isinstance(msg, dict) else None) or {}
    problems: list[dict[str, Any]] = []
    patch = _validated(_patch_adapter, frame_settings, "query", problems)
    only_frame = isinstance(msg, dict) and msg.get("type") == "frame"
    asked = _validated(_frame_adapter, msg, "body", problems) if only_frame else None
    accumulate = bool(asked is not None and asked.accumulate)
    gesture = None if only_frame else _validated(_gesture_adapter, msg, "body", problems)
    if problems:
        raise RequestValidationError(problems)
    with errors.located(Where.QUERY):  # the message's "frame" is the query of a frame request
        if only_frame:
            request = await run_in_threadpool(
                lambda: service.frame_request(session_id, patch.given(), accumulate=accumulate)
            )
        else:
            request = await run_in_threadpool(lambda: service.gesture_request(session_id, gesture, patch.given()))
        frame = await run_in_threadpool(lambda: final(frames.run(request)))
    return frame, frame_view(request)


def refine_request(
    service: SessionService, session_id: str, data: str | bytes, cancel: threading.Event
) -> Generator[tuple[RefineStep, dict[str, Any]], None, None] | None:
    """The refinement stream a ``refine`` message asks for (validated now, nothing run yet) — each
    step with the view its frame was rendered with (:func:`frame_view`) — or None for any other
    message."""
    msg = parse_json(data, service.config.max_json_depth)
    if not (isinstance(msg, dict) and msg.get("type") == "refine"):
        return None
    frame_settings = msg.pop("frame", None) or {}
    problems: list[dict[str, Any]] = []
    patch = _validated(_patch_adapter, frame_settings, "query", problems)
    asked = _validated(_refine_adapter, msg, "body", problems)
    if problems:
        raise RequestValidationError(problems)
    given = patch.given()
    with errors.located(Where.QUERY):
        service.frame_settings(service.get(session_id), given)  # a refused setting is answered now

    def steps() -> Generator[tuple[RefineStep, dict[str, Any]], None, None]:
        with errors.located(Where.QUERY):
            for step in refine(
                service,
                session_id,
                given,
                target_samples=asked.target_samples,
                target_ms=asked.target_ms,
                target_noise=asked.target_noise,
                cancel=cancel,
            ):
                assert step.request is not None  # a step's frame was made from a request
                yield step, frame_view(step.request)

    return steps()


def frame_head(frame: Frame, view: dict[str, Any], refined: RefineStep | None = None) -> str:
    """The text message before a frame's bytes; ``view``: the camera and settings it was rendered with."""
    head = {
        "version": frame.version,
        "camera": view["camera"],
        "settings": view["settings"],
        "timings": frame.timings,
        "stats": frame.stats,
        "media_type": frame.media_type,
        "samples": frame.samples,
    }
    if refined is not None:
        head["refine"] = refined.progress()
    return json.dumps(head)


@router.websocket("/sessions/{session_id}/ws")
async def session_socket(websocket: WebSocket, session_id: str, service: ServiceDep, frames: FramesDep) -> None:
    """One connection: each message is answered by a frame or by one error message; a ``refine``
    message by its stream of frames, which the next message stops."""
    await websocket.accept()
    config = websocket.app.state.config
    where = f"WS {websocket.url.path}"
    sending = asyncio.Lock()  # a frame's two messages go together
    refining: asyncio.Task | None = None
    stop = threading.Event()

    async def send_frame(head: str, data: bytes, stopped: threading.Event | None = None) -> bool:
        async with sending:
            if stopped is not None and stopped.is_set():
                return False
            await websocket.send_text(head)
            await websocket.send_bytes(data)
            return True

    async def stream(steps: Generator[tuple[RefineStep, dict[str, Any]], None, None], stopped: threading.Event) -> None:
        try:
            while True:
                got = await run_in_threadpool(next, steps, None)
                if got is None:
                    return
                step, view = got
                if not await send_frame(frame_head(step.frame, view, step), step.frame.body, stopped):
                    return
                if step.done:
                    return
        except Exception as exc:  # as a message's failure: one error message (unless stopped meanwhile)
            async with sending:
                if not stopped.is_set():
                    try:
                        await websocket.send_text(json.dumps(errors.answer(exc, config, where).ws_message()))
                    except Exception:  # the connection is gone: nobody to tell
                        pass
        finally:
            await run_in_threadpool(steps.close)  # (next has returned: the generator is not running)

    def stop_refining() -> None:
        nonlocal refining
        stop.set()  # its frame in flight stops between slices, and nothing more of it is sent
        refining = None

    try:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            if refining is not None:
                stop_refining()
            data = message.get("text")
            if data is None:
                data = message.get("bytes") or b""
            refused = wire.refusal(websocket.scope)  # answers of this address not taken: no new work
            if refused is not None:
                async with sending:
                    await websocket.send_text(json.dumps(refused))
                continue
            try:
                stop = threading.Event()
                steps = await run_in_threadpool(refine_request, service, session_id, data, stop)
                if steps is not None:
                    refining = asyncio.ensure_future(stream(steps, stop))
                    continue
                frame, view = await answer_message(service, frames, session_id, data)
            except Exception as exc:  # every failure is a row of the error table, as over HTTP
                async with sending:
                    await websocket.send_text(json.dumps(errors.answer(exc, config, where).ws_message()))
                continue
            await send_frame(frame_head(frame, view), frame.body)
    except WebSocketDisconnect:
        return
    finally:
        stop.set()  # a stream still running ends at its next frame's slice, sending nothing
