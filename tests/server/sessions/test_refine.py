"""Refinement while still (server/sessions/refine.py; docs/API.md, "Refinement"): a refine stream's
sample counts rise to its target, its last image is one frame of all those samples, the next
message (a gesture) stops it, the HTTP twin streams the same parts, and a Whitted colour view refines by
jittered slices of its sub-pixel grid."""

from __future__ import annotations

import io
import json
import time
import warnings

import numpy as np
import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import make_config, new_session, wait_ready

from server.app import create_app
from server.sessions.refine import FIRST_SLICE, GROWTH, next_slice

SIDE = 16
MAX_REFINE_MS = 30_000  # the service's bound of a stream's GL time (POCKETRAY_MAX_REFINE_MS)
PATH = {
    "integrator": "path",
    "width": SIDE,
    "height": SIDE,
    "format": "npy",
    "samples_per_pixel": 4,
    "max_recursion_depth": 4,
}


def test_a_slice_is_sized_to_the_time_it_aims_at():
    assert next_slice(4, 40.0, 100.0, 1000) == 10  # 10 ms a sample: 10 samples in 100 ms
    assert next_slice(4, 1.0, 100.0, 1000) == 4 * GROWTH, "one measurement grows a slice GROWTH× at most"
    assert next_slice(4, 1.0, 100.0, 7) == 7, "never past the target"
    assert next_slice(4, 4000.0, 100.0, 1000) == 1


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("refine")
    # slices of about one sample: a stream of many frames within a few samples
    config = make_config(tmp, max_work=SIDE * SIDE * 4 * 64, refine_slice_ms=0.001, max_refine_ms=MAX_REFINE_MS)
    with TestClient(create_app(config)) as c:
        wait_ready(c.get)
        yield c


def cornell(c: TestClient) -> str:
    return new_session(c, scenario=None, n=None, seed=None, radius=None, mesh_scene={"kind": "cornell", "detail": 0})[
        "id"
    ]


def test_a_refine_stream_rises_to_its_target_and_ends_as_one_frame_of_its_samples(app):
    sid = cornell(app)
    target = FIRST_SLICE + 3
    heads, image = [], None
    with app.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_json({"type": "refine", "target_samples": target, "target_ms": 600_000, "frame": PATH})
        while True:
            head = ws.receive_json()
            assert "refine" in head, head
            image = np.load(io.BytesIO(ws.receive_bytes()))
            heads.append(head)
            if head["refine"]["done"]:
                break
    counts = [h["samples"] for h in heads]
    assert len(counts) >= 2 and counts[0] == FIRST_SLICE and counts[-1] == target, counts
    assert all(a < b for a, b in zip(counts, counts[1:], strict=False)), counts
    assert [h["refine"]["samples"] for h in heads] == counts
    assert heads[-1]["refine"]["reason"] == "samples" and not any(h["refine"]["done"] for h in heads[:-1])
    assert all(h["refine"]["target_samples"] == target for h in heads)
    assert all(h["refine"]["target_ms"] == 600_000 for h in heads), "the wall-clock target as asked"
    assert all(h["refine"]["budget_ms"] == MAX_REFINE_MS for h in heads), "the service's bound of its GL time"
    assert all(0 < a["refine"]["gl_ms"] < b["refine"]["gl_ms"] for a, b in zip(heads, heads[1:], strict=False))
    r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, "samples_per_pixel": target})
    one = np.load(io.BytesIO(r.content))
    assert image is not None and np.abs(image - one).max() < 1e-5, "k slices are one frame of all their samples"
    assert np.abs(image - np.load(io.BytesIO(app.get(f"/api/sessions/{sid}/frame", params=PATH).content))).max() > 1e-2


def test_the_next_message_stops_the_stream(app):
    sid = cornell(app)
    with app.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_json({"type": "refine", "target_samples": 4096, "target_ms": 600_000, "frame": PATH})
        first = ws.receive_json()
        assert first["refine"]["done"] is False, first
        ws.receive_bytes()
        ws.send_json({"type": "pan", "dx": 3, "dy": 0, "frame": PATH})
        late = 0
        while "refine" in (head := ws.receive_json()):  # frames sent before the gesture was read
            ws.receive_bytes()
            late += 1
        assert late <= 1 and head["version"] == 2, head
        ws.receive_bytes()
        held = app.app.state.frames.accumulations.count(sid)
        time.sleep(0.5)
        ws.send_json({"type": "frame", "frame": PATH})
        head = ws.receive_json()
        assert "refine" not in head and head["version"] == 2, "nothing of the stream after the gesture's answer"
        ws.receive_bytes()
        assert app.app.state.frames.accumulations.count(sid) == held, "the stopped stream adds nothing more"
        ws.send_json({"type": "refine", "target_samples": 0, "frame": PATH})
        refused = ws.receive_json()
        assert refused["status"] == 422 and refused["detail"][0]["loc"] == ["body", "target_samples"]


def test_a_stream_ends_at_its_time(app):
    sid = cornell(app)
    with app.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_json({"type": "refine", "target_samples": 4096, "target_ms": 1, "frame": PATH})
        head = ws.receive_json()
        ws.receive_bytes()
    assert head["refine"]["done"] and head["refine"]["reason"] == "time", head
    assert head["refine"]["elapsed_ms"] >= 1 and head["samples"] == FIRST_SLICE


@pytest.mark.gl
def test_a_stream_without_a_time_of_its_own_ends_at_the_services_gl_budget(tmp_path):
    """refine_time_ms 0 (the default): no wall-clock end; the stream's frames' GL time, summed, meets the
    service's POCKETRAY_MAX_REFINE_MS (here 1 ms: the first frame)."""
    config = make_config(tmp_path, max_work=SIDE * SIDE * 4 * 64, max_refine_ms=1)
    with TestClient(create_app(config)) as c:
        wait_ready(c.get)
        sid = cornell(c)
        with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
            ws.send_json({"type": "refine", "target_samples": 4096, "frame": PATH})
            head = ws.receive_json()
            ws.receive_bytes()
    assert head["refine"]["done"] and head["refine"]["reason"] == "budget", head
    assert head["refine"]["target_ms"] == 0 and head["refine"]["budget_ms"] == 1
    assert head["refine"]["gl_ms"] >= 1 and head["samples"] == FIRST_SLICE


def stream_to(app, sid: str, samples: int, **params) -> list[tuple[dict, np.ndarray]]:
    """A refinement stream over HTTP: each part's progress and image."""
    r = app.get(
        f"/api/sessions/{sid}/frame",
        params={**PATH, "refine": 1, "refine_samples": samples, "refine_time_ms": 600_000, **params},
    )
    assert r.status_code == 200, r.text
    return [(json.loads(h["X-Refine"]), np.load(io.BytesIO(body))) for h, body in parts(r)]


def test_the_noise_estimate_is_the_error_against_a_converged_image(app):
    """The estimate from the held samples and the last frame's (server/frames/accumulate.py) against the
    relative RMS error measured against the same view at 16× the samples (the estimator is under test,
    not the integrator; the sampler is deterministic, so is this comparison). The estimate takes the
    samples as independent; the pixel positions' lattice (shaders/lighting.glsl) converges faster, so
    it is conservative: above the error, within 4×."""
    sid = cornell(app)
    for _ in range(32):  # 1,024 samples in 32 accumulation frames
        r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, "samples_per_pixel": 32, "accumulate": 1})
    assert r.headers["x-samples"] == "1024"
    reference = np.load(io.BytesIO(r.content))
    got = stream_to(app, cornell(app), 64)
    progress, image = got[-1]
    assert got[0][0]["noise"] is None, "one frame has no second part to compare with"
    estimated = progress["noise"]
    measured = float(np.sqrt(np.mean((image - reference) ** 2)) / np.mean(reference))
    assert 1.0 <= estimated / measured < 4.0, (estimated, measured)
    noises = [p["noise"] for p, _ in got[1:]]
    assert noises[-1] < noises[0], noises

    # a noise target ends the stream before its samples
    target = min(1.0, 1.2 * estimated)  # (reached by 64 samples: the same samples as above)
    ended = stream_to(app, cornell(app), 4096, refine_noise=target)[-1][0]
    assert ended["reason"] == "noise" and ended["noise"] <= target and ended["samples"] <= 64, ended


def parts(r) -> list[tuple[dict[str, str], bytes]]:
    """The parts of a multipart/mixed answer (each with Content-Length)."""
    boundary = r.headers["content-type"].split("boundary=")[1].encode()
    out, data = [], r.content
    for chunk in data.split(b"--" + boundary)[1:]:
        if chunk.startswith(b"--"):
            break
        head, _, rest = chunk[2:].partition(b"\r\n\r\n")
        headers = dict(line.split(": ", 1) for line in head.decode().split("\r\n"))
        out.append((headers, rest[: int(headers["Content-Length"])]))
    return out


def test_the_http_stream_has_the_same_parts(app):
    sid = cornell(app)
    r = app.get(
        f"/api/sessions/{sid}/frame",
        params={**PATH, "refine": 1, "refine_samples": FIRST_SLICE + 2, "refine_time_ms": 600_000},
    )
    assert r.status_code == 200 and r.headers["content-type"].startswith("multipart/mixed"), r.text
    got = parts(r)
    progress = [json.loads(h["X-Refine"]) for h, _ in got]
    assert [p["samples"] for p in progress] == [int(h["X-Samples"]) for h, _ in got]
    assert progress[0]["samples"] == FIRST_SLICE and progress[-1]["samples"] == FIRST_SLICE + 2
    assert [h["X-Frame-Part"] for h, _ in got] == ["refine"] * (len(got) - 1) + ["final"]
    assert progress[-1]["done"] and progress[-1]["reason"] == "samples"
    assert np.load(io.BytesIO(got[-1][1])).shape == (SIDE, SIDE, 3)


def test_a_whitted_colour_frame_refines_by_jittered_slices(app):
    """Each frame of a Whitted stream is one jittered slice of the session's 2 × 2 grid: the counts rise
    by 4 to the target, the first image is the plain frame's bit for bit, the later ones differ from it
    (the sub-pixels' points moved); a Whitted data mode is answered once."""
    whitted = {"integrator": "whitted", "samples_per_pixel": 4}
    sid = cornell(app)
    plain = np.load(io.BytesIO(app.get(f"/api/sessions/{sid}/frame", params={**PATH, **whitted}).content))
    got = stream_to(app, sid, 16, **whitted)
    assert [p["samples"] for p, _ in got] == [4, 8, 12, 16], [p for p, _ in got]
    assert got[-1][0]["done"] and got[-1][0]["reason"] == "samples"
    assert np.array_equal(got[0][1], plain), "the first slice is the plain frame"
    assert np.abs(got[-1][1] - plain).max() > 1e-3, "the later slices traced other sub-pixel points"
    assert app.app.state.frames.accumulations.count(sid) == 16
    r = app.get(f"/api/sessions/{sid}/frame", params={**PATH, **whitted, "mode": "depth", "refine": 1})
    got_depth = parts(r)
    assert len(got_depth) == 1 and json.loads(got_depth[0][0]["X-Refine"])["reason"] == "one_frame"


@pytest.fixture(scope="module")
def timed_app(tmp_path_factory):
    """Slices sized to 300 ms of GL time: a 16 × 16 frame's grow GROWTH× each frame."""
    config = make_config(tmp_path_factory.mktemp("refine-timed"), max_work=SIDE * SIDE * 4 * 64, refine_slice_ms=300)
    with TestClient(create_app(config)) as c:
        wait_ready(c.get)
        yield c


def test_a_whitted_stream_sizes_its_frames_in_slices(timed_app):
    """A Whitted stream's frames grow by whole slices as a path stream's by samples; its last image is
    the accumulation of as many one-slice frames (up to float rounding)."""
    whitted = {"integrator": "whitted", "samples_per_pixel": 4}
    got = stream_to(timed_app, cornell(timed_app), 64, **whitted)
    counts = [p["samples"] for p, _ in got]
    assert counts[0] == 4 and counts[-1] == 64 and all(c % 4 == 0 for c in counts), counts
    assert len(counts) < 16 and counts[1] - counts[0] > 4, "later frames hold several slices"
    sid = cornell(timed_app)
    for _ in range(16):
        r = timed_app.get(f"/api/sessions/{sid}/frame", params={**PATH, **whitted, "accumulate": 1})
    assert r.headers["x-samples"] == "64"
    np.testing.assert_allclose(got[-1][1], np.load(io.BytesIO(r.content)), rtol=1e-5, atol=1e-6)


def test_a_deleted_session_ends_its_stream_without_an_error(app):
    """The session deleted between two frames (or expired): the stream ends as for a gesture, so a
    client sees the end of its stream, never a broken connection."""
    from server.sessions.refine import refine

    service = app.app.state.service
    sid = cornell(app)
    steps = refine(service, sid, {**PATH, "integrator": "whitted"}, target_samples=4096, target_ms=600_000)
    assert next(steps).samples == 4
    assert app.delete(f"/api/sessions/{sid}").status_code == 204
    assert next(steps, None) is None


@pytest.mark.gl
def test_a_frame_over_one_frames_bytes_ends_the_stream_at_once(app, monkeypatch):
    """A view whose frame alone is over POCKETRAY_MAX_FRAME_BYTES: the stream's first frame is refused
    (422 at width) and no smaller slice of samples is tried — the size is its pixels'."""
    from server.faults import FrameTooLarge
    from server.sessions.refine import refine

    service, frames = app.app.state.service, app.app.state.frames
    monkeypatch.setattr(type(frames), "max_frame_bytes", property(lambda self: 64 << 10))
    checked: list[int] = []
    check_size = frames.check_size

    def counted(settings, accumulate=False):
        checked.append(settings.samples_per_pixel)
        return check_size(settings, accumulate)

    monkeypatch.setattr(frames, "check_size", counted)
    sid = cornell(app)
    with pytest.raises(FrameTooLarge) as refused:
        list(refine(service, sid, {**PATH, "width": 32, "height": 32}, target_samples=64))
    assert refused.value.loc == ("width",) and "POCKETRAY_MAX_FRAME_BYTES" in refused.value.message
    assert checked == [FIRST_SLICE], checked
    assert frames.accumulations.count(sid) == 0
