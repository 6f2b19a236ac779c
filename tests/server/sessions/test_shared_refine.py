"""Shared refinement (server/sessions/shared_refine.py; docs/DEPLOY.md, "Shared refinement"): two
service instances on one Redis, each with its own GL context; the stream's process merges the ranges
the other traced into one image of all the samples, takes back a range whose claimant died, and
the helpers leave interactive frames first; with sqlite (the embedded default) nothing is shared."""

from __future__ import annotations

import io
import threading
import time
import uuid
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import make_config, new_session, wait_ready

from server.app import create_app
from server.sessions.refine import FIRST_SLICE
from server.sessions.shared_refine import Board, Range, split

SIDE = 16
RANGE = 4  # samples per range
TARGET = FIRST_SLICE + 8 * RANGE + 1  # the first frame, eight ranges, the owner's last sample
LEASE_S = 1.0
BIG, BIG_SAMPLES = 32, 256  # a range far longer than a 16 × 16 frame of one sample
PATH = {
    "integrator": "path",
    "width": SIDE,
    "height": SIDE,
    "format": "npy",
    "samples_per_pixel": 1,
    "max_recursion_depth": 4,
}


def test_ranges_cover_the_samples_once_in_order():
    ranges = split(5, 20, 4)
    assert [(r.start, r.count) for r in ranges] == [(5, 4), (9, 4), (13, 4), (17, 3)]
    r = Range("s:1:ab", 9, 4)
    assert Range.parse(r.entry.encode()) == r and r.end == 13


def config(tmp, redis_url, prefix, **kw):
    settings = dict(
        state_backend="redis",
        redis_url=redis_url,
        redis_prefix=prefix,
        max_work=SIDE * SIDE * 4 * 256,
        refine_slice_ms=0.001,  # the owner's frames of one sample: helpers have ranges to take
        max_refine_ms=60_000,
        shared_refine_range_samples=RANGE,
        shared_refine_lease_s=LEASE_S,
    )
    return make_config(tmp, **{**settings, **kw})


@pytest.fixture(scope="module")
def pair(tmp_path_factory, redis_url):
    """(owner, helper): two apps, two GL contexts, one Redis."""
    prefix = f"shared-{uuid.uuid4().hex[:8]}:"
    a = TestClient(create_app(config(tmp_path_factory.mktemp("a"), redis_url, prefix)))
    b = TestClient(create_app(config(tmp_path_factory.mktemp("b"), redis_url, prefix)))
    with a, b:
        wait_ready(a.get)
        wait_ready(b.get)
        yield a, b


def cornell(c: TestClient) -> str:
    return new_session(c, scenario=None, n=None, seed=None, radius=None, mesh_scene={"kind": "cornell", "detail": 0})[
        "id"
    ]


def refine_to(c: TestClient, sid: str, target: int) -> tuple[list[int], np.ndarray]:
    counts, image = [], None
    with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_json({"type": "refine", "target_samples": target, "target_ms": 60_000, "frame": PATH})
        while True:
            head = ws.receive_json()
            assert "refine" in head, head
            image = np.load(io.BytesIO(ws.receive_bytes()))
            counts.append(head["refine"]["samples"])
            if head["refine"]["done"]:
                assert head["refine"]["reason"] == "samples", head
                break
    assert image is not None
    return counts, image


def one_frame(c: TestClient, sid: str, samples: int) -> np.ndarray:
    r = c.get(f"/api/sessions/{sid}/frame", params={**PATH, "samples_per_pixel": samples})
    assert r.status_code == 200, r.text
    return np.load(io.BytesIO(r.content))


def assert_same_samples(merged: np.ndarray, one: np.ndarray) -> None:
    """Equal up to float32 rounding: a pixel's sum adds at most TARGET float32 parts (each within
    2⁻²⁴ of its exact value), so the means differ by far less than 1e-5 of their size."""
    bound = 1e-5 * np.maximum(np.abs(one), 1e-2)
    worst = float(np.max(np.abs(merged - one) - bound))
    assert worst <= 0, f"merged image off by {float(np.abs(merged - one).max()):.3g}"


@pytest.mark.gl
def test_the_merged_image_is_one_frame_of_all_its_samples(pair):
    a, b = pair
    sid = cornell(a)
    helper = b.app.state.service.shared_refine.helper
    before = helper.traced
    counts, merged = refine_to(a, sid, TARGET)
    assert counts[0] == FIRST_SLICE and counts[-1] == TARGET, counts
    assert all(x < y for x, y in zip(counts, counts[1:], strict=False)), counts
    assert helper.traced > before, "the other process traced ranges of the stream"
    assert any(y - x >= RANGE for x, y in zip(counts, counts[1:], strict=False)), (
        f"a helper's range merged between two of the owner's frames: {counts}"
    )
    assert_same_samples(merged, one_frame(a, sid, TARGET))
    board = a.app.state.service.shared_refine.board
    assert board.client.llen(board.queue) == 0 and board.client.zcard(board.leases) == 0, "the stream left nothing"


@pytest.mark.gl
def test_a_range_whose_claimant_died_is_traced_by_the_owner(pair, redis_url):
    a, b = pair
    sid = cornell(a)
    board = a.app.state.service.shared_refine.board
    # A process that claims every range it sees and dies before it finishes any (its lease runs out).
    dead = Board(board.client, board.prefix[: -len("refine:")], LEASE_S, 60)
    claimed: list[Range] = []
    stop = threading.Event()

    def die_holding() -> None:
        while not stop.is_set():
            r = dead.claim()
            if r is None:
                time.sleep(0.001)
            else:
                claimed.append(r)

    thief = threading.Thread(target=die_holding)
    b.app.state.service.shared_refine.helper.stop()  # (only the dead one claims: its ranges are lost)
    thief.start()
    try:
        counts, merged = refine_to(a, sid, TARGET)
    finally:
        stop.set()
        thief.join()
    assert claimed, "the dead process held ranges"
    assert counts[-1] == TARGET, counts
    assert_same_samples(merged, one_frame(a, sid, TARGET))


@pytest.mark.gl
def test_interactive_frames_go_before_a_helpers_range(tmp_path, redis_url):
    prefix = f"shared-{uuid.uuid4().hex[:8]}:"
    roomy = config(tmp_path, redis_url, prefix, max_work=BIG * BIG * BIG_SAMPLES * 8, max_frame_cost=1e6)
    with TestClient(create_app(roomy)) as c:
        wait_ready(c.get)
        service = c.app.state.service
        sid, other = cornell(c), cornell(c)
        shared = service.shared_refine
        shared.helper.stop()  # the test claims for it, one step at a time
        big = {**PATH, "width": BIG, "height": BIG}
        job = f"{sid}:1:test"
        state = service.get(sid)
        shared.board.publish(
            job, {"session": sid, "version": state.version, "patch": big}, [Range(job, 0, BIG_SAMPLES)]
        )
        tracing = threading.Thread(target=shared.helper.step)
        tracing.start()
        deadline = time.monotonic() + 60
        while service.frames.worker.admitted == 0 and time.monotonic() < deadline:
            time.sleep(0.005)
        assert service.frames.worker.admitted == 1, "the helper's range is in flight"
        assert not shared.helper.idle(), "a process with a frame admitted claims nothing more"
        r = c.get(f"/api/sessions/{other}/frame", params={**PATH, "samples_per_pixel": 1})
        assert r.status_code == 200, r.text
        assert tracing.is_alive(), "the interactive frame was served while the range was still being traced"
        tracing.join()
        assert shared.helper.traced == 1 and shared.board.result(Range(job, 0, BIG_SAMPLES)) is not None


def test_one_process_shares_nothing(tmp_path, redis_url):
    with TestClient(create_app(make_config(tmp_path))) as c:
        assert c.app.state.service.shared_refine is None, "sqlite: the embedded default refines alone"
    off = make_config(tmp_path, state_backend="redis", redis_url=redis_url, shared_refine=False)
    with TestClient(create_app(off)) as c:
        assert c.app.state.service.shared_refine is None


@pytest.mark.gl
def test_one_process_on_redis_traces_its_own_ranges(tmp_path, redis_url):
    with TestClient(create_app(config(tmp_path, redis_url, f"shared-{uuid.uuid4().hex[:8]}:"))) as c:
        wait_ready(c.get)
        sid = cornell(c)
        counts, merged = refine_to(c, sid, TARGET)
        assert counts[-1] == TARGET, counts
        assert c.app.state.service.shared_refine.helper.traced == 0, "a helper leaves its own process's streams"
        assert_same_samples(merged, one_frame(c, sid, TARGET))
