"""``GET /metrics``: the Prometheus text exposition of :mod:`server.http.metrics` (outside ``/api``)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response
from prometheus_client import CONTENT_TYPE_LATEST

from ...http.metrics import exposition

router = APIRouter(tags=["service"])


@router.get(
    "/metrics",
    response_class=Response,
    operation_id="metrics",
    summary="Prometheus metrics (text exposition format)",
    responses={200: {"description": "metrics", "content": {CONTENT_TYPE_LATEST: {"schema": {"type": "string"}}}}},
)
def metrics(request: Request) -> Response:
    return Response(exposition(request.app.state), media_type=CONTENT_TYPE_LATEST)
