"""Prometheus metrics of one service (``GET /metrics``, the text exposition format).

The names (docs/API.md, "Metrics"):

- ``pocketray_renders_admitted`` — renders admitted to the GL queue (running + waiting);
  ``pocketray_renders_waiting`` — of those, the ones not yet running. What an autoscaler
  watches: a queue that stays non-empty wants another process.
- ``pocketray_renders_total{method, mode}`` — frames rendered.
- ``pocketray_render_stage_seconds{method, mode, stage}`` — histogram of each stage of a
  frame (``queue, pose, update, build, upload, trace, read, encode, total``: the
  ``Server-Timing`` of docs/API.md).
- ``pocketray_unavailable_total{cause}`` — 503 answers by cause: ``queue_full``,
  ``gl_unavailable``, ``render_timeout``, ``store_unavailable`` (the error table) and
  ``not_ready`` / ``draining`` (``/api/ready``).
- ``pocketray_http_requests_total{method, route, status}`` and
  ``pocketray_http_request_duration_seconds{method, route}`` — every request, by route
  template (``/api/sessions/{session_id}/frame``), never by raw path.
- ``pocketray_accumulation_bytes`` — bytes the sessions' accumulations hold (their float32 sums,
  bounded by ``POCKETRAY_MAX_ACCUMULATION_BYTES``), and
  ``pocketray_accumulations_dropped_total{reason}`` — accumulations dropped: ``change`` (a frame
  of the session changed what the image depends on), ``budget`` (least recently used, to make
  room), ``deleted`` (its session was).
- ``pocketray_sessions`` — sessions in the store (all processes', not expired), and
  ``pocketray_store_bytes`` — the bytes its quota counts (``POCKETRAY_MAX_STORE_BYTES``), both
  read at most every :data:`SESSIONS_CACHE_S` seconds; ``pocketray_ready`` — 1 when this process
  answers ``/api/ready`` with 200.

Every label value comes from a closed set, whatever a client sends, so that no request can
add series (each one is kept for the life of the process, and is in every scrape): the HTTP
method is one of :data:`HTTP_METHODS` or ``other``; the route is a template of the app's
routes, ``static`` (the static files, and paths nothing serves) or ``other``; the status is
the answer's code; render methods, modes and stages are the renderer's names (else ``other``).

With several uvicorn workers (``pocketray serve --workers N``) every worker writes its
values to ``PROMETHEUS_MULTIPROC_DIR`` (the CLI makes one) and a scrape, whichever worker
answers it, sums them (gauges: the live processes' sum). The hooks below are the only
calls the rest of the service makes; they never raise.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Iterable
from typing import Any

from prometheus_client import (
    REGISTRY,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    disable_created_metrics,
    generate_latest,
)
from prometheus_client.core import GaugeMetricFamily

from renderer.config.settings import METHOD_NAMES
from renderer.modes import MODES

from ..contract.headers import TIMING_NAMES

disable_created_metrics()  # no *_created series: they double the exposition and nobody graphs them

log = logging.getLogger("pocketray.metrics")

MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
SESSIONS_CACHE_S = 10.0
STAGE_BUCKETS_S = (
    0.0005,
    0.001,
    0.0025,
    0.005,
    0.01,
    0.025,
    0.05,
    0.1,
    0.25,
    0.5,
    1.0,
    2.5,
    5.0,
    10.0,
    30.0,
    60.0,
    120.0,
)
HTTP_BUCKETS_S = (0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 120.0)

RENDERS_ADMITTED = Gauge(
    "pocketray_renders_admitted", "Renders admitted to the GL queue (running + waiting)", multiprocess_mode="livesum"
)
RENDERS_WAITING = Gauge(
    "pocketray_renders_waiting", "Admitted renders waiting for the GL thread", multiprocess_mode="livesum"
)
RENDERS = Counter("pocketray_renders", "Frames rendered", ["method", "mode"])
STAGE_SECONDS = Histogram(
    "pocketray_render_stage_seconds",
    "Time of each stage of a frame (Server-Timing)",
    ["method", "mode", "stage"],
    buckets=STAGE_BUCKETS_S,
)
UNAVAILABLE = Counter("pocketray_unavailable", "503 answers by cause", ["cause"])
HTTP_REQUESTS = Counter("pocketray_http_requests", "HTTP requests answered", ["method", "route", "status"])
HTTP_SECONDS = Histogram(
    "pocketray_http_request_duration_seconds", "HTTP request duration", ["method", "route"], buckets=HTTP_BUCKETS_S
)

ACCUMULATION_BYTES = Gauge(
    "pocketray_accumulation_bytes", "Bytes the sessions' accumulations hold", multiprocess_mode="livesum"
)
ACCUMULATION_DROP_REASONS = ("change", "budget", "deleted")
ACCUMULATIONS_DROPPED = Counter("pocketray_accumulations_dropped", "Accumulations dropped, by reason", ["reason"])
for _reason in ACCUMULATION_DROP_REASONS:  # every series from the start: a scrape shows the zeros
    ACCUMULATIONS_DROPPED.labels(_reason)
# The methods the API answers (server/http/allow.py's and OPTIONS); any other method is one label value.
HTTP_METHODS = frozenset(("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"))
OTHER = "other"
STAGES = frozenset(TIMING_NAMES)
RENDER_METHODS, RENDER_MODES = frozenset(METHOD_NAMES), frozenset(MODES)
_MAX_ROUTE_LABEL = 128


def method_label(method: str) -> str:
    """The HTTP method as a label: one of HTTP_METHODS, else ``other``."""
    return method if method in HTTP_METHODS else OTHER


def route_label(route: str) -> str:
    """A route template as a label (they come from the app's routes; a long one is not one of them)."""
    return route if isinstance(route, str) and 0 < len(route) <= _MAX_ROUTE_LABEL else OTHER


def status_label(status: int) -> str:
    """The status code as a label: a valid code (100 … 599), else ``other``."""
    return str(status) if isinstance(status, int) and 100 <= status <= 599 else OTHER


METRIC_NAMES = (
    "pocketray_renders_admitted",
    "pocketray_renders_waiting",
    "pocketray_renders_total",
    "pocketray_render_stage_seconds",
    "pocketray_unavailable_total",
    "pocketray_http_requests_total",
    "pocketray_http_request_duration_seconds",
    "pocketray_accumulation_bytes",
    "pocketray_accumulations_dropped_total",
    "pocketray_sessions",
    "pocketray_store_bytes",
    "pocketray_ready",
)


def _safe(fn):
    def wrapped(*args: Any, **kwargs: Any) -> None:
        try:
            fn(*args, **kwargs)
        except Exception:  # pragma: no cover - a metric must never fail a request
            log.exception("metrics hook %s failed", fn.__name__)

    wrapped.__name__ = fn.__name__
    wrapped.__doc__ = fn.__doc__
    return wrapped


# ---- hooks --------------------------------------------------------------------------------
@_safe
def render_admitted() -> None:
    """A render took a slot of the GL queue (server.frames.trace)."""
    RENDERS_ADMITTED.inc()
    RENDERS_WAITING.inc()


@_safe
def render_started() -> None:
    """An admitted job began on the GL thread."""
    RENDERS_WAITING.dec()


@_safe
def render_released(never_ran: bool = False) -> None:
    """A slot was freed; ``never_ran``: its job was never submitted (it still counted as waiting)."""
    RENDERS_ADMITTED.dec()
    if never_ran:
        RENDERS_WAITING.dec()


@_safe
def observe_stages(method: str, mode: str, timings_ms: dict[str, float]) -> None:
    """One rendered frame: its stages' times in ms (the Server-Timing names)."""
    method = method if method in RENDER_METHODS else OTHER
    mode = mode if mode in RENDER_MODES else OTHER
    RENDERS.labels(method, mode).inc()
    for stage, ms in timings_ms.items():
        if stage in STAGES:
            STAGE_SECONDS.labels(method, mode, stage).observe(max(0.0, float(ms)) / 1e3)


@_safe
def accumulation_bytes(nbytes: int) -> None:
    """What this process's accumulations hold now (server.frames.accumulate)."""
    ACCUMULATION_BYTES.set(nbytes)


@_safe
def accumulation_dropped(reason: str) -> None:
    """An accumulation dropped: ``change``, ``budget`` or ``deleted``."""
    ACCUMULATIONS_DROPPED.labels(reason if reason in ACCUMULATION_DROP_REASONS else OTHER).inc()


@_safe
def unavailable(cause: str) -> None:
    """A 503 answer, by cause."""
    UNAVAILABLE.labels(cause).inc()


@_safe
def http_request(method: str, route: str, status: int, seconds: float) -> None:
    """One answered request; its labels from closed sets (see the module's docstring)."""
    method, route = method_label(method), route_label(route)
    HTTP_REQUESTS.labels(method, route, status_label(status)).inc()
    HTTP_SECONDS.labels(method, route).observe(seconds)


# ---- the scrape -------------------------------------------------------------------------------
class _ProcessCollector:
    """What is read at scrape time: the store's session count (cached) and this process's readiness."""

    def __init__(self, app_state: Any):
        self.state = app_state

    def collect(self) -> Iterable[GaugeMetricFamily]:
        counted = _session_count(self.state)
        if counted is not None:
            sessions, used = counted
            yield GaugeMetricFamily("pocketray_sessions", "Sessions in the store (not expired)", value=sessions)
            if used is not None:
                yield GaugeMetricFamily(
                    "pocketray_store_bytes",
                    "Bytes of the stored scenes, as the store's quota (POCKETRAY_MAX_STORE_BYTES) counts them",
                    value=used,
                )
        ready = getattr(self.state, "is_ready", None)
        yield GaugeMetricFamily(
            "pocketray_ready",
            "1 when /api/ready answers 200 in this process",
            value=1.0 if (ready() if callable(ready) else False) else 0.0,
        )


_count_lock = threading.Lock()


def _session_count(state: Any) -> tuple[int, int | None] | None:
    """(sessions, bytes the quota counts, if the store says), cached SESSIONS_CACHE_S."""
    store = getattr(state, "store", None)
    if store is None or not hasattr(store, "count"):
        return None
    with _count_lock:
        cached = getattr(state, "_metrics_sessions", None)
        now = time.monotonic()
        if cached is not None and now - cached[0] < SESSIONS_CACHE_S:
            return cached[1]
        try:
            n = int(store.count())
            used = int(store.used_bytes()) if hasattr(store, "used_bytes") else None
        except Exception as e:  # the store is down: say nothing rather than a wrong number
            log.warning("metrics: cannot count sessions: %s", e)
            return None
        state._metrics_sessions = (now, (n, used))
        return n, used


def exposition(app_state: Any) -> bytes:
    """The text exposition of every metric: the workers' sum in multiprocess mode, else this process's."""
    if os.environ.get(MULTIPROC_ENV):
        from prometheus_client import multiprocess

        registry = CollectorRegistry()
        multiprocess.MultiProcessCollector(registry)
        body = generate_latest(registry)
    else:
        body = generate_latest(REGISTRY)
    local = CollectorRegistry()
    local.register(_ProcessCollector(app_state))
    return body + generate_latest(local)


def process_exit() -> None:
    """Forget this process's live gauges (multiprocess mode; called at shutdown)."""
    if os.environ.get(MULTIPROC_ENV):
        try:
            from prometheus_client import multiprocess

            multiprocess.mark_process_dead(os.getpid())
        except Exception:  # pragma: no cover
            pass
