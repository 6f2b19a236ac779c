"""The session WebSocket (server/api/routes/ws.py)."""

from __future__ import annotations

import json

import pytest
from pocketray_server_support import new_session

from server.api.schemas import PanGesture


def test_websocket_gesture_to_frame(ready_client):
    c = ready_client
    sid = new_session(c)["id"]
    with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_text(json.dumps({"type": "pinch", "scale": 2, "frame": {"width": 32, "height": 48, "format": "jpeg"}}))
        meta = json.loads(ws.receive_text())
        assert meta["version"] == 2 and meta["camera"]["position"] == [0.0, 0.0, 50.0]
        assert meta["media_type"] == "image/jpeg" and "trace" in meta["timings"]
        assert ws.receive_bytes()[:2] == b"\xff\xd8"
        ws.send_text(json.dumps({"type": "pinch", "scale": -1}))
        err = json.loads(ws.receive_text())  # the HTTP route's 422 (server/api/errors.py)
        assert err["status"] == 422 and any("scale" in d["msg"] for d in err["detail"])
    assert c.get(f"/api/sessions/{sid}").json()["version"] == 2


def _move_after_each_frame(monkeypatch, app, sid: str) -> dict[int, dict]:
    """Another client moves the session once each frame is made (after its commit, before its message
    is sent). Returns the camera of every version the session went through meanwhile, as JSON."""
    frames, service = app.state.frames, app.state.service
    run = frames.run
    seen: dict[int, dict] = {}

    def run_then_move(request):
        yield from run(request)
        state = service.get(sid)  # the session as the frame left it (its gesture committed)
        seen[state.version] = json.loads(json.dumps(state.camera))
        moved = service.gesture(sid, PanGesture(type="pan", dx=7, dy=0))
        seen[moved.version] = json.loads(json.dumps(moved.camera))

    monkeypatch.setattr(frames, "run", run_then_move)
    return seen


@pytest.mark.parametrize(
    "message",
    [
        {"type": "frame", "frame": {"width": 32, "height": 48}},
        {"type": "pinch", "scale": 2, "frame": {"width": 32, "height": 48}},
        {"type": "refine", "target_samples": 2, "frame": {"width": 32, "height": 48, "samples_per_pixel": 1}},
    ],
    ids=["frame", "gesture", "refine"],
)
def test_message_names_the_camera_of_its_version(ready_client, monkeypatch, message):
    """The session moved by someone else between the frame and its message: the message still says
    the camera (and settings) the frame was rendered with, the camera of the version it names."""
    c = ready_client
    sid = new_session(c)["id"]
    seen = _move_after_each_frame(monkeypatch, c.app, sid)
    with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_text(json.dumps(message))
        head = json.loads(ws.receive_text())
        assert "status" not in head, head
        ws.receive_bytes()
    now = c.get(f"/api/sessions/{sid}").json()
    assert now["version"] > head["version"] and now["camera"] != head["camera"]  # it did move meanwhile
    assert head["camera"] == seen[head["version"]]
    assert head["settings"]["width"] == 32 and head["settings"]["height"] == 48  # the message's, not the session's
    assert now["settings"]["width"] != 32


@pytest.mark.parametrize(
    ("message", "loc"),
    [
        ({"type": "frame", "acumulate": True}, ["body", "acumulate"]),
        ({"type": "refine", "target_sample": 4}, ["body", "target_sample"]),
        ({"type": "pan", "dx": 1, "dy": 0, "dz": 1}, ["body", "pan", "dz"]),
        ({"type": "frame", "frame": {"widht": 32}}, ["query", "widht"]),
    ],
    ids=["frame", "refine", "gesture", "frame-settings"],
)
def test_unknown_fields_are_refused(ready_client, message, loc):
    """A message's unknown field is a 422 naming it, as every HTTP body's (docs/API.md), and nothing
    runs; the connection stays open."""
    c = ready_client
    sid = new_session(c)["id"]
    with c.websocket_connect(f"/api/sessions/{sid}/ws") as ws:
        ws.send_text(json.dumps(message))
        head = json.loads(ws.receive_text())
        assert head["status"] == 422
        assert [(d["type"], d["loc"]) for d in head["detail"]] == [("extra_forbidden", loc)]
        ws.send_text(json.dumps({"type": "frame"}))
        head = json.loads(ws.receive_text())
        assert "status" not in head and head["version"] == 1 and head["samples"] == 1
        ws.receive_bytes()
    assert c.get(f"/api/sessions/{sid}").json()["version"] == 1
