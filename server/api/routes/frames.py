"""Frames (the View) and what the Controller's gestures ask for: a gesture (optionally
answered with the new frame), a session's frame, its build statistics, a stateless render."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Query, Response
from fastapi.responses import JSONResponse

from ...models import CameraModel, CameraOut, Gesture, GestureQuery, RenderRequest, StatsOut, StatsQuery
from ...view import FRAME_RESPONSE_DOC, Frame, frame_headers
from ..deps import FrameParams, ServiceDep, SessionId
from ..errors import documented

router = APIRouter()


def frame_response(frame: Frame) -> Response:
    """An encoded frame with the headers that describe it (docs/API.md, "Frames")."""
    return Response(content=frame.body, media_type=frame.media_type, headers=frame_headers(frame))


@router.post("/sessions/{session_id}/gesture", response_model=CameraOut,
             responses={200: FRAME_RESPONSE_DOC, **documented(404, 413, 503)},
             summary="Apply pan / pinch / reset; with ?frame=1 answer with the new frame")
def gesture(session_id: SessionId, body: Annotated[Gesture, Body()], service: ServiceDep,
            query: Annotated[GestureQuery, Query()]) -> Any:
    # The frame parameters are validated even without ?frame=1, as they always were.
    if query.frame:
        return frame_response(service.gesture_frame(session_id, body, query.given()))
    state = service.gesture(session_id, body)
    return CameraOut(version=state.version, camera=CameraModel(**state.camera))


@router.get("/sessions/{session_id}/frame", response_class=Response,
            responses={200: FRAME_RESPONSE_DOC, **documented(404, 503)},
            summary="Render the session's current view")
def session_frame(session_id: SessionId, service: ServiceDep, params: FrameParams) -> Response:
    return frame_response(service.session_frame(session_id, params))


@router.get("/sessions/{session_id}/stats", response_model=StatsOut, responses=documented(404, 503),
            summary="Statistics of the acceleration structure for the current (or given) settings")
def session_stats(session_id: SessionId, service: ServiceDep, query: Annotated[StatsQuery, Query()]) -> Any:
    return JSONResponse(service.stats(session_id, query.given()))


@router.post("/render", response_class=Response, responses={200: FRAME_RESPONSE_DOC, **documented(413, 503)},
             summary="Stateless render of a scene with settings (docs/FORMATS.md)")
def render(body: RenderRequest, service: ServiceDep) -> Response:
    return frame_response(service.render_stateless(body.scene, body.settings.given()))
