"""The app as assembled (server/app.py): the static client, the shaders and the docs it mounts."""

from __future__ import annotations


def test_static_client_shaders_and_docs(client):
    r = client.get("/shaders/raytrace.frag")
    assert r.status_code == 200 and "#version" in r.text
    assert client.put("/shaders/raytrace.frag", content=b"x").status_code == 405
    assert client.get("/docs").status_code == 200
    spec = client.get("/openapi.json").json()
    assert "/api/sessions/{session_id}/gesture" in spec["paths"]
