"""The security headers (server/http/security.py): the client's Content-Security-Policy and the
others on every answer, the offline docs' own policy. The browser test
(tests/browser/test_csp.py) checks that the client and the docs work under them."""

from __future__ import annotations

import base64
import hashlib
import re

import pytest

from server.http.security import CSP, SecurityHeaders
from tests.helpers import run_coroutine


def directives(policy: str) -> dict[str, list[str]]:
    out = {}
    for part in policy.split(";"):
        name, *values = part.split()
        out[name] = values
    return out


@pytest.mark.parametrize("path", ["/", "/index.html", "/js/app.js", "/style.css", "/api/health", "/api/info"])
def test_the_client_and_the_api_carry_the_security_headers(client, path):
    r = client.get(path)
    assert r.status_code == 200
    assert r.headers["x-content-type-options"] == "nosniff"
    assert r.headers["x-frame-options"] == "DENY"
    assert r.headers["referrer-policy"] == "no-referrer"
    policy = directives(r.headers["content-security-policy"])
    assert policy["frame-ancestors"] == ["'none'"]
    assert policy["script-src"] == ["'self'"]  # no inline script, no eval
    assert policy["object-src"] == ["'none'"] and policy["base-uri"] == ["'none'"]
    assert "'unsafe-inline'" not in policy["style-src"]


def test_the_docs_allow_their_own_inline_script_by_its_hash(client):
    r = client.get("/docs")
    assert r.status_code == 200
    inline = re.findall(rb"<script>(.*?)</script>", r.content, re.DOTALL)
    assert len(inline) == 1  # Swagger UI's start-up script, written into the page
    digest = base64.b64encode(hashlib.sha256(inline[0]).digest()).decode()
    policy = directives(r.headers["content-security-policy"])
    assert policy["script-src"] == ["'self'", f"'sha256-{digest}'"]
    assert policy["frame-ancestors"] == ["'none'"] and r.headers["x-content-type-options"] == "nosniff"
    redoc = client.get("/redoc")
    assert "blob:" in directives(redoc.headers["content-security-policy"])["worker-src"]  # its search worker


def test_an_answer_that_sets_a_header_keeps_it():
    sent = []

    async def app(scope, receive, send):
        await send({"type": "http.response.start", "status": 200, "headers": [(b"X-Frame-Options", b"SAMEORIGIN")]})
        await send({"type": "http.response.body", "body": b""})

    async def send(message):
        sent.append(message)

    run_coroutine(SecurityHeaders(app)({"type": "http"}, None, send))
    headers = sent[0]["headers"]
    assert [v for k, v in headers if k.lower() == b"x-frame-options"] == [b"SAMEORIGIN"]
    assert [k for k, _ in headers].count(CSP.encode()) == 1
