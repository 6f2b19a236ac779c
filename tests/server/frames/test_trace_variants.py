"""The rate of new shader variants (server.frames.trace.VariantRate): each program a frame's start
compiles is charged to its session; over the rate, the frame fails with VariantsLimited before
anything is compiled, and a variant the renderer holds costs nothing."""

from __future__ import annotations

import pytest

from renderer.gl.programs import ProgramCache
from server.frames.trace import GLWorker, VariantRate, VariantsLimited


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_a_session_has_its_burst_then_its_rate():
    clock = Clock()
    rate = VariantRate(per_min=6.0, burst=2, clock=clock)  # one every 10 s
    rate.charge("a")
    rate.charge("a")
    with pytest.raises(VariantsLimited) as e:
        rate.charge("a")
    assert e.value.retry_after_s == 10 and (e.value.per_min, e.value.burst) == (6.0, 2)
    rate.charge("b")  # another session has its own bucket
    clock.t = 4.0
    with pytest.raises(VariantsLimited) as e:  # a refusal takes nothing: still 6 s to go
        rate.charge("a")
    assert e.value.retry_after_s == 6
    clock.t = 10.0
    rate.charge("a")


def test_frames_without_a_session_share_one_bucket_and_zero_is_no_limit():
    rate = VariantRate(per_min=1.0, burst=1, clock=Clock())
    rate.charge(object())
    with pytest.raises(VariantsLimited):
        rate.charge(object())
    unlimited = VariantRate(per_min=0.0, burst=1)
    for _ in range(100):
        unlimited.charge("a")


def test_the_buckets_are_bounded_in_number():
    rate = VariantRate(per_min=1.0, burst=1, max_sessions=2, clock=Clock())
    for s in ("a", "b", "c"):
        rate.charge(s)
    rate.charge("a")  # forgotten: a full bucket again


class _Program:
    class _GL:
        def release(self) -> None:
            pass

    def __init__(self) -> None:
        self.mglo = self._GL()


class CachingRenderer:
    """A renderer with a program cache (no GL): a frame's start 'compiles' the variants it names."""

    info = {"renderer": "fake", "version": "0"}

    def __init__(self) -> None:
        self.programs = ProgramCache(8, trim=False)

    def start(self, *variants: str):
        for v in variants:
            self.programs.get(v, _Program)  # type: ignore[arg-type]
        return Done()


class Done:
    preview = None

    def step(self) -> bool:
        return True

    def result(self) -> str:
        return "done"

    def release(self) -> None:
        pass


@pytest.fixture
def worker():
    w = GLWorker(
        queue_size=4,
        renderer_factory=CachingRenderer,
        render_timeout_s=10.0,
        variant_rate=VariantRate(per_min=0.01, burst=2),
    )
    w.start().result(5)
    yield w
    w.close()


def frame(worker: GLWorker, session: str, *variants: str):
    return worker.admit().frame(lambda r: r.start(*variants), session=session, cost_ms=1).wait(5)


def test_the_worker_charges_each_compile_to_the_frames_session(worker):
    assert frame(worker, "A", "v1", "v2") == "done"
    assert frame(worker, "A", "v1", "v2") == "done"  # held: free
    with pytest.raises(VariantsLimited):
        frame(worker, "A", "v3")
    assert "v3" not in worker.renderer.programs  # refused before it was compiled
    assert frame(worker, "B", "v3") == "done"  # another session's bucket
    assert frame(worker, "A", "v3") == "done"  # … and now held: free for A too
    assert worker.admitted == 0  # every slot given back, the refused frame's too
