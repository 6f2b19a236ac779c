"""The session WebSocket (server/api/routes/ws.py)."""

from __future__ import annotations

import json

from pocketray_server_support import new_session


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
