"""Refinement while still: a resting camera's session frames, each adding samples to its accumulation,
until a target (docs/API.md, "Refinement").

:func:`refine` yields one :class:`RefineStep` per frame: the frame (the mean of every sample the
session's accumulation holds) and where the stream stands. Each frame is an accumulation frame
(:mod:`server.frames.accumulate`): a background frame, so the GL thread serves every interactive
frame first, and one the session's next interactive frame supersedes. Its samples per pixel are
sized from the stream's previous frame so that one frame takes about ``POCKETRAY_REFINE_SLICE_MS``
of GL time (the first takes :data:`FIRST_SLICE` samples; the next at most :data:`GROWTH` × as many),
never past the target nor past what the caps accept (halved until a frame is accepted).

The stream ends after the frame that reaches ``target_samples``, or the first to end at or past
``target_ms`` of wall-clock time (0: none), or the first whose frames' GL time reaches the service's
POCKETRAY_MAX_REFINE_MS (the GL time, not the wall: resting sessions share the GL thread, and a
stream that waits its turn spends none of it), or the first whose estimated relative noise is at
most ``target_noise`` (:func:`server.frames.accumulate.relative_noise`; 0: none), or when the
accumulation did not grow (its byte budget or MAX_ACCUMULATED_SAMPLES), or — without a frame — when
the session changed (a gesture, new settings) or was deleted, or ``cancel`` is set (the client went away, a
WebSocket's next message).

A Whitted colour frame refines the same way by jittered slices of its √s × √s sub-pixel grid
(s = its ``samples_per_pixel``; :func:`renderer.gl.frame.plan_whitted_slices`) — stochastic
anti-aliasing past 16 samples: its first frame is one slice (the plain frame's image), the next
are sized in slices as a path stream's in samples, each adding s samples per pixel a slice. A frame
of another mode (depth, primid, normal, heat, recursion) is answered once: its image does not
change with more frames.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from renderer.config.settings import SettingValues
from renderer.limits import MAX_PATH_SAMPLES

from ..faults import FrameTooLarge, InputError, NotFound, Superseded
from ..frames.encode import Frame
from ..frames.pipeline import FrameRequest, accumulates, final, radiance
from .service import SessionService

FIRST_SLICE = 4  # samples per pixel of a stream's first frame: the first better image comes soon
GROWTH = 4  # a frame adds at most this many times its predecessor's samples (its timing is one measurement)


@dataclass(frozen=True)
class RefineStep:
    """One frame of a refinement stream and where the stream stands after it. ``reason`` (when
    ``done``): ``samples`` (target reached), ``time`` (target time spent), ``noise`` (the noise
    estimated at most the target), ``held`` (the accumulation did not grow: its byte budget, or
    MAX_ACCUMULATED_SAMPLES), ``budget`` (the service's GL time for one resting view spent) or
    ``one_frame`` (not a colour frame)."""

    frame: Frame
    samples: int  # samples per pixel the image holds
    target_samples: int
    target_ms: int  # wall-clock target (0: none)
    elapsed_ms: float
    done: bool
    reason: str | None = None
    noise: float | None = None  # the image's relative noise as estimated (None: not yet)
    target_noise: float = 0.0
    gl_ms: float = 0.0  # GL time the stream's frames took so far
    budget_ms: int = 0  # … and the most it may take (POCKETRAY_MAX_REFINE_MS)
    request: FrameRequest | None = None  # the frame's request: the view it was rendered with

    def progress(self) -> dict[str, Any]:
        """What the WebSocket's ``refine`` object and the HTTP part's ``X-Refine`` say."""
        return {
            "samples": self.samples,
            "target_samples": self.target_samples,
            "target_ms": self.target_ms,
            "elapsed_ms": round(self.elapsed_ms, 1),
            "done": self.done,
            "reason": self.reason,
            "noise": None if self.noise is None else round(self.noise, 5),
            "target_noise": self.target_noise,
            "gl_ms": round(self.gl_ms, 1),
            "budget_ms": self.budget_ms,
        }


def next_slice(samples: int, trace_ms: float, slice_ms: float, left: int) -> int:
    """Samples per pixel of the next frame: about ``slice_ms`` at the previous frame's ``trace_ms``
    for ``samples``, at most GROWTH × as many, within 1 … ``left`` and MAX_PATH_SAMPLES."""
    per_sample = max(trace_ms, 1e-3) / max(samples, 1)
    k = int(slice_ms / per_sample)
    return max(1, min(k, GROWTH * samples, left, MAX_PATH_SAMPLES))


def refine(
    service: SessionService,
    session_id: str,
    patch: SettingValues,
    *,
    target_samples: int | None = None,
    target_ms: int | None = None,
    target_noise: float | None = None,
    cancel: threading.Event | None = None,
) -> Iterator[RefineStep]:
    """The refinement stream of the session's current view with the frame query's ``patch``; the
    targets default to the session's ``refine_samples``, ``refine_time_ms`` and ``refine_noise``
    (with the patch's)."""
    t0 = time.perf_counter()
    state = service.get(session_id)
    settings = service.caps.merge_settings(state.settings, patch)
    goal_samples = int(target_samples if target_samples is not None else settings["refine_samples"])
    goal_ms = int(target_ms if target_ms is not None else settings["refine_time_ms"])
    budget_ms = service.config.max_refine_ms
    gl_ms = 0.0
    goal_noise = float(target_noise if target_noise is not None else settings["refine_noise"])
    version = state.version
    noise: float | None = None
    request: FrameRequest | None = None  # the request of the frame made last

    def step(frame: Frame, held: int, done: bool, reason: str | None) -> RefineStep:
        elapsed = (time.perf_counter() - t0) * 1e3
        return RefineStep(
            frame, held, goal_samples, goal_ms, elapsed, done, reason, noise, goal_noise, gl_ms, budget_ms, request
        )

    render = service.frame_settings(state, patch).render
    if not accumulates(render):
        request = service.frame_request(session_id, patch, cancel=cancel)
        frame = final(service.frames.run(request))
        yield step(frame, frame.samples or 1, True, "one_frame")
        return
    # A path frame adds k samples; a Whitted frame k jittered slices of the session's own grid, each
    # of `unit` samples (its first frame one slice: the plain frame's image, as soon as it).
    path = radiance(render)
    unit = 1 if path else render.samples_per_pixel
    held = service.frames.accumulations.count(session_id)  # (of this view or not: the first frame says)
    k = FIRST_SLICE if path else 1

    def left(held: int) -> int:  # increments (samples, or slices) to the target
        return -(-(goal_samples - held) // unit)

    # Every free render process traces ranges of the samples too (redis backend; docs/DEPLOY.md).
    shared = None
    if path and service.shared_refine is not None:

        def still() -> bool:
            try:
                return not (cancel is not None and cancel.is_set()) and service.get(session_id).version == version
            except NotFound:
                return False

        shared = service.shared_refine.stream(service, session_id, patch, version, goal_samples, still)
    try:
        while True:
            if cancel is not None and cancel.is_set():
                return
            try:
                if service.get(session_id).version != version:
                    return  # a gesture or a settings change: the stream was of the view before it
            except NotFound:
                return  # the session was deleted (or expired) meanwhile: its stream ends as for a change
            k = max(1, min(k, left(held))) if held < goal_samples else 1
            if shared is not None:  # the ranges other processes traced up to here added; k up to the next
                got = shared.next_frame(held, k)
                if got is None:
                    return
                held, k = got
            try:
                if path:
                    request = service.frame_request(
                        session_id, {**patch, "samples_per_pixel": k}, cancel=cancel, accumulate=True
                    )
                else:
                    request = service.frame_request(session_id, patch, cancel=cancel, accumulate=True, slices=k)
                frame = final(service.frames.run(request))
            except InputError as e:
                if k == 1 or not path or isinstance(e, FrameTooLarge):
                    raise
                k //= 2  # over a cap (work, cost): a smaller slice (the caps see a Whitted frame's grid alone)
                continue
            except (Superseded, NotFound):
                return  # the session's next interactive frame (or the client, or its deletion) stopped it
            held = int(frame.samples or 0)
            gl_ms += frame.timings.get("trace", 0.0)
            kept = service.frames.accumulations.count(session_id) == held
            noise = service.frames.accumulations.noise(session_id) if kept else None
            elapsed_ms = (time.perf_counter() - t0) * 1e3
            if held >= goal_samples:
                yield step(frame, held, True, "samples")
                return
            if not kept:
                yield step(frame, held, True, "held")
                return
            if goal_noise > 0 and noise is not None and noise <= goal_noise:
                yield step(frame, held, True, "noise")
                return
            if goal_ms and elapsed_ms >= goal_ms:
                yield step(frame, held, True, "time")
                return
            if gl_ms >= budget_ms:
                yield step(frame, held, True, "budget")
                return
            yield step(frame, held, False, None)
            k = next_slice(k, frame.timings.get("trace", 0.0), service.config.refine_slice_ms, left(held))
    finally:
        if shared is not None:
            shared.close()
