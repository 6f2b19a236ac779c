"""Shared refinement: the samples of a resting path-traced view traced by every render process whose
GL thread is idle, coordinated through the Redis the stack already shares (docs/DEPLOY.md, "Shared
refinement").

A path frame's pixel sample i is the same path whichever process traces it (its random numbers
depend on the pixel and i alone, :func:`renderer.gl.frame.plan_path_passes`), so disjoint ranges of
sample indices add up to one frame of them all. The process that runs a session's refinement stream
(:mod:`server.sessions.refine`, the *owner*) publishes the samples from what its accumulation holds
up to one short of the target as :class:`Range` s of POCKETRAY_SHARED_REFINE_RANGE_SAMPLES in one
Redis list. The owner traces the ranges from the bottom, as its ordinary accumulation frames; a
:class:`Helper` in every other process claims ranges from the top — only while its own GL thread has
nothing admitted, so interactive frames keep priority everywhere, and as background frames, so an
interactive frame that arrives meanwhile is sliced first — and writes the float32 sum of its range
back. The owner adds a helper's sum to its accumulation when its count reaches the range's start:
in the order of the ranges, whoever traced them, so the image is one process's image of the same
samples up to float32 rounding. While a helper holds the range at its count, the owner traces the
lowest range nobody claimed yet and keeps its sum for when its count gets there. The last sample
is always the owner's own frame, the stream's final image.

A claim is a lease of POCKETRAY_SHARED_REFINE_LEASE_S: a range whose helper died (or failed, or
gave it back) is traced by the owner when its count gets there, so a dead process costs its
unfinished range and no more. A change of the view ends the stream, which withdraws its ranges;
a helper drops a range whose stream is gone or whose session moved on (its version) without
tracing it. With the sqlite backend, or POCKETRAY_SHARED_REFINE false, nothing here runs.

Redis keys, under ``<POCKETRAY_REDIS_PREFIX>refine:``: ``queue`` (the unclaimed ranges, one list
for every stream), ``leases`` (claimed ranges → deadline, ms of Redis's clock), ``job:<id>`` (a
stream's session, version and frame query) and ``sum:<range>`` (a finished range's sum), the last
two expiring with the longest stream.
"""

from __future__ import annotations

import json
import logging
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from renderer.config.settings import SettingValues

from ..config import ServerConfig
from ..frames.accumulate import AccumulationKey, accumulation_key
from ..frames.pipeline import FramePipeline

if TYPE_CHECKING:
    from .service import SessionService

log = logging.getLogger("pocketray.shared_refine")

HELPER_POLL_S = 0.05  # an idle helper asks for a range this often (one Redis round trip)
OWNER_POLL_S = 0.02  # the owner waits for a range a helper holds in steps of this
CLAIM_DEPTH = 256  # a helper looks at this many of the newest ranges for one it may claim
SUM_DTYPE = np.float32  # a range's sum as an accumulation holds it (12 bytes a pixel)

# Claim the newest range (the top of the list: the owner works from the bottom) of a stream this
# process does not own (ARGV[3] …: their jobs; among the CLAIM_DEPTH newest), and lease it.
_CLAIM = """
local items = redis.call('LRANGE', KEYS[1], -tonumber(ARGV[2]), -1)
for i = #items, 1, -1 do
  local e = items[i]
  local job = string.match(e, '^(.*)|%d+|%d+$')
  local own = false
  for j = 3, #ARGV do
    if ARGV[j] == job then own = true break end
  end
  if not own then
    redis.call('LREM', KEYS[1], -1, e)
    local t = redis.call('TIME')
    redis.call('ZADD', KEYS[2], tonumber(t[1]) * 1000 + math.floor(tonumber(t[2]) / 1000) + tonumber(ARGV[1]), e)
    return e
  end
end
return false
"""
# The owner at a range's start: 2 its sum is there; 1 it is the owner's now (unclaimed, or its lease
# expired or was given back); 0 a helper holds it.
_TAKE = """
if redis.call('EXISTS', KEYS[3]) == 1 then return 2 end
if redis.call('LREM', KEYS[1], 1, ARGV[1]) == 1 then return 1 end
local d = redis.call('ZSCORE', KEYS[2], ARGV[1])
local t = redis.call('TIME')
if (not d) or tonumber(d) < tonumber(t[1]) * 1000 + math.floor(tonumber(t[2]) / 1000) then
  redis.call('ZREM', KEYS[2], ARGV[1])
  return 1
end
return 0
"""
# A helper's sum, kept only while its stream is (and its lease dropped either way).
_FINISH = """
redis.call('ZREM', KEYS[2], ARGV[1])
if redis.call('EXISTS', KEYS[1]) == 0 then return 0 end
redis.call('SET', KEYS[3], ARGV[2], 'PX', ARGV[3])
return 1
"""


@dataclass(frozen=True)
class Range:
    """Sample indices ``start`` … ``start + count − 1`` of the stream ``job``."""

    job: str
    start: int
    count: int

    @property
    def end(self) -> int:
        return self.start + self.count

    @property
    def entry(self) -> str:
        return f"{self.job}|{self.start}|{self.count}"

    @classmethod
    def parse(cls, entry: bytes | str) -> Range:
        text = entry.decode() if isinstance(entry, bytes) else entry
        job, start, count = text.rsplit("|", 2)
        return cls(job, int(start), int(count))


def split(start: int, end: int, size: int) -> list[Range]:
    """The ranges of ``size`` samples (the last one shorter) over ``start`` … ``end − 1`` (job unset)."""
    return [Range("", s, min(size, end - s)) for s in range(start, end, max(1, size))]


class Board:
    """The ranges in Redis, as every process sees them (``client``: a redis-py client)."""

    def __init__(self, client: Any, prefix: str, lease_s: float, ttl_s: float):
        self.client = client
        self.prefix = f"{prefix}refine:"
        self.queue, self.leases = f"{self.prefix}queue", f"{self.prefix}leases"
        self.lease_ms = max(1, int(lease_s * 1000))
        self.ttl_ms = max(1, int(ttl_s * 1000))
        self._claim = client.register_script(_CLAIM)
        self._take = client.register_script(_TAKE)
        self._finish = client.register_script(_FINISH)

    def job_key(self, job: str) -> str:
        return f"{self.prefix}job:{job}"

    def sum_key(self, r: Range) -> str:
        return f"{self.prefix}sum:{r.entry}"

    # ---- the owner -------------------------------------------------------------------------------
    def publish(self, job: str, meta: dict[str, Any], ranges: list[Range]) -> None:
        """The stream's ranges, bottom first (helpers take them from the top)."""
        pipe = self.client.pipeline(transaction=True)
        pipe.set(self.job_key(job), json.dumps(meta), px=self.ttl_ms)
        pipe.rpush(self.queue, *(r.entry for r in ranges))
        pipe.execute()

    def take(self, r: Range) -> int:
        """2: its sum is there; 1: the range is the owner's to trace; 0: a live helper holds it."""
        return int(self._take(keys=[self.queue, self.leases, self.sum_key(r)], args=[r.entry]))

    def result(self, r: Range) -> bytes | None:
        """A finished range's sum (and it is gone from Redis)."""
        pipe = self.client.pipeline(transaction=True)
        pipe.get(self.sum_key(r))
        pipe.delete(self.sum_key(r))
        got, _ = pipe.execute()
        return got

    def withdraw(self, job: str, ranges: list[Range]) -> None:
        """The stream ended: its ranges unclaimed, claimed or finished go (a helper tracing one drops it)."""
        pipe = self.client.pipeline(transaction=False)
        pipe.delete(self.job_key(job))
        for r in ranges:
            pipe.lrem(self.queue, 1, r.entry)
            pipe.zrem(self.leases, r.entry)
            pipe.delete(self.sum_key(r))
        pipe.execute()

    # ---- a helper --------------------------------------------------------------------------------
    def claim(self, own: frozenset[str] = frozenset()) -> Range | None:
        """The newest range of a stream not in ``own`` (the streams this process owns: their owner
        traces the ranges it does not wait for itself), leased; None when there is none."""
        got = self._claim(keys=[self.queue, self.leases], args=[self.lease_ms, CLAIM_DEPTH, *sorted(own)])
        return None if got is None else Range.parse(got)

    def meta(self, job: str) -> dict[str, Any] | None:
        got = self.client.get(self.job_key(job))
        return None if got is None else json.loads(got)

    def finish(self, r: Range, data: bytes) -> bool:
        """Hand the range's sum over; False when its stream is gone meanwhile (nothing kept)."""
        keys = [self.job_key(r.job), self.leases, self.sum_key(r)]
        return bool(self._finish(keys=keys, args=[r.entry, data, self.ttl_ms]))

    def give_back(self, r: Range) -> None:
        """A range this helper will not trace: its owner traces it when it gets there."""
        self.client.zrem(self.leases, r.entry)


def trace_range(
    pipeline: FramePipeline, service: SessionService, session_id: str, patch: SettingValues, r: Range
) -> bytes:
    """The float32 sum (image rows, H × W × 3) of the samples of ``r`` of the session's view, traced
    here as a background frame."""
    request = service.frame_request(session_id, {**patch, "samples_per_pixel": r.count})
    owner = request.owner
    assert owner is not None, "a session's frame"
    frame = pipeline.plan(request.scene, request.settings.render, key=(owner.id, owner.scene_rev))
    with pipeline.frame_memory(frame.settings, True):
        # owner=None: none of the session's frames here is superseded by it, nor supersedes it
        handle = pipeline.start_frame(frame, owner=None, accumulated=(None, r.start))
        result = pipeline.wait(handle, time.perf_counter())
    assert result.sample_sum is not None, "an accumulation frame hands its sum back"
    return np.ascontiguousarray(result.sample_sum, dtype=SUM_DTYPE).tobytes()


class OwnJobs:
    """The streams this process owns (their ranges are its stream threads' to trace, not its helper's)."""

    def __init__(self) -> None:
        self._jobs: set[str] = set()
        self._lock = threading.Lock()

    def add(self, job: str) -> None:
        with self._lock:
            self._jobs.add(job)

    def discard(self, job: str) -> None:
        with self._lock:
            self._jobs.discard(job)

    def snapshot(self) -> frozenset[str]:
        with self._lock:
            return frozenset(self._jobs)


class SharedStream:
    """The owner's side of one refinement stream: before each of its frames, :meth:`next_frame`
    adds the ranges helpers finished at its count and says how many samples its own frame may add."""

    def __init__(
        self,
        board: Board,
        service: SessionService,
        session_id: str,
        patch: SettingValues,
        version: int,
        goal: int,
        range_samples: int,
        still: Callable[[], bool],
        own: OwnJobs | None = None,
    ):
        self.board, self.service, self.session_id, self.patch = board, service, session_id, patch
        self.own = own if own is not None else OwnJobs()
        self.version, self.goal, self.range_samples, self.still = version, goal, range_samples, still
        self.job = f"{session_id}:{version}:{uuid.uuid4().hex[:12]}"
        self.ranges: list[Range] = []  # every range published (to withdraw at the end)
        self.pending: deque[Range] = deque()  # those the count has not passed yet, bottom first
        self.mine: Range | None = None  # the range the owner's frames trace now
        self.published = False
        self.calls = 0
        self.merged = 0  # ranges added from helpers
        self.spare: dict[int, bytes] = {}  # sums of later ranges the owner traced while it waited, by start
        self.key: AccumulationKey | None = None
        self.shape: tuple[int, int, int] | None = None

    def _publish(self, held: int) -> None:
        self.published = True
        end = self.goal - 1  # the last sample is the owner's: its frame is the stream's final image
        if end - held < self.range_samples:
            return  # less than one range to share
        request = self.service.frame_request(self.session_id, {**self.patch, "samples_per_pixel": 1})
        owner, render = request.owner, request.settings.render
        assert owner is not None, "a session's frame"
        posed, _ = FramePipeline.posed(request.scene, render.time)
        self.key = accumulation_key(owner.scene_rev, json.dumps(posed.camera.to_json(), sort_keys=True), render)
        self.shape = (render.height, render.width, 3)
        self.ranges = [Range(self.job, r.start, r.count) for r in split(held, end, self.range_samples)]
        self.pending = deque(self.ranges)
        meta = {"session": self.session_id, "version": self.version, "patch": self.patch}
        self.own.add(self.job)
        self.board.publish(self.job, meta, self.ranges)

    def next_frame(self, held: int, k: int) -> tuple[int, int] | None:
        """(samples held, samples the owner's next frame adds) after the ranges finished at ``held``
        are added; None: the stream is to end (cancelled, or the view changed while waiting). When
        Redis fails here the stream goes on alone."""
        try:
            return self._next_frame(held, k)
        except Exception:
            log.warning("shared refinement: %s goes on alone", self.job, exc_info=True)
            self.pending.clear()
            self.mine = None
            count = self.service.frames.accumulations.count(self.session_id)
            return count, max(1, min(k, self.goal - count))

    def _next_frame(self, held: int, k: int) -> tuple[int, int] | None:
        # Published after the stream's first frame: that frame comes at once, and its count is of this view
        # (the count before it may be of the view before).
        self.calls += 1
        if not self.published and self.calls > 1 and held > 0:
            self._publish(held)
        while True:
            if self.mine is not None and held < self.mine.end:
                return held, max(1, min(k, self.mine.end - held))
            self.mine = None
            if not self.pending:
                return held, max(1, min(k, self.goal - held))
            r = self.pending[0]
            if r.start != held:  # the accumulation moved under the stream (dropped for its budget)
                self._stop_sharing()
                continue
            data = self.spare.pop(r.start, None)
            if data is not None:
                state = 2
            else:
                state = self.board.take(r)
            if state == 2:
                data = data if data is not None else self.board.result(r)
                if data is not None and self._merge(r, data):
                    self.pending.popleft()
                    self.merged += 1
                    held = r.end
                    continue
                state = 1  # (gone or not added: the owner traces it)
            if state == 1:
                self.mine = self.pending.popleft()
                continue
            if not self.still():
                return None
            if not self._trace_spare():
                time.sleep(OWNER_POLL_S)

    def _trace_spare(self) -> bool:
        """While a helper holds the range at the count: trace the lowest later range nobody has
        claimed, here, to add when the count gets there (False: there is none)."""
        for r in list(self.pending)[1:]:
            if r.start in self.spare:
                continue
            if self.board.take(r) == 1:
                self.spare[r.start] = trace_range(self.service.frames, self.service, self.session_id, self.patch, r)
                return True
        return False

    def _merge(self, r: Range, data: bytes) -> bool:
        assert self.key is not None and self.shape is not None, "published"
        part = np.frombuffer(data, SUM_DTYPE)
        if part.size != int(np.prod(self.shape)):
            return False
        accumulations = self.service.frames.accumulations
        held_sum, count = accumulations.start(self.session_id, self.key)
        if held_sum is None or count != r.start:
            return False
        return accumulations.commit(self.session_id, self.key, r.start, held_sum + part.reshape(self.shape), r.end)

    def _stop_sharing(self) -> None:
        self.board.withdraw(self.job, self.ranges)
        self.pending.clear()
        self.mine = None

    def close(self) -> None:
        """The stream ended: what it published goes."""
        self.own.discard(self.job)
        if self.ranges:
            try:
                self.board.withdraw(self.job, self.ranges)
            except Exception:  # Redis away: the keys expire, helpers drop ranges without a job
                log.warning("shared refinement: could not withdraw %s", self.job, exc_info=True)


class Helper:
    """One process's helper: while its GL thread has nothing admitted, claim a range of any stream,
    trace it, and hand its sum back (a thread, :meth:`start` … :meth:`stop`)."""

    def __init__(self, board: Board, service: SessionService, own: OwnJobs | None = None):
        self.board, self.service = board, service
        self.own = own if own is not None else OwnJobs()
        self.worker = service.frames.worker
        self.traced = 0  # ranges handed back by this process
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._main, name="pocketray-refine-helper", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=30)

    def idle(self) -> bool:
        """No frame nor call of this process is admitted to its GL thread."""
        w = self.worker
        return w.ready.is_set() and not w.closing and w.admitted == 0

    def _main(self) -> None:
        while not self._stop.wait(HELPER_POLL_S):
            try:
                while self.idle() and not self._stop.is_set() and self.step():
                    pass
            except Exception:  # Redis away, a frame that failed: the owners trace those ranges
                log.warning("shared refinement: helper step failed", exc_info=True)

    def step(self) -> bool:
        """Claim and trace one range; False when none is waiting."""
        r = self.board.claim(self.own.snapshot())
        if r is None:
            return False
        try:
            meta = self.board.meta(r.job)
            if meta is None or self._moved(meta):
                self.board.give_back(r)
                return True
            data = trace_range(self.service.frames, self.service, meta["session"], meta["patch"], r)
        except BaseException:
            self.board.give_back(r)
            raise
        if self.board.finish(r, data):
            self.traced += 1
        return True

    def _moved(self, meta: dict[str, Any]) -> bool:
        from ..faults import NotFound

        try:
            return self.service.get(meta["session"]).version != meta["version"]
        except NotFound:
            return True


@dataclass
class SharedRefine:
    """What a process with shared refinement holds: the board and its helper."""

    board: Board
    helper: Helper
    range_samples: int

    def stream(
        self,
        service: SessionService,
        session_id: str,
        patch: SettingValues,
        version: int,
        goal: int,
        still: Callable[[], bool],
    ) -> SharedStream:
        own = self.helper.own
        return SharedStream(self.board, service, session_id, patch, version, goal, self.range_samples, still, own)

    def close(self) -> None:
        self.helper.stop()


def start_shared_refine(config: ServerConfig, store: Any, service: SessionService) -> SharedRefine | None:
    """The shared refinement of this process (its helper started), or None: the sqlite backend, or
    POCKETRAY_SHARED_REFINE false."""
    client = getattr(store, "client", None)
    if not config.shared_refine or config.state_backend != "redis" or client is None:
        return None
    ttl_s = config.max_refine_ms / 1e3 + 2 * config.shared_refine_lease_s
    board = Board(client, config.redis_prefix, config.shared_refine_lease_s, ttl_s)
    helper = Helper(board, service)
    helper.start()
    return SharedRefine(board, helper, config.shared_refine_range_samples)
