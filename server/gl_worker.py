"""The one thread that owns the OpenGL context, and its bounded queue.

An OpenGL context belongs to the thread that made it, so all GL work (and the
BIH builds, which are CPU work the GL thread is waiting for anyway) runs on a
single-worker executor created at start-up. Admission is bounded: at most
``queue_size`` jobs are admitted at once (the running one included). A request
first takes a :class:`Ticket` (or gets :class:`QueueFull`, which the API turns
into 503 + Retry-After), checks and applies its change, then runs its job with
the ticket; the slot is freed when the job has finished on the GL thread.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Callable, TypeVar

from . import metrics

log = logging.getLogger("pocketray.gl")
T = TypeVar("T")


def default_renderer() -> Any:
    """The service's renderer: GLRenderer on a headless context.

    Its ``finish()`` releases the GIL (renderer.gl.context), so HTTP handling,
    /api/health and 503 answers go on while the GL thread waits for a frame.
    """
    from renderer.gl.renderer import GLRenderer

    return GLRenderer()


class QueueFull(Exception):
    """No slot free; ``retry_after_s`` estimates when one will be (whole seconds ≥ 1)."""

    def __init__(self, retry_after_s: int):
        super().__init__(f"render queue full; retry after {retry_after_s} s")
        self.retry_after_s = retry_after_s


class GLNotReady(Exception):
    """The GL context could not be created (``detail`` says why)."""


class GLWorker:
    """Single GL thread + bounded admission.

    ``warmup(renderer)`` runs once after the context exists; ``ready`` is set when
    it succeeded. ``info`` holds the GL renderer and version strings.
    """

    def __init__(self, queue_size: int, warmup: Callable[[Any], None] | None = None,
                 renderer_factory: Callable[[], Any] | None = None):
        self.queue_size = queue_size
        self._warmup = warmup
        self._factory = renderer_factory
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="pocketray-gl")
        self._lock = threading.Lock()
        self._admitted = 0
        self._avg_job_s = 0.5  # moving average of a job's duration, for Retry-After
        self.renderer: Any = None
        self.info: dict[str, str] | None = None
        self.error: str | None = None
        self.ready = threading.Event()
        self.started: Future | None = None

    # ---- life cycle ----------------------------------------------------------------
    def start(self) -> Future:
        """Create the context (and warm up) on the GL thread; returns at once."""
        self.started = self._executor.submit(self._init)
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
        """Finish admitted jobs, release the context on its own thread, stop the thread."""
        def release() -> None:
            ctx = getattr(self.renderer, "ctx", None)
            if ctx is not None:
                try:
                    ctx.release()
                except Exception:  # pragma: no cover - best effort at shutdown
                    pass
            self.renderer = None
        try:
            self._executor.submit(release)
        except RuntimeError:
            pass
        self._executor.shutdown(wait=True, cancel_futures=False)

    # ---- admission -----------------------------------------------------------------------
    @property
    def admitted(self) -> int:
        return self._admitted

    def admit(self) -> "Ticket":
        """Reserve a slot or raise QueueFull (GLNotReady when the context failed)."""
        if self.error is not None:
            raise GLNotReady(self.error)
        with self._lock:
            if self._admitted >= self.queue_size:
                raise QueueFull(self.retry_after())
            self._admitted += 1
        metrics.render_admitted()
        return Ticket(self)

    def retry_after(self) -> int:
        """Seconds until the queue has likely drained by one slot's worth (≥ 1)."""
        return max(1, math.ceil(self._avg_job_s * max(1, self._admitted) / 2))

    def _release(self) -> None:
        with self._lock:
            self._admitted -= 1

    def _run(self, fn: Callable[[Any], T]) -> T:
        if self.renderer is None:
            raise GLNotReady(self.error or "OpenGL context not created")
        t0 = time.perf_counter()
        metrics.render_started()
        try:
            return fn(self.renderer)
        finally:
            dt = time.perf_counter() - t0
            self._avg_job_s = 0.8 * self._avg_job_s + 0.2 * dt


class Ticket:
    """One admitted job. Use as a context manager; ``submit`` at most once."""

    def __init__(self, worker: GLWorker):
        self._worker = worker
        self._submitted = False
        self._released = False
        self._lock = threading.Lock()

    def submit(self, fn: Callable[[Any], T]) -> "Future[T]":
        """Run ``fn(renderer)`` on the GL thread; the slot frees when it is done."""
        if self._submitted:
            raise RuntimeError("a ticket runs one job")
        self._submitted = True
        fut = self._worker._executor.submit(self._worker._run, fn)
        fut.add_done_callback(lambda _f: self._release())
        return fut

    def run(self, fn: Callable[[Any], T], timeout_s: float | None = None) -> T:
        """``submit`` and wait (TimeoutError after ``timeout_s`` seconds)."""
        return self.submit(fn).result(timeout=timeout_s)

    def _release(self) -> None:
        with self._lock:
            if self._released:
                return
            self._released = True
        self._worker._release()
        metrics.render_released(never_ran=not self._submitted)

    def __enter__(self) -> "Ticket":
        return self

    def __exit__(self, *exc: object) -> None:
        if not self._submitted:
            self._release()
