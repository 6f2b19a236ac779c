"""The frame pipeline (server/frames/pipeline.py): the memory of frames in flight (docs/API.md,
"Memory budget").

Rules out: eight concurrent 4096 × 4096 ``normal`` ``npy`` frames peaked at 5.49 GB resident, for a
budget of 3 GiB: every admitted frame held its render target at once (two RGBA32F attachments,
host memory on llvmpipe), then its read-back, its result's arrays and three copies of the npy
array. Frames reserve their estimated bytes in POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT, a
frame lets go of its target and read-back as soon as it can, and the npy body is the one copy
of the array. A frame whose estimate alone is over POCKETRAY_MAX_FRAME_BYTES is refused up front
(was: admitted when no other frame held bytes, so that it held more than the whole budget and
every other session's frame got 503 for its whole run). The tests use an 8 MiB budget and small
frames, not 4096² ones.
"""

from __future__ import annotations

import io
import threading
import time
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import make_config, new_session, wait_ready

from renderer.config.settings import RenderSettings
from renderer.image.denoise import ATROUS_BYTES_PER_PIXEL, OIDN_BYTES_PER_PIXEL, denoise_nbytes
from renderer.image.result import traced_nbytes
from server.app import create_app
from server.frames.pipeline import GUIDE_BYTES_PER_PIXEL, frame_nbytes

SIDE = 256  # a 256² normal npy frame: ~7 MB estimated, over half the 8 MiB budget
BUDGET = 8 << 20
FRAME = {"width": SIDE, "height": SIDE, "mode": "normal", "format": "npy"}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("frame-memory")
    with TestClient(
        create_app(make_config(tmp, max_work=SIDE * SIDE * 16, max_frame_bytes_in_flight=BUDGET, queue_size=4))
    ) as c:
        wait_ready(c.get)
        yield c


def frames_of(c: TestClient):
    return c.app.state.frames


def test_frames_past_the_byte_budget_are_never_in_flight_together(app, monkeypatch):
    """Four frames of four sessions at once, each over half the budget: one at a time from
    its admission to its encoded body (was: all four, as many as POCKETRAY_QUEUE_SIZE admits)."""
    frames = frames_of(app)
    monkeypatch.setattr(frames, "FRAME_BYTES_WAIT_S", 30.0, raising=False)  # wait their turn, no 503
    sids = [new_session(app)["id"] for _ in range(4)]
    encode_frame = frames.encode_frame
    lock, now, most = threading.Lock(), [0], [0]

    def slow_encode(*args, **kwargs):  # the stage where all four overlapped
        with lock:
            now[0] += 1
            most[0] = max(most[0], now[0])
        try:
            time.sleep(0.3)
            return encode_frame(*args, **kwargs)
        finally:
            with lock:
                now[0] -= 1

    monkeypatch.setattr(frames, "encode_frame", slow_encode)
    codes: list[int] = []

    def get(sid: str) -> None:
        codes.append(app.get(f"/api/sessions/{sid}/frame", params=FRAME).status_code)

    threads = [threading.Thread(target=get, args=(sid,)) for sid in sids]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert codes == [200] * 4
    assert most[0] == 1, most[0]
    assert frames.frame_bytes.used == 0


def test_a_frame_that_finds_the_budget_taken_gets_503_with_retry_after(app, monkeypatch):
    frames = frames_of(app)
    sid = new_session(app)["id"]
    monkeypatch.setattr(frames, "FRAME_BYTES_WAIT_S", 0.05)
    assert frames.frame_bytes.acquire(BUDGET, 0)  # another frame holds the whole budget
    try:
        r = app.get(f"/api/sessions/{sid}/frame", params=FRAME)
    finally:
        frames.frame_bytes.release(BUDGET)
    assert r.status_code == 503 and int(r.headers["retry-after"]) >= 1, r.text
    assert "POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT" in r.json()["detail"]
    small = {**FRAME, "width": 16, "height": 16}  # the budget back: frames are served
    assert app.get(f"/api/sessions/{sid}/frame", params=small).status_code == 200
    assert app.get(f"/api/sessions/{sid}/frame", params=FRAME).status_code == 200  # alone, within it


@pytest.mark.parametrize("mode", ["normal", "depth", "primid", "color"])
def test_the_npy_body_is_the_renderers_array(app, monkeypatch, mode):
    frames = frames_of(app)
    sid = new_session(app)["id"]
    seen = []
    encode_frame = frames.encode_frame

    def spy(result, *args, **kwargs):
        seen.append(result.array().copy())
        return encode_frame(result, *args, **kwargs)

    monkeypatch.setattr(frames, "encode_frame", spy)
    r = app.get(f"/api/sessions/{sid}/frame", params={**FRAME, "mode": mode, "width": 48, "height": 40})
    assert r.status_code == 200, r.text
    got = np.load(io.BytesIO(r.content), allow_pickle=False)
    want = seen[-1]
    assert got.dtype == want.dtype and got.shape == want.shape and got.tobytes() == want.tobytes()


def test_the_estimate_of_a_frame_counts_its_target_read_back_and_body():
    from renderer.gl.targets import BYTES_PER_PIXEL, BYTES_PER_PIXEL_RGBA8, TargetPool
    from renderer.image.result import TARGET_BYTES_PER_PIXEL, TARGET_BYTES_PER_PIXEL_RGBA8

    assert (TARGET_BYTES_PER_PIXEL, TARGET_BYTES_PER_PIXEL_RGBA8) == (BYTES_PER_PIXEL, BYTES_PER_PIXEL_RGBA8)
    pixels = 4096 * 4096
    big = RenderSettings(width=4096, height=4096, mode="normal", format="npy", samples_per_pixel=1)
    result = 3 * 4 + 3 * 4 + 4 + 4  # image, normal, depth, primid
    assert frame_nbytes(big) == 2 * TargetPool.nbytes_of(4096, 4096) + (result + 12) * pixels  # 1.69 GiB
    png = RenderSettings(width=4096, height=4096, format="png", samples_per_pixel=1)
    assert frame_nbytes(png) < frame_nbytes(big) / 3
    assert traced_nbytes(64, 64, 4) > traced_nbytes(64, 64, 1)  # the sub-pixel grid


# A path colour jpeg frame with accumulate: ~308 bytes a pixel (target, read-back, arrays, sums, tone
# mapping), 20 MB at 256² — alone over the 8 MiB budget.
OVER = {"width": SIDE, "height": SIDE, "mode": "color", "format": "jpeg", "integrator": "path", "accumulate": 1}


def test_a_frame_over_the_budget_alone_is_refused_up_front_and_others_are_served(app, monkeypatch):
    """An accumulation frame whose estimate alone is over the budget: 422 naming its size and the
    largest accepted, nothing of its session changed (its accumulation of another view is kept);
    another session's small frame meanwhile is served (was: the large frame was admitted alone,
    held more than the budget, and the small one waited its 1 s and got 503)."""
    frames = frames_of(app)
    monkeypatch.setattr(frames, "FRAME_BYTES_WAIT_S", 0.05)
    sid, other = new_session(app)["id"], new_session(app)["id"]
    small_acc = {**OVER, "width": 16, "height": 16}
    assert app.get(f"/api/sessions/{sid}/frame", params=small_acc).status_code == 200
    held = frames.accumulations.count(sid)
    version = app.get(f"/api/sessions/{sid}").json()["version"]
    assert held > 0
    encode_frame, in_encode = frames.encode_frame, threading.Event()

    def slow_encode(result, frame, *args, **kwargs):  # the large frame (if admitted) stays in flight
        if frame.settings.width == SIDE:
            in_encode.set()
            time.sleep(1.0)
        return encode_frame(result, frame, *args, **kwargs)

    monkeypatch.setattr(frames, "encode_frame", slow_encode)
    big: list = []
    t = threading.Thread(target=lambda: big.append(app.get(f"/api/sessions/{sid}/frame", params=OVER)))
    t.start()
    deadline = time.monotonic() + 30  # until it is refused, or (admitted) in flight
    while t.is_alive() and not in_encode.is_set() and time.monotonic() < deadline:
        time.sleep(0.01)
    small = app.get(f"/api/sessions/{other}/frame", params={**FRAME, "width": 16, "height": 16})
    t.join(60)
    assert small.status_code == 200, small.text
    r = big[0]
    assert r.status_code == 422, r.text
    (error,) = r.json()["detail"]
    assert error["loc"] == ["query", "width"], error
    message = error["msg"]
    assert f"{SIDE} × {SIDE}" in message and "POCKETRAY_MAX_FRAME_BYTES" in message, message

    def over(**change) -> RenderSettings:
        return RenderSettings(**{**{k: v for k, v in OVER.items() if k != "accumulate"}, **change})

    need = frame_nbytes(over(), True)
    per_pixel = need // (SIDE * SIDE)
    largest = BUDGET // per_pixel
    assert f"~{need:,} bytes" in message and f"at most {largest // SIDE} at height {SIDE}" in message, message
    assert (
        frame_nbytes(over(width=largest // SIDE), True) <= BUDGET < frame_nbytes(over(width=largest // SIDE + 1), True)
    )
    # nothing committed: the accumulation of the session's other view, its version, the budget
    assert frames.accumulations.count(sid) == held
    assert app.get(f"/api/sessions/{sid}").json()["version"] == version
    assert frames.frame_bytes.used == 0


def test_the_estimate_of_a_denoised_path_frame_counts_the_denoiser():
    """A denoised path frame's reservation counts its guides and the denoiser's own working memory
    (OIDN's scratch: 576 bytes a pixel measured, and its output), which it did not."""
    assert OIDN_BYTES_PER_PIXEL >= 576 + 12 and ATROUS_BYTES_PER_PIXEL >= 216
    path = dict(width=640, height=480, mode="color", format="jpeg", integrator="path", samples_per_pixel=4)
    pixels = 640 * 480
    off = frame_nbytes(RenderSettings(**path, denoise="off"))
    for denoiser, own in (("oidn", OIDN_BYTES_PER_PIXEL), ("atrous", ATROUS_BYTES_PER_PIXEL)):
        assert denoise_nbytes(denoiser, 640, 480) == own * pixels
        on = frame_nbytes(RenderSettings(**path, denoise=denoiser))
        assert on - off == (GUIDE_BYTES_PER_PIXEL + own) * pixels, denoiser
    assert denoise_nbytes("off", 640, 480) == 0
    assert frame_nbytes(RenderSettings(**path, denoise="oidn"), accumulate=True) > frame_nbytes(
        RenderSettings(**path, denoise="oidn")
    )
