"""Accumulation (server/frames/accumulate.py; docs/API.md, "Accumulation"): a session's path
samples added up across frame requests — k requests give the image of one request of all their
samples, any change of camera or settings starts over, the byte budget drops the least recently
used, and a frame that fails commits nothing."""

from __future__ import annotations

import io
import threading
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import make_config, new_session, wait_ready

from renderer.config.settings import RenderSettings
from server.app import create_app
from server.faults import Superseded
from server.frames.accumulate import Accumulations, accumulation_key
from server.frames.pipeline import FrameRequest, FrameSettings
from server.http import metrics

SIDE = 16
PATH = {
    "integrator": "path",
    "width": SIDE,
    "height": SIDE,
    "format": "npy",
    "samples_per_pixel": 16,
    "max_recursion_depth": 4,
}
SUM_BYTES = SIDE * SIDE * 3 * 4  # one accumulation's float32 sum


def dropped(reason: str) -> float:
    return metrics.ACCUMULATIONS_DROPPED.labels(reason)._value.get()


def test_the_store_keeps_one_per_session_within_its_bytes():
    """Another key drops the session's accumulation (``change``); past the budget the least recently
    used goes (``budget``); a commit made from a count that moved meanwhile keeps nothing."""
    store = Accumulations(2 * SUM_BYTES)
    key = accumulation_key("rev", "{}", RenderSettings(**PATH))
    s = np.ones((SIDE, SIDE, 3), np.float32)
    assert store.start("a", key) == (None, 0)
    assert store.commit("a", key, 0, s, 16) and store.bytes == SUM_BYTES
    assert not store.commit("a", key, 0, s, 16), "another frame committed from 0 first"
    assert store.start("a", key)[1] == 16
    other = accumulation_key("rev", "{}", RenderSettings(**{**PATH, "max_recursion_depth": 5}))
    assert accumulation_key("rev", "{}", RenderSettings(**{**PATH, "samples_per_pixel": 4, "exposure": 2.0})) == key
    change = dropped("change")
    assert store.start("a", other) == (None, 0) and store.bytes == 0 and dropped("change") == change + 1
    budget = dropped("budget")
    for session in ("a", "b", "c"):
        assert store.commit(session, key, 0, s, 16)
    assert store.count("a") == 0 and store.count("b") == store.count("c") == 16
    assert store.bytes == 2 * SUM_BYTES and dropped("budget") == budget + 1
    store.start("b", key)  # b is used: c is the least recently used now
    assert store.commit("d", key, 0, s, 16) and store.count("c") == 0 and store.count("b") == 16


def test_a_whitted_key_holds_its_grid():
    """Whitted's samples_per_pixel is its sub-pixel grid, whose slices the count numbers: another grid
    starts over; the path integrator's is only the frame's increment."""
    whitted = {**PATH, "integrator": "whitted"}
    key = accumulation_key("rev", "{}", RenderSettings(**whitted))
    assert accumulation_key("rev", "{}", RenderSettings(**{**whitted, "samples_per_pixel": 4})) != key
    assert accumulation_key("rev", "{}", RenderSettings(**{**whitted, "format": "png"})) == key


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("accumulate")
    config = make_config(tmp, max_work=SIDE * SIDE * 4 * 64, max_accumulation_bytes=2 * SUM_BYTES)
    with TestClient(create_app(config)) as c:
        wait_ready(c.get)
        yield c


def cornell(c: TestClient) -> str:
    return new_session(c, scenario=None, n=None, seed=None, radius=None, mesh_scene={"kind": "cornell", "detail": 0})[
        "id"
    ]


def frame(c: TestClient, sid: str, **params) -> tuple[np.ndarray, int]:
    r = c.get(f"/api/sessions/{sid}/frame", params={**PATH, "accumulate": 1, **params})
    assert r.status_code == 200, r.text
    return np.load(io.BytesIO(r.content)), int(r.headers["x-samples"])


def test_k_requests_equal_one_request_of_all_their_samples(app):
    sid = cornell(app)
    for k in (1, 2, 3):
        image, samples = frame(app, sid)
        assert samples == 16 * k
    one, n = frame(app, sid, accumulate=0, samples_per_pixel=48)
    assert n == 48
    assert np.abs(image - one).max() < 1e-5
    mse = float(np.mean((image - one) ** 2))
    assert mse == 0 or 10 * np.log10(float(one.max()) ** 2 / mse) > 60
    first, _ = frame(app, sid, accumulate=0)
    assert np.abs(image - first).max() > 1e-2, "the later requests added samples of their own"
    # tone mapping and the encoding are applied to the mean: they keep the samples
    r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, "accumulate": 1, "format": "png", "exposure": 1})
    assert r.status_code == 200 and r.headers["x-samples"] == "64"
    # … and so is the denoiser: the mean is denoised, the accumulation keeps its samples
    r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, "accumulate": 1, "format": "png", "denoise": "oidn"})
    assert r.status_code == 200 and r.headers["x-samples"] == "80"
    assert frame(app, sid)[1] == 96


def test_a_change_of_camera_or_settings_starts_over(app):
    sid = cornell(app)
    assert frame(app, sid)[1] == 16 and frame(app, sid)[1] == 32
    assert frame(app, sid, max_recursion_depth=3)[1] == 16, "a setting changed"
    assert frame(app, sid, max_recursion_depth=3)[1] == 32
    camera = app.get(f"/api/sessions/{sid}").json()["camera"]
    r = app.put(f"/api/sessions/{sid}/camera", json={**camera, "fov_y": camera["fov_y"] + 5})
    assert r.status_code == 200, r.text
    assert frame(app, sid, max_recursion_depth=3)[1] == 16, "the camera moved"
    assert frame(app, sid, max_recursion_depth=3, time=0.0)[1] == 32, "the same time"
    assert frame(app, sid, max_recursion_depth=3, accumulate=0)[1] == 16, "a frame without accumulate holds nothing"
    assert frame(app, sid, max_recursion_depth=3)[1] == 48, "… and drops nothing"


def test_the_budget_drops_the_least_recently_used(app):
    frames = app.app.state.frames
    a, b, c = (cornell(app) for _ in range(3))
    frame(app, a)
    frame(app, b)
    frame(app, a)  # a is used after b
    frame(app, c)  # the budget holds two: b goes
    assert [frames.accumulations.count(s) for s in (a, b, c)] == [32, 0, 16]
    assert frames.accumulations.bytes <= 2 * SUM_BYTES
    scrape = app.get("/metrics").text
    assert f"pocketray_accumulation_bytes {float(frames.accumulations.bytes)}" in scrape
    assert 'pocketray_accumulations_dropped_total{reason="budget"}' in scrape
    assert app.delete(f"/api/sessions/{a}").status_code == 204
    assert frames.accumulations.count(a) == 0


def test_a_failed_frame_commits_nothing(app):
    sid = cornell(app)
    frame(app, sid)
    service, frames = app.app.state.service, app.app.state.frames
    cancel = threading.Event()
    cancel.set()  # the client went away before the frame was traced
    request = service.frame_request(sid, PATH, cancel=cancel, accumulate=True)
    with pytest.raises(Superseded):
        list(frames.run(request))
    assert frames.accumulations.count(sid) == 16
    state = service.get(sid)
    stateless = FrameRequest(service.scene(state), FrameSettings.of({**state.settings, **PATH}), accumulate=True)
    list(frames.run(stateless))  # no session: nothing to accumulate into
    assert frame(app, sid)[1] == 32


def test_the_websocket_says_the_samples_it_holds(app):
    sid = cornell(app)
    with app.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        for want in (16, 32):
            ws.send_json({"type": "frame", "accumulate": True, "frame": PATH})
            head = ws.receive_json()
            assert head["samples"] == want, head
            assert np.load(io.BytesIO(ws.receive_bytes())).shape == (SIDE, SIDE, 3)
        ws.send_json({"type": "frame", "accumulate": "yes", "frame": PATH})
        refused = ws.receive_json()
        assert refused["status"] == 422 and refused["detail"][0]["loc"] == ["body", "accumulate"]


def test_whitted_colour_frames_accumulate_jittered_slices(app):
    """A Whitted colour frame with accumulate adds one jittered slice of its grid (s samples); the first
    is the plain frame; another grid starts over; a data mode accumulates nothing."""
    whitted = {"integrator": "whitted", "samples_per_pixel": 4}
    sid = cornell(app)
    plain, _ = frame(app, sid, accumulate=0, **whitted)
    first, n1 = frame(app, sid, **whitted)
    assert n1 == 4 and np.array_equal(first, plain)
    second, n2 = frame(app, sid, **whitted)
    assert n2 == 8 and np.abs(second - plain).max() > 1e-3
    assert frame(app, sid, integrator="whitted", samples_per_pixel=1)[1] == 1, "another grid starts over"
    one = {"integrator": "whitted", "samples_per_pixel": 1}
    r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, **one, "accumulate": 1, "format": "png"})
    assert r.status_code == 200 and r.headers["x-samples"] == "2", "a png frame (an 8-bit target alone) goes on too"
    r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, **one, "accumulate": 1, "mode": "depth"})
    assert r.status_code == 200 and app.app.state.frames.accumulations.count(sid) == 2
