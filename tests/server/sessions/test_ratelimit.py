"""The creation rate per client address (server/sessions/ratelimit.py): token buckets, and 429
with Retry-After over ``POCKETRAY_SESSION_CREATE_PER_MIN`` / ``_BURST``.

Without it, one address created 5,254 sessions in 60 s (the quota of stored bytes is
sessions/test_store.py's).
"""

from __future__ import annotations

import warnings

import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import SMALL, make_config

from server.app import create_app
from server.sessions.ratelimit import RateLimited, TokenBuckets, client_key


@pytest.fixture(scope="module")
def limited(tmp_path_factory):
    """An app whose addresses may create 3 sessions at once, then 6 a minute; a quota of 64 KiB."""
    tmp = tmp_path_factory.mktemp("quota")
    app = create_app(
        make_config(tmp, warmup=False, session_create_per_min=6, session_create_burst=3, max_store_bytes=64 * 1024)
    )
    with TestClient(app, client=("192.0.2.1", 40000)) as c:
        yield c


BODY = {"scenario": 3, "n": 64, "seed": 1, "radius": 1.0, "settings": dict(SMALL)}


def test_token_buckets_refill_at_the_rate_and_stay_bounded():
    now = [0.0]
    buckets = TokenBuckets(per_min=6, burst=3, max_clients=100, clock=lambda: now[0])
    for _ in range(3):
        buckets.take("a")
    with pytest.raises(RateLimited) as e:
        buckets.take("a")
    assert e.value.retry_after_s == 10  # one token every 10 s
    buckets.take("b")  # another address has its own bucket
    now[0] = 9.0
    with pytest.raises(RateLimited) as e:
        buckets.take("a")
    assert e.value.retry_after_s == 1
    now[0] = 10.5
    buckets.take("a")
    for i in range(1000):
        buckets.take(f"10.0.{i // 256}.{i % 256}")
    assert len(buckets) == 100  # the least recently seen are forgotten
    TokenBuckets(per_min=0, burst=1).take("x") or TokenBuckets(per_min=0, burst=1).take("x")  # 0: no limit


def test_ipv6_addresses_share_the_bucket_of_their_64():
    assert client_key("2001:db8:1:2:aaaa::1") == client_key("2001:db8:1:2:ffff::9") == "2001:db8:1:2::/64"
    assert client_key("2001:db8:1:3::1") != client_key("2001:db8:1:2::1")
    assert client_key("::ffff:10.1.2.3") == client_key("10.1.2.3") == "10.1.2.3"
    assert client_key(None) == "unknown"


def test_creation_over_the_rate_gets_429_with_retry_after(limited):
    store = limited.app.state.store
    first = [limited.post("/api/sessions", json=BODY) for _ in range(3)]
    assert [r.status_code for r in first] == [201, 201, 201]
    n = store.count()
    r = limited.post("/api/sessions", json=BODY)
    assert r.status_code == 429, r.text
    assert 1 <= int(r.headers["retry-after"]) <= 10
    assert "POCKETRAY_SESSION_CREATE_PER_MIN" in r.json()["detail"]
    assert store.count() == n  # nothing created
    assert limited.get(f"/api/sessions/{first[0].json()['id']}").status_code == 200  # its sessions go on
    other = TestClient(limited.app, client=("192.0.2.2", 40000))  # (no lifespan: the app runs already)
    assert other.post("/api/sessions", json=BODY).status_code == 201  # another address is not limited
    ipv6 = [TestClient(limited.app, client=(f"2001:db8::{i}", 40000)) for i in range(1, 5)]
    codes = [c.post("/api/sessions", json=BODY).status_code for c in ipv6]
    assert codes == [201, 201, 201, 429]  # one /64, one bucket
