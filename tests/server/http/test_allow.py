"""OPTIONS and 405 with the right Allow (server/http/allow.py)."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize(
    "path,allow",
    [
        ("/api/sessions", "OPTIONS, POST"),
        ("/api/sessions/abc", "DELETE, GET, OPTIONS"),
        ("/api/sessions/abc/scene", "GET, OPTIONS, PUT"),
        ("/api/sessions/abc/settings", "OPTIONS, PATCH"),
        ("/api/sessions/abc/gesture", "OPTIONS, POST"),
        ("/api/health", "GET, OPTIONS"),
    ],
)
def test_options_answers_the_paths_methods(client, path, allow):
    """Rules out: 405 with Allow: GET, HEAD (the static files' answer) on every API path."""
    r = client.options(path)
    assert r.status_code == 204 and r.headers["allow"] == allow and not r.content
    verbs = [m for m in ("GET", "POST", "PUT", "PATCH", "DELETE") if m not in allow]
    r = client.request(verbs[0], path)
    assert r.status_code == 405 and r.headers["allow"] == allow, r.text
    assert verbs[0] in r.json()["detail"] and allow in r.json()["detail"]
