"""Sessions are bounded: a creation rate per client address, and a quota of stored bytes.

Without either, one address created 5,254 sessions in 60 s, each holding its scene (up to a
16 MB model) for the 24 h idle TTL. Now: ``POCKETRAY_SESSION_CREATE_PER_MIN`` /
``_BURST`` (429 + Retry-After over it) and ``POCKETRAY_MAX_STORE_BYTES`` (507 + Retry-After
for a new session or a scene change that would pass it; nothing written; existing sessions
go on), the bytes counted by the store itself — SQLite and Redis, several processes alike.
"""

from __future__ import annotations

import threading
import time
import warnings
from dataclasses import replace

import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import SMALL, make_config, new_session

from server.app import create_app
from server.sessions.ratelimit import RateLimited, TokenBuckets, client_key
from server.sessions.store import RedisStore, SessionState, SQLiteStore, StoreFull

CAM = {"position": [0.0, 0.0, 100.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 60.0}


def state(sid: str, rev: str = "r1") -> SessionState:
    return SessionState(
        id=sid,
        version=1,
        camera=CAM,
        home_camera=CAM,
        settings={"width": 8},
        scene_info={"n_spheres": 1, "n_planes": 0},
        scene_rev=rev,
    )


def open_store(kind: str, request, tmp_path, max_bytes: int, ttl_s: float = 3600, prefix: str | None = None):
    if kind == "sqlite":
        return SQLiteStore(tmp_path / "s.sqlite3", ttl_s=ttl_s, max_bytes=max_bytes, touch_interval_s=0.0)
    return RedisStore(
        request.getfixturevalue("redis_url"),
        ttl_s=ttl_s,
        max_bytes=max_bytes,
        touch_interval_s=0.0,
        prefix=prefix or f"quota-{time.monotonic_ns()}:",
    )


# ---- the store's quota ------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["sqlite", "redis"])
def test_a_create_over_the_quota_is_refused_and_writes_nothing(kind, request, tmp_path):
    s = open_store(kind, request, tmp_path, max_bytes=100)
    try:
        s.create(state("a"), b"a" * 60)
        assert s.used_bytes() == 60
        with pytest.raises(StoreFull) as e:
            s.create(state("b"), b"b" * 41)
        assert (e.value.used, e.value.wanted, e.value.limit) == (60, 41, 100)
        assert s.get("b") is None and s.get_source("b") is None and s.used_bytes() == 60
        s.create(state("c"), b"c" * 40)  # exactly up to the quota
        assert s.used_bytes() == 100
        assert s.delete("a") and s.used_bytes() == 40  # a deletion gives its bytes back
        s.create(state("b"), b"b" * 60)
        assert s.used_bytes() == 100 and s.get_source("b") == ("r1", b"b" * 60)
    finally:
        s.close()


@pytest.mark.parametrize("kind", ["sqlite", "redis"])
def test_a_scene_that_would_pass_the_quota_is_refused_and_the_session_goes_on(kind, request, tmp_path):
    s = open_store(kind, request, tmp_path, max_bytes=100)
    try:
        s.create(state("a"), b"a" * 50)
        s.create(state("b"), b"b" * 40)
        with pytest.raises(StoreFull):  # 50 → 61 would make 101
            s.update("a", lambda old: replace(old, scene_rev="r2"), source=b"A" * 61)
        assert s.get("a").version == 1 and s.get_source("a") == ("r1", b"a" * 50)  # nothing half-applied
        assert s.used_bytes() == 90
        new = s.update("a", lambda old: replace(old, camera={**CAM, "fov_y": 30.0}))  # a gesture: no scene
        assert new.version == 2
        new = s.update("a", lambda old: replace(old, scene_rev="r3"), source=b"A" * 60)  # 50 → 60: fits
        assert new.version == 3 and s.get_source("a") == ("r3", b"A" * 60) and s.used_bytes() == 100
        new = s.update("a", lambda old: replace(old, scene_rev="r4"), source=b"a" * 10)  # smaller: always
        assert s.get_source("a") == ("r4", b"a" * 10) and s.used_bytes() == 50
    finally:
        s.close()


@pytest.mark.parametrize("kind", ["sqlite", "redis"])
def test_expired_sessions_give_their_bytes_back(kind, request, tmp_path):
    s = open_store(kind, request, tmp_path, max_bytes=100, ttl_s=0.3)
    try:
        s.create(state("old"), b"o" * 80)
        with pytest.raises(StoreFull):
            s.create(state("new"), b"n" * 80)
        time.sleep(0.5)
        s.create(state("new"), b"n" * 80)  # "old" expired: its bytes are free again
        assert s.used_bytes() == 80 and s.get("old") is None
    finally:
        s.close()


@pytest.mark.parametrize("kind", ["sqlite", "redis"])
def test_the_quota_holds_across_processes_writing_at_once(kind, request, tmp_path):
    """Two stores on the same file / Redis (two processes' connections), eight threads each
    creating and replacing scenes: the total never passes the quota and the count is exact."""
    prefix = f"quota-shared-{time.monotonic_ns()}:"
    stores = [open_store(kind, request, tmp_path, max_bytes=1000, prefix=prefix) for _ in range(2)]
    refused = []
    errors: list[BaseException] = []

    def work(i: int) -> None:
        s = stores[i % 2]
        try:
            for j in range(12):
                sid = f"t{i}-{j}"
                try:
                    s.create(state(sid), bytes([65 + i]) * (30 + 7 * j))
                    s.update(sid, lambda old: replace(old, scene_rev="r2"), source=bytes([97 + i]) * (40 + 5 * j))
                except StoreFull:
                    refused.append(sid)
        except BaseException as e:  # pragma: no cover - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    try:
        assert not errors, errors
        assert refused, "the quota was never reached"
        stored = 0
        for i in range(8):
            for j in range(12):
                got = stores[0].get_source(f"t{i}-{j}")
                stored += len(got[1]) if got else 0
        assert stores[0].used_bytes() == stores[1].used_bytes() == stored <= 1000
    finally:
        for s in stores:
            s.close()


def test_the_sqlite_count_is_recounted_when_the_file_is_opened(tmp_path):
    s = SQLiteStore(tmp_path / "s.sqlite3", ttl_s=3600)
    s.create(state("a"), b"a" * 70)
    s.create(state("b"), b"b" * 30)
    s._db.execute("UPDATE usage SET bytes = 5")  # a count gone wrong (a hand edit, an older version)
    s.close()
    reopened = SQLiteStore(tmp_path / "s.sqlite3", ttl_s=3600, max_bytes=120)
    try:
        assert reopened.used_bytes() == 100
        with pytest.raises(StoreFull):
            reopened.create(state("c"), b"c" * 21)
    finally:
        reopened.close()


# ---- the creation rate --------------------------------------------------------------------------------
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


def scene(n: int) -> dict:
    return {
        "materials": [{}],
        "spheres": [
            {
                "center": [(i * 7919) % 97 - 48.5, (i * 104729) % 89 - 44.5, (i * 1299709) % 83 - 41.5],
                "radius": 0.25 + (i % 7) / 10,
            }
            for i in range(n)
        ],
    }


def test_a_store_over_its_quota_refuses_new_scenes_with_507_and_existing_sessions_go_on(tmp_path):
    app = create_app(make_config(tmp_path, warmup=False, max_store_bytes=8 * 1024))
    with TestClient(app) as c:
        store = app.state.store
        sid = new_session(c)["id"]  # a recipe: a few hundred bytes
        used = store.used_bytes()
        assert 0 < used < 1024
        r = c.put(f"/api/sessions/{sid}/scene", json=scene(3000))  # 16 kB stored (npz)
        assert r.status_code == 507, r.text
        assert "POCKETRAY_MAX_STORE_BYTES" in r.json()["detail"] and int(r.headers["retry-after"]) > 0
        got = c.get(f"/api/sessions/{sid}").json()
        assert got["version"] == 1 and got["scene_info"]["n_spheres"] == 64 and store.used_bytes() == used
        n = store.count()
        r = c.post("/api/sessions", json={"scene": scene(3000), "settings": dict(SMALL)})
        assert r.status_code == 507 and store.count() == n and store.used_bytes() == used
        # the session goes on: a gesture, a smaller scene, a new session from a recipe
        assert c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2}).status_code == 200
        assert c.put(f"/api/sessions/{sid}/scene", json=scene(100)).status_code == 200
        assert new_session(c)["id"]
        metrics = c.get("/metrics").text
        assert "pocketray_store_bytes" in metrics
