"""The one thread that owns the OpenGL context: a scheduler of slices of GPU work.

An OpenGL context belongs to the thread that made it, so every GL call runs on one thread
made at start-up. Admission is bounded: at most ``queue_size`` jobs are admitted at once
(running ones included). A request takes a :class:`Ticket` (or gets :class:`QueueFull`,
which the API turns into 503 + Retry-After), then runs its job with it:

- :meth:`Ticket.run` / :meth:`Ticket.submit`: a call ``fn(renderer)`` done in one go
  (a build for statistics, the warm-up render);
- :meth:`Ticket.frame`: a frame traced as *slices* — ``start(renderer)`` returns a frame
  object with ``step()`` (one band of rows or one pass of a ray engine, each about
  ``POCKETRAY_SLICE_MS`` of estimated work, ending in ``glFinish``), ``done``, ``preview``,
  ``result()`` and ``release()`` (:class:`renderer.gl.frame.TracerFrame`,
  :class:`renderer.gl.ray_engine.RayEngineFrame`).

The thread takes one slice at a time, round-robin over the *sessions* that have frames in
flight (frames of one session in order), so a small frame of one session is answered
within a few slices while another session's long frame runs. *Background* frames (an
accumulation's, docs/API.md "Accumulation") get a slice only when no session's next frame is an
interactive one: they never hold up a preview or a gesture's frame by more than the slice that
is running. A frame stops between
slices when it is cancelled — its request timed out, its client went away, or a newer
frame of the same session superseded it — and its GPU memory and queue slot are given back
at once. Back-pressure tells the truth: ``Retry-After`` is the estimated work queued
ahead, and :attr:`GLWorker.saturated` says when it exceeds the render timeout.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Hashable
from concurrent.futures import Future
from contextlib import AbstractContextManager, nullcontext
from typing import Any, TypeVar

from ..http import metrics

log = logging.getLogger("pocketray.gl")
T = TypeVar("T")


def default_renderer(max_target_bytes: int = 256 << 20, max_programs: int | None = None) -> Any:
    """The service's renderer: GLRenderer on a headless context, keeping at most
    ``max_target_bytes`` of free render targets and ``max_programs`` compiled shader programs
    (None: ``renderer.limits.MAX_PROGRAMS``) for reuse.

    Its ``finish()`` and its draws release the GIL (renderer.gl.context), so HTTP handling,
    /api/health and 503 answers go on while the GL thread waits for a slice or llvmpipe
    compiles a new variant.
    """
    from renderer.gl.renderer import GLRenderer

    if max_programs is None:
        return GLRenderer(max_target_bytes=max_target_bytes)
    return GLRenderer(max_target_bytes=max_target_bytes, max_programs=max_programs)


class VariantsLimited(Exception):
    """A session asked for a shader variant the renderer holds no program of, with no compile
    left in its bucket: retry after ``retry_after_s`` seconds (nothing was compiled or traced)."""

    def __init__(self, retry_after_s: int, per_min: float, burst: int):
        super().__init__(f"new shader variants: retry after {retry_after_s} s")
        self.retry_after_s, self.per_min, self.burst = retry_after_s, per_min, burst


class VariantRate:
    """New shader variants each session may have compiled: a token bucket per session of at most
    ``burst`` compiles, refilled at ``per_min`` a minute (0: no limit). A compile takes a token;
    a variant the renderer holds costs nothing. Frames without a session share one bucket. The
    buckets are bounded in number: beyond ``max_sessions`` the least recently charged is
    forgotten (it starts again full, as a new session does)."""

    ANONYMOUS = "(no session)"

    def __init__(
        self,
        per_min: float,
        burst: int,
        max_sessions: int = 65_536,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.per_min, self.burst, self.max_sessions = float(per_min), int(burst), int(max_sessions)
        self.clock = clock
        self._buckets: OrderedDict[Hashable, tuple[float, float]] = OrderedDict()  # key → (tokens, at)
        self._lock = threading.Lock()

    def charge(self, session: Hashable) -> None:
        """Take one compile of ``session``'s bucket, or raise :class:`VariantsLimited`."""
        if self.per_min <= 0:
            return
        key = session if isinstance(session, (str, int)) else self.ANONYMOUS
        rate_s = self.per_min / 60.0
        with self._lock:
            now = self.clock()
            tokens, at = self._buckets.get(key, (float(self.burst), now))
            tokens = min(float(self.burst), tokens + (now - at) * rate_s)
            self._buckets[key] = (tokens - 1.0 if tokens >= 1.0 else tokens, now)
            self._buckets.move_to_end(key)
            while len(self._buckets) > self.max_sessions:
                self._buckets.popitem(last=False)
            if tokens < 1.0:
                raise VariantsLimited(max(1, math.ceil((1.0 - tokens) / rate_s)), self.per_min, self.burst)


class QueueFull(Exception):
    """No slot free; ``retry_after_s`` estimates when one will be (whole seconds ≥ 1)."""

    def __init__(self, retry_after_s: int):
        super().__init__(f"render queue full; retry after {retry_after_s} s")
        self.retry_after_s = retry_after_s


class GLNotReady(Exception):
    """The GL context could not be created (``detail`` says why), or the service is stopping."""


class FrameCancelled(Exception):
    """A frame stopped between slices: ``reason`` is ``timeout``, ``disconnected``,
    ``superseded`` or ``shutdown``; nothing it would have produced exists."""

    def __init__(self, reason: str):
        super().__init__(f"frame cancelled ({reason})")
        self.reason = reason


class FrameHandle:
    """A frame in flight: wait for its preview and its result, or cancel it."""

    def __init__(
        self,
        worker: GLWorker,
        ticket: Ticket,
        session: Hashable,
        start: Callable[[Any], Any],
        cost_ms: float,
        background: bool = False,
    ):
        self.worker, self.ticket, self.session, self.start = worker, ticket, session, start
        self.cost_ms = float(cost_ms)
        self.background = background  # sliced only when no interactive frame waits
        self.frame: Any = None  # the renderer's frame object, once started (GL thread)
        self.reason: str | None = None  # why it was cancelled
        self.started_at: float | None = None
        self._done = threading.Event()
        self._preview_ready = threading.Event()
        self._changed = threading.Condition()
        self._preview: Any = None
        self._result: Any = None
        self._error: BaseException | None = None

    # ---- the caller's side -------------------------------------------------------------------
    def cancel(self, reason: str) -> None:
        """Stop between slices (the GL thread drops the frame); the slot is free at once."""
        if self._done.is_set():
            return
        self.reason = self.reason or reason
        self.ticket._release()
        self.worker._wake()

    def poll(self, preview: bool, timeout_s: float | None) -> bool:
        """Wait up to ``timeout_s`` for the frame to finish (or, with ``preview``, for its first
        image); True when it is there. Nothing is cancelled by a timeout here."""

        def ready() -> bool:
            return self._done.is_set() or (preview and self._preview_ready.is_set())

        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._changed:
            while not ready():
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    return False
                self._changed.wait(1.0 if left is None else min(1.0, left))
        return True

    def result(self) -> Any:
        """The finished frame's result, or the error that ended it (:class:`FrameCancelled`)."""
        if not self._done.is_set():
            raise RuntimeError("the frame is not finished")
        if self._error is not None:
            raise self._error
        return self._result

    def preview_result(self) -> Any | None:
        """The first image of a frame with more passes to come; None when it has none (or it
        ended first: then :meth:`result` says how)."""
        return self._preview

    def wait_preview(self, timeout_s: float | None) -> Any | None:
        """:meth:`preview_result` once there (a frame without one: once finished)."""
        self._wait_or_cancel(True, timeout_s)
        return self._preview

    def wait(self, timeout_s: float | None) -> Any:
        """The finished frame's result; :class:`FrameCancelled` (``timeout`` after ``timeout_s``)."""
        self._wait_or_cancel(False, timeout_s)
        return self.result()

    def _wait_or_cancel(self, preview: bool, timeout_s: float | None) -> None:
        if self.poll(preview, timeout_s):
            return
        self.cancel("timeout")
        self._done.wait(5.0)  # the GL thread drops it at the end of its slice
        if not self._done.is_set():
            self._finish(error=FrameCancelled("timeout"))

    # ---- the GL thread's side -----------------------------------------------------------------
    @property
    def remaining_ms(self) -> float:
        f = self.frame
        total = getattr(f, "pixels_total", 0) if f is not None else 0
        if f is None or not total:
            return self.cost_ms
        return self.cost_ms * getattr(f, "pixels_left", total) / total

    def _finish(self, result: Any = None, error: BaseException | None = None) -> None:
        if self._done.is_set():
            return
        self._result, self._error = result, error
        with self._changed:
            self._done.set()
            self._changed.notify_all()

    def _set_preview(self, preview: Any) -> None:
        with self._changed:
            self._preview = preview
            self._preview_ready.set()
            self._changed.notify_all()


class GLWorker:
    """The GL thread: bounded admission, one-shot calls and sliced frames.

    ``warmup(renderer)`` runs once after the context exists; ``ready`` is set when it
    succeeded. ``info`` holds the GL renderer and version strings. ``render_timeout_s``
    is what :attr:`saturated` compares the queued work with. ``variant_rate``: each new shader
    program a frame's start compiles is charged to the frame's session (:class:`VariantRate`).
    """

    def __init__(
        self,
        queue_size: int,
        warmup: Callable[[Any], None] | None = None,
        renderer_factory: Callable[[], Any] | None = None,
        render_timeout_s: float = 120.0,
        variant_rate: VariantRate | None = None,
    ):
        self.queue_size = queue_size
        self.variant_rate = variant_rate
        self.render_timeout_s = render_timeout_s
        self._warmup = warmup
        self._factory = renderer_factory
        self._lock = threading.Lock()
        self._cv = threading.Condition(self._lock)
        self._admitted = 0
        self._calls: deque[tuple[Callable[[Any], Any], Future]] = deque()
        self._starting: deque[FrameHandle] = deque()
        self._frames: OrderedDict[Hashable, deque[FrameHandle]] = OrderedDict()  # round-robin by session
        self._closing = False
        self._avg_call_s = 0.5  # moving average of a one-shot call, for Retry-After
        self.renderer: Any = None
        self.info: dict[str, str] | None = None
        self.error: str | None = None
        self.ready = threading.Event()
        self.started: Future = Future()
        self.slices = 0
        self._thread = threading.Thread(target=self._main, name="pocketray-gl", daemon=True)

    # ---- life cycle ----------------------------------------------------------------------------
    def start(self) -> Future:
        """Create the context (and warm up) on the GL thread; returns at once."""
        self._thread.start()
        return self.started

    def _init(self) -> None:
        try:
            self.renderer = (self._factory or default_renderer)()
            self.info = dict(self.renderer.info)
            log.info("OpenGL: %s, %s", self.info.get("renderer"), self.info.get("version"))
        except Exception as e:  # no EGL, no driver: the service stays up, not ready
            self.error = f"OpenGL unavailable: {e}"
            log.error("%s", self.error)
            return
        try:
            if self._warmup is not None:
                t0 = time.perf_counter()
                self._warmup(self.renderer)
                log.info("warm-up render took %.0f ms", (time.perf_counter() - t0) * 1e3)
        except Exception as e:
            self.error = f"warm-up render failed: {e}"
            log.exception("warm-up render failed")
            return
        self.ready.set()

    def close(self) -> None:
        """Stop: cancel the frames in flight, finish the calls admitted, release the context."""
        with self._cv:
            self._closing = True
            for h in [*self._starting, *(h for q in self._frames.values() for h in q)]:
                h.reason = h.reason or "shutdown"
            self._cv.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=60)

    @property
    def closing(self) -> bool:
        return self._closing

    # ---- admission -----------------------------------------------------------------------------
    @property
    def admitted(self) -> int:
        return self._admitted

    def admit(self) -> Ticket:
        """Reserve a slot or raise QueueFull (GLNotReady when the context failed or the
        service is stopping)."""
        if self.error is not None:
            raise GLNotReady(self.error)
        if self._closing:
            raise GLNotReady("the service is shutting down")
        with self._lock:
            if self._admitted >= self.queue_size:
                raise QueueFull(self.retry_after())
            self._admitted += 1
        metrics.render_admitted()
        return Ticket(self)

    def queued_ms(self) -> float:
        """Estimated GL time of the work admitted and not yet done (ms)."""
        frames = [*self._starting, *(h for q in list(self._frames.values()) for h in list(q))]
        return sum(h.remaining_ms for h in frames if h.reason is None) + len(self._calls) * self._avg_call_s * 1e3

    def retry_after(self) -> int:
        """Whole seconds until the work queued ahead is likely done (≥ 1)."""
        return max(1, math.ceil(self.queued_ms() / 1e3))

    @property
    def saturated(self) -> bool:
        """The work queued ahead would take longer than a render may wait."""
        return self.queued_ms() > self.render_timeout_s * 1e3

    def _release(self) -> None:
        with self._lock:
            self._admitted -= 1

    def _wake(self) -> None:
        with self._cv:
            self._cv.notify_all()

    # ---- submission ----------------------------------------------------------------------------
    def _submit_call(self, fn: Callable[[Any], T]) -> Future[T]:
        fut: Future = Future()
        with self._cv:
            if self._closing:
                raise GLNotReady("the service is shutting down")
            self._calls.append((fn, fut))
            self._cv.notify_all()
        return fut

    def _submit_frame(self, handle: FrameHandle) -> None:
        with self._cv:
            if self._closing:
                raise GLNotReady("the service is shutting down")
            self._starting.append(handle)
            self._cv.notify_all()

    def in_flight(self, session: Hashable) -> list[FrameHandle]:
        """The frames of ``session`` admitted and not finished (for latest-wins)."""
        with self._lock:
            starting = [h for h in self._starting if h.session == session]
            return [h for h in [*starting, *self._frames.get(session, ())] if h.reason is None]

    # ---- the thread ----------------------------------------------------------------------------
    def _main(self) -> None:
        self._init()
        self.started.set_result(None)
        while True:
            with self._cv:
                while not (self._calls or self._starting or self._frames or self._closing):
                    self._cv.wait()
                if self._closing and not self._calls:
                    stopping = True
                else:
                    stopping = False
                call = self._calls.popleft() if self._calls else None
                start = self._starting.popleft() if call is None and self._starting else None
            if stopping:
                self._drop_all("shutdown")
                self._release_context()
                return
            if call is not None:
                self._run_call(*call)
            elif start is not None:
                self._start_frame(start)
            else:
                self._slice()

    def _run_call(self, fn: Callable[[Any], Any], fut: Future) -> None:
        if not fut.set_running_or_notify_cancel():
            return
        t0 = time.perf_counter()
        metrics.render_started()
        try:
            if self.renderer is None:
                raise GLNotReady(self.error or "OpenGL context not created")
            fut.set_result(fn(self.renderer))
        except BaseException as e:  # handed to the waiting request
            fut.set_exception(e)
        finally:
            self._avg_call_s = 0.8 * self._avg_call_s + 0.2 * (time.perf_counter() - t0)

    def _start_frame(self, h: FrameHandle) -> None:
        if h.reason is not None:  # cancelled while it waited: it never runs
            metrics.render_started()
            h._finish(error=FrameCancelled(h.reason))
            return
        try:
            if self.renderer is None:
                raise GLNotReady(self.error or "OpenGL context not created")
            h.started_at = time.perf_counter()
            metrics.render_started()
            with self._charging(h.session):
                h.frame = h.start(self.renderer)  # uploads: counts as a slice
        except BaseException as e:
            h._finish(error=e)
            h.ticket._release()
            return
        with self._lock:
            self._frames.setdefault(h.session, deque()).append(h)

    def _charging(self, session: Hashable) -> AbstractContextManager[None]:
        """While a frame of ``session`` starts: each program it compiles is charged to the session."""
        programs = getattr(self.renderer, "programs", None)
        rate = self.variant_rate
        if rate is None or programs is None:
            return nullcontext()
        return programs.charging(lambda: rate.charge(session))

    def _slice(self) -> None:
        """One slice of the next session's frame, round-robin; background frames only when no
        session's next frame is interactive."""
        with self._lock:
            if not self._frames:
                return
            # (a cancelled background frame goes at once: an interactive frame of its session waits behind it)
            session, queue = next(
                ((s, q) for s, q in self._frames.items() if not q[0].background or q[0].reason is not None),
                next(iter(self._frames.items())),
            )
            self._frames.move_to_end(session)  # the next session goes next time
            h = queue[0]
        done = False
        try:
            if h.reason is not None:
                h.frame.release()
                h._finish(error=FrameCancelled(h.reason))
                done = True
            else:
                finished = h.frame.step()
                self.slices += 1
                preview = getattr(h.frame, "preview", None)
                if preview is not None and not h._preview_ready.is_set():
                    h._set_preview(preview)
                if finished:
                    h._finish(result=h.frame.result())
                    done = True
        except BaseException as e:  # a frame that fails fails alone
            try:
                h.frame.release()
            except Exception:  # pragma: no cover - best effort
                pass
            h._finish(error=e)
            done = True
        if done:
            with self._lock:
                queue.popleft()
                if not queue:
                    del self._frames[session]
            if h.reason is None:
                h.ticket._release()

    def _drop_all(self, reason: str) -> None:
        with self._lock:
            pending = [*self._starting, *(h for q in self._frames.values() for h in q)]
            self._starting.clear()
            self._frames.clear()
        for h in pending:
            if h.frame is not None:
                try:
                    h.frame.release()
                except Exception:  # pragma: no cover
                    pass
            h.reason = h.reason or reason
            h._finish(error=FrameCancelled(h.reason))

    def _release_context(self) -> None:
        ctx = getattr(self.renderer, "ctx", None)
        if ctx is not None:
            try:
                ctx.release()
            except Exception:  # pragma: no cover - best effort at shutdown
                pass
        self.renderer = None


class Ticket:
    """One admitted job. Use as a context manager; run at most one job with it."""

    def __init__(self, worker: GLWorker):
        self._worker = worker
        self._submitted = False
        self._released = False
        self._lock = threading.Lock()

    def submit(self, fn: Callable[[Any], T]) -> Future[T]:
        """Run ``fn(renderer)`` on the GL thread in one go; the slot frees when it is done."""
        self._claim()
        fut = self._worker._submit_call(fn)
        fut.add_done_callback(lambda _f: self._release())
        return fut

    def run(self, fn: Callable[[Any], T], timeout_s: float | None = None) -> T:
        """``submit`` and wait (TimeoutError after ``timeout_s`` seconds)."""
        return self.submit(fn).result(timeout=timeout_s)

    def frame(
        self,
        start: Callable[[Any], Any],
        *,
        session: Hashable = None,
        cost_ms: float = 0.0,
        background: bool = False,
    ) -> FrameHandle:
        """Trace a frame in slices: ``start(renderer)`` (on the GL thread) returns the frame
        object; frames of one ``session`` go in order, sessions take turns; a ``background``
        frame's turns go to any interactive frame that waits."""
        self._claim()
        handle = FrameHandle(
            self._worker, self, session if session is not None else object(), start, cost_ms, background
        )
        self._worker._submit_frame(handle)
        return handle

    def _claim(self) -> None:
        if self._submitted:
            raise RuntimeError("a ticket runs one job")
        self._submitted = True

    def _release(self) -> None:
        with self._lock:
            if self._released:
                return
            self._released = True
        self._worker._release()
        metrics.render_released(never_ran=not self._submitted)

    def __enter__(self) -> Ticket:
        return self

    def __exit__(self, *exc: object) -> None:
        if not self._submitted:
            self._release()
