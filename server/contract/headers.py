"""The response headers of a frame that more than the frames read: the stages ``Server-Timing`` names
(the metrics' stage histogram has one series each) and the headers a browser may read across origins
(CORS's ``Access-Control-Expose-Headers``). Where they are written: :mod:`server.frames.encode`."""

from __future__ import annotations

TIMING_NAMES = ("queue", "pose", "update", "build", "upload", "trace", "read", "encode", "total")
EXPOSED = (
    "Server-Timing",
    "X-Session-Version",
    "X-Method",
    "X-Stats",
    "X-Frame-Part",
    "X-Samples",
    "X-Refine",
    "Retry-After",
)
