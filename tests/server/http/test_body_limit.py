"""The body size limit (server/http/body_limit.py): 413 for bodies too large, and nothing changes."""

from __future__ import annotations

import json

from pocketray_server_support import scene_with, snapshot


def test_oversized_body_is_413_and_changes_nothing(client, sid):
    before = snapshot(client, sid)
    big = scene_with()
    big["spheres"] = [{"center": [i % 20, 0, 0], "radius": 0.5} for i in range(10000)]  # > 256 KiB
    r = client.put(f"/api/sessions/{sid}/scene", json=big)
    assert r.status_code == 413 and "body" in r.json()["detail"]
    # chunked (no Content-Length) is refused as well
    body = json.dumps(big).encode()
    r = client.put(
        f"/api/sessions/{sid}/scene",
        content=iter([body[:1000], body[1000:]]),
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 413
    assert snapshot(client, sid) == before
