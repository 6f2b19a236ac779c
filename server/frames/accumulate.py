"""Accumulations: a session's colour samples, added up across frame requests — the path integrator's
paths, or Whitted's jittered slices of its sub-pixel grid (:func:`renderer.gl.frame.plan_whitted_slices`).

A frame asked with ``accumulate`` (docs/API.md, "Accumulation") goes on from the samples its
session's accumulation holds — their float32 sum (image rows, H × W × 3) and count — when nothing
that changes the image changed since: its :class:`AccumulationKey` (scene revision, camera, every
setting the radiance depends on, the time, the size) is the one held. The GL thread adds the frame's
samples (sample indices go on from the count, so k frames are one frame of all their samples,
:func:`renderer.gl.frame.plan_path_passes`) and the request commits the new sum here once the frame
is done: a failed, cancelled or timed-out frame commits nothing.

Each commit also estimates the mean's noise (:func:`relative_noise`): the samples held before and
the frame's own are two independent estimates of every pixel, so their difference measures the
variance without keeping anything more — a refinement stream may stop at a noise level
(:mod:`server.sessions.refine`).

A session holds at most one accumulation: a frame of another key drops the old one (``change``).
Together they hold at most POCKETRAY_MAX_ACCUMULATION_BYTES; past it the least recently used go
first (``budget``). Both drops, and the bytes held, are metrics (docs/API.md, "Metrics").
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from renderer.config.settings import RenderSettings
from renderer.integrators import Integrator
from renderer.limits import MAX_ACCUMULATED_SAMPLES

from ..http import metrics

# Settings that do not change the radiance a frame adds: how many samples (the increment itself),
# the body's encoding, and the tone mapping and denoising applied to the mean when it is encoded.
NOT_IMAGE_SETTINGS = frozenset(("samples_per_pixel", "format", "tone_map", "exposure", "denoise"))


@dataclass(frozen=True)
class AccumulationKey:
    """What an accumulation's samples depend on; any change starts it over."""

    scene_rev: str
    camera: str  # the camera's JSON
    settings: tuple[tuple[str, Any], ...]  # every image-changing setting (time, width and height among them)


def accumulation_key(scene_rev: str, camera_json: str, settings: RenderSettings) -> AccumulationKey:
    """The key of a frame of ``settings`` through ``camera_json`` of the scene revision ``scene_rev``
    (a Whitted frame's ``samples_per_pixel`` is its sub-pixel grid, whose slices the count numbers:
    part of the key)."""
    skip = NOT_IMAGE_SETTINGS if settings.integrator == Integrator.PATH else NOT_IMAGE_SETTINGS - {"samples_per_pixel"}
    fields = tuple((k, getattr(settings, k)) for k in sorted(RenderSettings.names()) if k not in skip)
    return AccumulationKey(scene_rev, camera_json, fields)


def relative_noise(held_sum: np.ndarray, held: int, new_sum: np.ndarray, count: int) -> float | None:
    """The relative RMS error of the mean of ``count`` samples (sum ``new_sum``), estimated from the
    ``held`` samples it went on from (sum ``held_sum``) and the frame's own: two means of n_a and n_b
    independent samples differ by a variance σ²(1/n_a + 1/n_b), the mean of all has σ²/(n_a + n_b),
    so its variance is (m_a − m_b)² n_a n_b / (n_a + n_b)² — averaged over pixels and channels, its
    root over the image's mean. None without two parts (or for a black image)."""
    n_a, n_b = held, count - held
    if n_a <= 0 or n_b <= 0:
        return None
    m_a = held_sum / n_a
    m_b = (new_sum - held_sum) / n_b
    variance = float(np.mean(np.square(m_a - m_b, dtype=np.float64))) * n_a * n_b / (n_a + n_b) ** 2
    level = float(np.mean(new_sum, dtype=np.float64)) / count
    return float(np.sqrt(variance) / level) if level > 0 else None


@dataclass
class Held:
    """One session's accumulation: its key, the float32 sum of its samples and their count, and
    the estimate of its mean's relative noise at its last commit (None: not yet known)."""

    key: AccumulationKey
    sum: np.ndarray
    count: int
    noise: float | None = None

    @property
    def nbytes(self) -> int:
        return int(self.sum.nbytes)


class Accumulations:
    """The accumulations of one process's sessions, bounded in bytes (least recently used dropped first)."""

    def __init__(self, max_bytes: int):
        self.max_bytes = int(max_bytes)
        self._held: OrderedDict[str, Held] = OrderedDict()
        self._lock = threading.Lock()
        self.bytes = 0

    def start(self, session: str, key: AccumulationKey) -> tuple[np.ndarray | None, int]:
        """What a frame of ``session`` with ``key`` goes on from: (sum, count), or (None, 0) when the
        session holds nothing of that key (one of another key is dropped now: the image changed)."""
        with self._lock:
            held = self._held.get(session)
            if held is None:
                return None, 0
            if held.key != key:
                self._drop(session, "change")
                return None, 0
            self._held.move_to_end(session)
            return held.sum, held.count

    def commit(self, session: str, key: AccumulationKey, base_count: int, new_sum: np.ndarray, count: int) -> bool:
        """Keep ``new_sum`` of ``count`` samples, made from what the session held at ``base_count``;
        False (nothing kept) when the accumulation moved meanwhile (another frame committed first,
        or it was dropped), at MAX_ACCUMULATED_SAMPLES, or when it alone is over the budget."""
        nbytes = int(new_sum.nbytes)
        with self._lock:
            held = self._held.get(session)
            now = 0 if held is None or held.key != key else held.count
            if now != base_count or count > MAX_ACCUMULATED_SAMPLES or nbytes > self.max_bytes:
                return False
            noise = None
            if held is not None:
                noise = relative_noise(held.sum, held.count, new_sum, int(count))
                self._drop(session, None)
            while self._held and self.bytes + nbytes > self.max_bytes:
                self._drop(next(iter(self._held)), "budget")
            self._held[session] = Held(key, new_sum, int(count), noise)
            self.bytes += nbytes
            metrics.accumulation_bytes(self.bytes)
            return True

    def drop_session(self, session: str) -> None:
        """Forget the session's accumulation (the session is deleted)."""
        with self._lock:
            if session in self._held:
                self._drop(session, "deleted")

    def count(self, session: str) -> int:
        """Samples the session's accumulation holds (0: none)."""
        with self._lock:
            held = self._held.get(session)
            return 0 if held is None else held.count

    def noise(self, session: str) -> float | None:
        """The relative noise estimated at the session's last commit (None: none held, or not known)."""
        with self._lock:
            held = self._held.get(session)
            return None if held is None else held.noise

    def __len__(self) -> int:
        return len(self._held)

    def _drop(self, session: str, reason: str | None) -> None:
        """(lock held) ``reason`` None: replaced by its own next sum, not a drop."""
        held = self._held.pop(session)
        self.bytes -= held.nbytes
        metrics.accumulation_bytes(self.bytes)
        if reason is not None:
            metrics.accumulation_dropped(reason)
