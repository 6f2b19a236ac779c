"""Gestures in, frames out, on one WebSocket (measured against ?frame=1, see docs/API.md).

Client → a text (or UTF-8 binary) JSON message: a gesture (``{"type": "pan", "dx", "dy"}``
…, or ``{"type": "frame"}`` for a frame without a gesture, ``{"type": "frame", "accumulate":
true}`` for one added to the session's accumulation) with an optional
``"frame": {settings}`` — the settings ``POST …/gesture?frame=1`` takes in its query.
Server → text JSON ``{"version", "camera", "timings", "stats", "media_type", "samples"}`` then the
frame as one binary message; on an error one text JSON ``{"status", "detail"}`` (and
``"retry_after"``, seconds, where HTTP sends Retry-After) — the very answer the HTTP
route gives (:mod:`server.api.errors`), and the connection stays open. While the client's
address has more answer bytes not taken than ``POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT``, a
message is answered ``{"status": 429, …}`` without any work (:func:`server.http.wire.refusal`);
the connection's idle time, message rate and write timeout are :mod:`server.http.wire`'s.

A message is read and validated as FastAPI reads a request: its JSON as the body
(``loc`` ``["body", …]``), its ``"frame"`` settings as the query (``["query", …]``), all
errors of both in one 422.
"""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from pydantic import TypeAdapter, ValidationError

from ...faults import Where
from ...frames.encode import Frame
from ...frames.pipeline import FramePipeline, final
from ...http import wire
from ...sessions.service import SessionService
from .. import body, errors
from ..deps import FramesDep, ServiceDep
from ..schemas import FrameMessage, Gesture, SettingsPatch

router = APIRouter()

_gesture_adapter = TypeAdapter(Gesture)
_patch_adapter = TypeAdapter(SettingsPatch)
_frame_adapter = TypeAdapter(FrameMessage)


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


async def answer_message(
    service: SessionService, frames: FramePipeline, session_id: str, data: str | bytes
) -> tuple[Frame, dict]:
    """The frame one message asks for and the session's camera after it."""
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
            frame = await run_in_threadpool(
                lambda: final(frames.run(service.frame_request(session_id, patch.given(), accumulate=accumulate)))
            )
        else:
            frame = await run_in_threadpool(
                lambda: final(frames.run(service.gesture_request(session_id, gesture, patch.given())))
            )
    state = await run_in_threadpool(service.get, session_id)
    return frame, state.camera


@router.websocket("/sessions/{session_id}/ws")
async def session_socket(websocket: WebSocket, session_id: str, service: ServiceDep, frames: FramesDep) -> None:
    """One connection: each message is answered by a frame or by one error message."""
    await websocket.accept()
    config = websocket.app.state.config
    where = f"WS {websocket.url.path}"
    try:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            data = message.get("text")
            if data is None:
                data = message.get("bytes") or b""
            refused = wire.refusal(websocket.scope)  # answers of this address not taken: no new work
            if refused is not None:
                await websocket.send_text(json.dumps(refused))
                continue
            try:
                frame, camera = await answer_message(service, frames, session_id, data)
            except Exception as exc:  # every failure is a row of the error table, as over HTTP
                await websocket.send_text(json.dumps(errors.answer(exc, config, where).ws_message()))
                continue
            await websocket.send_text(
                json.dumps(
                    {
                        "version": frame.version,
                        "camera": camera,
                        "timings": frame.timings,
                        "stats": frame.stats,
                        "media_type": frame.media_type,
                        "samples": frame.samples,
                    }
                )
            )
            await websocket.send_bytes(frame.body)
    except WebSocketDisconnect:
        return
