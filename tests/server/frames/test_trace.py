"""The GL thread as a scheduler of slices: fair between sessions, cancellable,
truthful about the work queued ahead. Fake frames (no GL) make the order of slices exact."""

from __future__ import annotations

import math
import threading
import time

import pytest
from pocketray_server_support import SMALL, new_session

from renderer.config.settings import RenderSettings
from server.frames.pipeline import render_settings
from server.frames.trace import FrameCancelled, GLWorker
from server.sessions.service import owner


class FakeRenderer:
    info = {"renderer": "fake", "version": "0"}


class FakeFrame:
    """``slices`` steps; each one appends (name, i) to ``log`` and may wait on ``gate``."""

    def __init__(self, name: str, slices: int, log: list, gate: threading.Event | None = None, preview_at=None):
        self.name, self.n, self.log, self.gate, self.preview_at = name, slices, log, gate, preview_at
        self.i = 0
        self.released = False
        self.preview = None

    @property
    def pixels_total(self) -> int:
        return self.n

    @property
    def pixels_left(self) -> int:
        return self.n - self.i

    @property
    def done(self) -> bool:
        return self.i >= self.n

    def step(self) -> bool:
        if self.gate is not None:
            self.gate.wait(5)
        self.log.append((self.name, self.i))
        self.i += 1
        if self.preview_at is not None and self.i == self.preview_at:
            self.preview = f"{self.name} preview"
        return self.done

    def result(self):
        return f"{self.name} done"

    def release(self) -> None:
        self.released = True


@pytest.fixture
def worker():
    w = GLWorker(queue_size=8, renderer_factory=FakeRenderer, render_timeout_s=10.0)
    w.start().result(5)
    yield w
    w.close()


def test_sessions_take_turns_slice_by_slice(worker):
    """A small frame of one session is answered within a few slices while another
    session's long frame runs, and frames of one session keep their order."""
    log: list = []
    gate = threading.Event()
    long = worker.admit().frame(lambda r: FakeFrame("long", 50, log, gate), session="A", cost_ms=5000)
    time.sleep(0.05)  # the long frame is started and waits at its first slice
    short = worker.admit().frame(lambda r: FakeFrame("short", 3, log), session="B", cost_ms=30)
    gate.set()
    assert short.wait(5) == "short done"
    assert long.wait(5) == "long done"
    # The short frame's three slices came before the long one's fifth.
    last_short = max(i for i, (name, _) in enumerate(log) if name == "short")
    assert [name for name, _ in log[: last_short + 1]].count("long") <= 4
    assert [i for name, i in log if name == "long"] == list(range(50))


def test_in_flight_names_only_the_sessions_own_frames(worker):
    gate = threading.Event()
    blocker = worker.admit().submit(lambda r: gate.wait(5))  # the frames below wait to start
    a = worker.admit().frame(lambda r: FakeFrame("a", 1, []), session="A", cost_ms=1)
    b = worker.admit().frame(lambda r: FakeFrame("b", 1, []), session="B", cost_ms=1)
    assert worker.in_flight("A") == [a] and worker.in_flight("B") == [b] and worker.in_flight("C") == []
    gate.set()
    blocker.result(5)
    assert a.wait(5) == "a done" and b.wait(5) == "b done"


def test_a_cancelled_frame_stops_between_slices_and_frees_its_slot_at_once(worker):
    log: list = []
    gate = threading.Event()
    frames: list[FakeFrame] = []

    def start(r):
        frames.append(FakeFrame("f", 1000, log, gate))
        return frames[-1]

    h = worker.admit().frame(start, session="A", cost_ms=1e5)
    time.sleep(0.05)
    assert worker.admitted == 1
    h.cancel("disconnected")
    assert worker.admitted == 0  # the slot is free before the GL thread even looks
    gate.set()
    with pytest.raises(FrameCancelled) as e:
        h.wait(5)
    assert e.value.reason == "disconnected"
    assert frames[0].released and frames[0].i < 1000


def test_a_timeout_cancels_the_frame(worker):
    gate = threading.Event()
    # The first slice ends 1 s in, well after the 0.2 s timeout, and the GL thread drops the cancelled
    # frame there (without the timer that slice would wait out its gate's 5 s).
    threading.Timer(1.0, gate.set).start()
    h = worker.admit().frame(lambda r: FakeFrame("slow", 10**6, [], gate), session="A", cost_ms=1e6)
    with pytest.raises(FrameCancelled) as e:
        h.wait(0.2)
    gate.set()
    assert e.value.reason == "timeout" and worker.admitted == 0


def test_retry_after_and_saturation_come_from_the_work_queued_ahead(worker):
    gate = threading.Event()
    handles = [
        worker.admit().frame(lambda r: FakeFrame("x", 100, [], gate), session=s, cost_ms=ms)
        for s, ms in (("A", 4_000.0), ("B", 7_500.0))
    ]
    time.sleep(0.1)
    queued = worker.queued_ms()
    assert 11_000 <= queued <= 11_500  # what is left of both (one slice of one may have run)
    assert worker.retry_after() == math.ceil(queued / 1e3)
    assert worker.saturated is True  # 11.5 s of work, over the 10 s render timeout
    for h in handles:
        h.cancel("test")
    gate.set()
    time.sleep(0.1)
    assert worker.queued_ms() == 0 and not worker.saturated


def test_the_preview_is_handed_over_before_the_frame_is_done(worker):
    gate = threading.Event()
    h = worker.admit().frame(lambda r: FakeFrame("p", 20, [], None, preview_at=2), session="A", cost_ms=1)
    assert h.wait_preview(5) == "p preview"
    assert h.wait(5) == "p done"
    del gate


def test_shutdown_cancels_the_frames_in_flight():
    w = GLWorker(queue_size=4, renderer_factory=FakeRenderer)
    w.start().result(5)
    gate = threading.Event()
    h = w.admit().frame(lambda r: FakeFrame("s", 10**6, [], gate), session="A", cost_ms=1e6)
    time.sleep(0.05)
    closer = threading.Thread(target=w.close)
    closer.start()
    gate.set()
    closer.join(10)
    with pytest.raises(FrameCancelled) as e:
        h.wait(1)
    assert e.value.reason == "shutdown" and not closer.is_alive()


# ---- through the service -------------------------------------------------------------------
FRAME = {"width": 96, "height": 128, "max_recursion_depth": 2}


def estimate_ms(n: int, **settings) -> float:
    from renderer.config.settings import RenderSettings
    from renderer.frame.prepare import prepare_frame
    from renderer.scenes.scenarios import scenario

    return prepare_frame(scenario(3, n, seed=1), RenderSettings(**{**SMALL, **FRAME, **settings})).cost.bound_ms


@pytest.fixture(scope="module")
def capped(tmp_path_factory):
    """A service whose frame cost cap lies between the BIH's frame and brute force's on 4,096
    spheres (from the model itself, so the test holds whatever the fitted constants)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    from pocketray_server_support import make_config

    from server.app import create_app

    bih, bf = estimate_ms(4096), estimate_ms(4096, method="bruteforce")
    assert bf > 4 * bih
    limit = math.sqrt(bih * bf)
    with TestClient(create_app(make_config(tmp_path_factory.mktemp("capped"), max_frame_cost=limit))) as c:
        c.get("/api/ready")
        yield c


def test_a_frame_over_the_cost_cap_is_refused_naming_the_setting_to_change(capped):
    c = capped
    limit = c.app.state.config.max_frame_cost
    # the session's own frames are FRAME's (the cap lies between the BIH and brute force at that size)
    sid = new_session(c, n=4096, settings={**SMALL, **FRAME})["id"]
    assert c.get(f"/api/sessions/{sid}/frame", params=FRAME).status_code == 200  # the BIH fits
    for params, field in (
        ({"method": "bruteforce"}, "method"),
        ({"max_prims": 4096}, "max_prims"),
        ({"max_tree_depth": 1}, "max_tree_depth"),
    ):
        r = c.get(f"/api/sessions/{sid}/frame", params={**FRAME, **params})
        assert r.status_code == 422, r.text
        d = r.json()["detail"][0]
        assert d["loc"] == ["query", field], d
        assert "POCKETRAY_MAX_FRAME_COST" in d["msg"] and f"{limit:,.0f}" in d["msg"]
    # PATCH refuses what no frame could render, and changes nothing.
    before = c.get(f"/api/sessions/{sid}").json()
    r = c.patch(f"/api/sessions/{sid}/settings", json={"max_prims": 4096})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "max_prims"], r.text
    assert c.get(f"/api/sessions/{sid}").json() == before


def test_the_largest_accepted_width_named_is_accepted(capped):
    """A frame too big for its size: the 422 names width and the largest accepted value, which passes."""
    c = capped
    sid = new_session(c, n=4096)["id"]
    big = {**FRAME, "width": 4096, "height": 128, "max_recursion_depth": 2}
    c.app.state.config.__dict__["max_work"] = 10**9  # only the cost cap decides here
    r = c.get(f"/api/sessions/{sid}/frame", params=big)
    assert r.status_code == 422, r.text
    d = r.json()["detail"][0]
    assert d["loc"] == ["query", "width"], d
    width = int(d["msg"].split("width: at most ")[1].split()[0])
    assert 96 <= width < 4096
    assert c.get(f"/api/sessions/{sid}/frame", params={**big, "width": width}).status_code == 200
    assert c.get(f"/api/sessions/{sid}/frame", params={**big, "width": width + 64}).status_code == 422


def test_latest_wins_for_the_frames_of_one_session(ready_client):
    c = ready_client
    service, frames, worker = c.app.state.service, c.app.state.frames, c.app.state.worker
    sid = new_session(c)["id"]
    state = service.get(sid)
    gate = threading.Event()
    blocker = worker.admit().submit(lambda r: gate.wait(5))  # the GL thread is busy
    older = frames.start_frame(frames.plan(service.scene(state), render_settings(state.settings)), owner=owner(state))
    newer: list = []
    t = threading.Thread(target=lambda: newer.append(c.get(f"/api/sessions/{sid}/frame")))
    t.start()
    deadline = time.monotonic() + 5
    while older.reason is None and time.monotonic() < deadline:  # the newer request supersedes it
        time.sleep(0.01)
    gate.set()
    t.join(10)
    blocker.result(5)
    assert newer and newer[0].status_code == 200
    with pytest.raises(FrameCancelled) as e:
        older.wait(5)
    assert e.value.reason == "superseded"
    assert worker.admitted == 0


def test_a_gesture_whose_frame_times_out_changes_nothing(ready_client, monkeypatch):
    c = ready_client
    service = c.app.state.service
    sid = new_session(c)["id"]
    before = c.get(f"/api/sessions/{sid}").json()
    monkeypatch.setattr(service.config, "__dict__", {**service.config.__dict__, "render_timeout_s": 0.0})
    r = c.post(f"/api/sessions/{sid}/gesture?frame=1", json={"type": "pinch", "scale": 2})
    assert r.status_code == 503 and "nothing was changed" in r.json()["detail"], r.text
    assert int(r.headers["retry-after"]) >= 1
    assert c.get(f"/api/sessions/{sid}").json() == before


def test_progressive_frames_stream_the_preview_then_the_final_image(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    q = {"samples_per_pixel": 4, "format": "png"}
    r = c.get(f"/api/sessions/{sid}/frame", params={**q, "progressive": 1})
    assert r.status_code == 200 and r.headers["content-type"].startswith("multipart/mixed"), r.text
    parts = split_multipart(r)
    assert [p["headers"]["x-frame-part"] for p in parts] == ["preview", "final"]
    final = c.get(f"/api/sessions/{sid}/frame", params=q)
    centre = c.get(f"/api/sessions/{sid}/frame", params={**q, "samples_per_pixel": 1})
    assert parts[1]["body"] == final.content  # the final part is the one-shot frame
    assert parts[0]["body"] == centre.content  # the preview is the pixel-centre frame
    # A frame with one pass has one part.
    one = split_multipart(c.get(f"/api/sessions/{sid}/frame", params={"samples_per_pixel": 1, "progressive": 1}))
    assert [p["headers"]["x-frame-part"] for p in one] == ["final"]


def test_a_progressive_gesture_commits_with_its_final_part(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    v = c.get(f"/api/sessions/{sid}").json()["version"]
    r = c.post(
        f"/api/sessions/{sid}/gesture?frame=1&progressive=1&samples_per_pixel=4", json={"type": "pinch", "scale": 2}
    )
    parts = split_multipart(r)
    assert [p["headers"].get("x-session-version") for p in parts] == [str(v), str(v + 1)]
    assert c.get(f"/api/sessions/{sid}").json()["version"] == v + 1


def split_multipart(r) -> list[dict]:
    boundary = r.headers["content-type"].split("boundary=")[1].encode()
    out = []
    for chunk in r.content.split(b"--" + boundary)[1:]:
        if chunk.startswith(b"--"):
            break
        head, _, body = chunk.lstrip(b"\r\n").partition(b"\r\n\r\n")
        headers = {
            k.strip().lower(): v.strip()
            for k, v in (line.split(":", 1) for line in head.decode().split("\r\n") if line)
        }
        out.append({"headers": headers, "body": body[: int(headers["content-length"])]})
    return out


def test_a_traced_frame_keeps_no_target_or_read_back_once_its_result_is_made(gl_renderer):
    from renderer.scenes.scenarios import scenario

    settings = RenderSettings(**{**SMALL, "mode": "normal", "format": "npy"})
    frame = gl_renderer.begin(scenario(3, 64), settings)
    frame.run()
    assert frame.fbo is None
    assert frame._centre is None and not frame._subs  # was: the read-back, as large again as the result
    assert frame.result().normal.shape == (SMALL["height"], SMALL["width"], 3)


def test_a_background_frame_yields_every_slice_to_interactive_ones(worker):
    """An accumulation's frame (background) gets no slice while an interactive frame of any
    session waits: once one arrives, the background frame takes at most the slice running."""
    log: list = []
    gate = threading.Event()
    bg = worker.admit().frame(lambda r: FakeFrame("bg", 20, log, gate), session="A", cost_ms=2000, background=True)
    time.sleep(0.05)  # the background frame is started and waits at its first slice
    fg = worker.admit().frame(lambda r: FakeFrame("fg", 5, log), session="B", cost_ms=50)
    time.sleep(0.05)
    gate.set()
    assert fg.wait(5) == "fg done" and bg.wait(5) == "bg done"
    names = [name for name, _ in log]
    assert names[:6] == ["bg", "fg", "fg", "fg", "fg", "fg"], names[:8]


@pytest.mark.gl
@pytest.mark.parametrize("how", ["raster", "tiles"])
def test_a_cancelled_frame_of_overlapping_quads_stops_within_a_slice(how):
    """A frame whose rasterised quads all cover the same pixels is drawn in chunks of about
    POCKETRAY_SLICE_MS, one a slice: cancelled (its client gone) after a few, its GL work stops at
    the end of the slice that runs — not after the whole band of its quads."""
    import dataclasses

    import numpy as np

    from renderer.frame import cost
    from renderer.frame.prepare import prepare_frame
    from renderer.scenes.scenarios import scenario

    base = scenario(1, 1)
    cam = base.camera
    dist = float(np.linalg.norm(np.subtract(cam.target, cam.position)))
    n, side = 2000, 128
    scene = dataclasses.replace(
        base,
        sphere_centers=np.tile(np.asarray(cam.target, dtype=np.float64), (n, 1)),
        sphere_radii=np.full(n, 0.9 * dist),
        sphere_materials=np.zeros(n, np.int32),
        planes=(),
    )
    frame = prepare_frame(scene, RenderSettings(width=side, height=side, mode="depth", first_hits=how))
    ns = cost.RASTER_NS_FRAGMENT if how == "raster" else cost.TILES_NS_PAIR / 256
    slice_ms = 20 * side * side * ns / 1e6  # twenty quads' fragments: a hundred slices for the frame
    w = GLWorker(queue_size=2, render_timeout_s=60.0)
    w.start().result(60)
    try:
        assert w.ready.is_set(), w.error
        with w.admit() as ticket:
            h = ticket.frame(lambda r: r.start(frame, slice_ms=slice_ms), session="s", cost_ms=frame.cost.ms)
        deadline = time.monotonic() + 60
        while w.slices < 3 and not h._done.is_set() and time.monotonic() < deadline:
            time.sleep(0.001)
        assert not h._done.is_set(), "the frame ended before it could be cancelled: one draw of all its quads"
        h.cancel("disconnected")
        at = w.slices
        assert h._done.wait(30)
        assert w.slices - at <= 1  # the slice that was running, and no other
        with pytest.raises(FrameCancelled):
            h.result()
        assert w.slices < 50  # the frame's hundred slices were not all drawn
    finally:
        w.close()
