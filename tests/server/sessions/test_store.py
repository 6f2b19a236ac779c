"""State backends (SQLite, Redis) behind one interface: atomic changes, versions, expiry; the quota
of stored bytes; store faults under the service.

The quota: without it, one address created 5,254 sessions in 60 s, each holding its scene (up
to a 16 MB model) for the 24 h idle TTL. Now ``POCKETRAY_MAX_STORE_BYTES`` (507 + Retry-After
for a new session or a scene change that would pass it; nothing written; existing sessions go
on), the bytes counted by the store itself — SQLite and Redis, several processes alike (the
creation rate per address is sessions/test_ratelimit.py's). A store file broken, deleted or
corrupt, or a Redis that keeps failing, is 503 and ``/api/ready`` says so, never a 500.
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time
import warnings
from dataclasses import replace
from pathlib import Path

import pytest

with warnings.catch_warnings():  # as in conftest.py: the TestClient still speaks httpx
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from pocketray_server_support import SMALL, make_config, new_session

from server.app import create_app
from server.sessions.store import RedisStore, SessionState, SQLiteStore, StoreFull, StoreStartupError, StoreUnavailable

CAM = {"position": [0.0, 0.0, 100.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 60.0}


def state(sid: str = "s1", rev: str = "r1") -> SessionState:
    return SessionState(
        id=sid,
        version=1,
        camera=CAM,
        home_camera=CAM,
        settings={"width": 8},
        scene_info={"n_spheres": 1, "n_planes": 0},
        scene_rev=rev,
    )


@pytest.fixture(params=["sqlite", "redis"])
def store(request, tmp_path):
    if request.param == "sqlite":
        s = SQLiteStore(tmp_path / "s.sqlite3", ttl_s=3600)
    else:
        url = request.getfixturevalue("redis_url")
        s = RedisStore(url, ttl_s=3600, prefix=f"test-{time.monotonic_ns()}:")
    yield s
    s.close()


def test_create_get_update_bumps_version(store):
    store.create(state(), b"source-1")
    assert store.get("s1").version == 1
    new = store.update("s1", lambda old: replace(old, camera={**CAM, "fov_y": 30.0}))
    assert new.version == 2 and new.camera["fov_y"] == 30.0
    assert store.get("s1") == replace(new, accessed_at=store.get("s1").accessed_at)
    assert store.get_source("s1") == ("r1", b"source-1")
    store.update("s1", lambda old: replace(old, scene_rev="r2"), source=b"source-2")
    assert store.get_source("s1") == ("r2", b"source-2")
    assert store.get("s1").version == 3


def test_failed_mutation_changes_nothing(store):
    store.create(state(), b"src")

    def boom(old):
        raise ValueError("rejected")

    with pytest.raises(ValueError):
        store.update("s1", boom, source=b"other")
    assert store.get("s1").version == 1
    assert store.get_source("s1") == ("r1", b"src")


def test_sessions_are_separate_and_delete(store):
    store.create(state("a"), b"A")
    store.create(state("b"), b"B")
    store.update("a", lambda old: replace(old, settings={"width": 99}))
    assert store.get("b").settings == {"width": 8} and store.get("b").version == 1
    assert store.delete("a") is True
    assert store.get("a") is None and store.get_source("a") is None
    assert store.update("a", lambda old: old) is None
    assert store.delete("a") is False
    assert store.get_source("b") == ("r1", b"B")


def test_concurrent_updates_lose_nothing(store):
    store.create(state(), b"src")

    def work():
        done = 0
        while done < 25:  # a change that collided more than the store's retries is refused: retry it
            try:
                store.update("s1", lambda old: replace(old, settings={"width": old.settings["width"] + 1}))
                done += 1
            except StoreUnavailable:
                pass

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    got = store.get("s1")
    assert got.version == 101 and got.settings["width"] == 8 + 100


def test_sqlite_idle_expiry_and_reopen(tmp_path):
    path = tmp_path / "s.sqlite3"
    s = SQLiteStore(path, ttl_s=0.3, touch_interval_s=0.0)
    s.create(state("old"), b"x")
    s.create(state("kept"), b"y")
    for _ in range(4):  # reads keep "kept" alive
        time.sleep(0.1)
        assert s.get("kept") is not None
    time.sleep(0.1)
    assert s.get("old") is None  # idle longer than the TTL
    s.close()
    reopened = SQLiteStore(path, ttl_s=3600)
    assert reopened.get("kept").version == 1 and reopened.get("old") is None
    reopened.close()


def test_redis_idle_expiry(redis_url):
    s = RedisStore(redis_url, ttl_s=0.3, prefix="test-expiry:", touch_interval_s=0.0)
    s.create(state("gone"), b"x")
    assert s.get("gone") is not None
    time.sleep(0.5)
    assert s.get("gone") is None and s.get_source("gone") is None
    s.close()


def test_sessions_expire_after_the_idle_time(tmp_path):
    from fastapi.testclient import TestClient
    from pocketray_server_support import make_config

    from server.app import create_app

    with TestClient(create_app(make_config(tmp_path, session_ttl_s=1.0, warmup=False))) as c:
        idle = new_session(c)["id"]
        busy = new_session(c)["id"]
        for _ in range(6):
            time.sleep(0.25)
            assert c.get(f"/api/sessions/{busy}").status_code == 200  # use keeps it alive
        assert c.get(f"/api/sessions/{idle}").status_code == 404


@pytest.fixture
def own_store(tmp_path):
    """An app on its own SQLite file (the tests below break it)."""
    with TestClient(create_app(make_config(tmp_path)), raise_server_exceptions=False) as c:
        yield c, tmp_path / "sessions.sqlite3"


def wait_ready_status(c, want: int) -> dict:
    deadline = time.monotonic() + 60
    while True:
        r = c.get("/api/ready")
        if r.status_code == want or time.monotonic() > deadline:
            return {"status": r.status_code, **r.json()}
        time.sleep(0.1)


def assert_store_503(r) -> None:
    assert r.status_code == 503 and r.headers.get("retry-after"), (r.status_code, r.text)
    detail = r.json()["detail"]
    assert detail.startswith("state: ") and "/" not in detail and "Traceback" not in detail, detail


def test_a_store_file_overwritten_with_junk_is_503_and_not_ready(own_store):
    """Rules out: 500 "DatabaseError", dropped connections, and /api/ready 200."""
    c, path = own_store
    assert wait_ready_status(c, 200)["status"] == 200
    sid = new_session(c)["id"]
    junk = os.urandom(path.stat().st_size)
    with open(path, "r+b") as f:  # the same file (inode), its bytes replaced
        f.write(junk)
    assert_store_503(c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2}))
    assert_store_503(c.get(f"/api/sessions/{sid}"))
    ready = wait_ready_status(c, 503)
    assert ready["status"] == 503 and ready["detail"].startswith("state backend: sqlite"), ready


def test_a_deleted_store_file_refuses_writes_instead_of_losing_them(own_store):
    """Rules out: writes acknowledged after the file was deleted, gone at the restart."""
    c, path = own_store
    sid = new_session(c)["id"]
    for suffix in ("", "-wal", "-shm"):
        Path(str(path) + suffix).unlink(missing_ok=True)
    r = c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2})
    assert_store_503(r)
    assert "deleted" in r.json()["detail"] and "restart" in r.json()["detail"]
    assert_store_503(c.post("/api/sessions", json={"scenario": 1, "n": 4}))
    ready = wait_ready_status(c, 503)
    assert ready["status"] == 503 and "deleted" in ready["detail"], ready


def test_a_corrupt_store_file_at_start_up_is_moved_aside_or_refused(tmp_path):
    """Rules out: the process exiting with a traceback. A setting says which of the two happens;
    neither loses the file."""
    path = tmp_path / "sessions.sqlite3"
    path.write_bytes(b"this is not a database, it is junk" * 100)
    with pytest.raises(StoreStartupError) as e:
        SQLiteStore(path, ttl_s=60, on_corrupt="refuse")
    assert "POCKETRAY_SQLITE_ON_CORRUPT=move_aside" in str(e.value) and "mv " in str(e.value)
    assert path.read_bytes().startswith(b"this is not")  # refused: untouched
    store = SQLiteStore(path, ttl_s=60, on_corrupt="move_aside")
    (aside,) = tmp_path.glob("sessions.sqlite3.corrupt-*")
    assert aside.read_bytes().startswith(b"this is not") and store.probe() is None
    store.create(
        SessionState(id="s", version=1, camera={}, home_camera={}, settings={}, scene_info={}, scene_rev="r"), b"x"
    )
    assert store.get("s").version == 1
    store.close()


def test_a_server_refusing_a_corrupt_store_says_how_to_recover(tmp_path):
    import subprocess
    import sys

    from pocketray_server_support import ROOT, server_env

    path = tmp_path / "sessions.sqlite3"
    path.write_bytes(b"junk" * 1000)
    env = server_env(path, sqlite_on_corrupt="refuse", warmup="false")
    done = subprocess.run(
        [sys.executable, "-m", "server"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode != 0
    assert "is not a readable SQLite database" in done.stderr and "POCKETRAY_SQLITE_ON_CORRUPT" in done.stderr


def test_store_failures_of_every_kind_are_503_never_500(own_store, monkeypatch):
    c, _ = own_store
    store = c.app.state.store
    sid = new_session(c)["id"]
    for exc in (
        sqlite3.DatabaseError("file is not a database"),
        sqlite3.InterfaceError("bad binding"),
        StoreUnavailable("holding a session record that does not decode (JSONDecodeError)"),
    ):

        def broken(*args, exc=exc, **kwargs):
            raise exc

        monkeypatch.setattr(store, "get", broken)
        assert_store_503(c.get(f"/api/sessions/{sid}"))
    monkeypatch.undo()
    # A scene source the store holds that is no scene.
    c.app.state.service.cache.drop_session(sid)
    monkeypatch.setattr(store, "get_source", lambda session_id: ("rev", b"A" + b"not an npz"))
    assert_store_503(c.get(f"/api/sessions/{sid}/frame"))


def test_redis_change_retries_are_capped_and_end_in_503(redis_url):
    """Rules out: a WATCH conflict retried forever."""
    import redis

    store = RedisStore(redis_url, ttl_s=60, prefix=f"capped-{time.monotonic_ns()}:", max_retries=2)
    other = redis.Redis.from_url(redis_url)
    cam = {"position": [0, 0, 1], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60}
    store.create(
        SessionState(id="s", version=1, camera=cam, home_camera=cam, settings={}, scene_info={}, scene_rev="r"), b"x"
    )
    attempts = []

    def collide(old):
        attempts.append(old.version)
        other.set(f"{store.prefix}state:s", store.client.get(f"{store.prefix}state:s"))  # another process wrote
        return old

    with pytest.raises(StoreUnavailable) as e:
        store.update("s", collide)
    assert len(attempts) == 3 and "busy" in str(e.value)
    assert store.get("s").version == 1
    other.close()
    store.close()


def test_a_redis_read_refreshes_the_ttl_in_one_command(redis_url):
    """Rules out: a MULTI/EXEC transaction (two PEXPIREs) per read past the touch interval."""
    import redis

    store = RedisStore(redis_url, ttl_s=3600, prefix=f"getex-{time.monotonic_ns()}:", touch_interval_s=60)
    cam = {"position": [0, 0, 1], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 60}
    store.create(
        SessionState(
            id="s", version=1, camera=cam, home_camera=cam, settings={}, scene_info={}, scene_rev="r", accessed_at=0.0
        ),
        b"x",
    )
    admin = redis.Redis.from_url(redis_url)
    k_state = f"{store.prefix}state:s"
    admin.pexpire(k_state, 5_000)

    def calls() -> dict[str, int]:
        stats = admin.info("commandstats")
        return {k.split("_", 1)[1]: v["calls"] for k, v in stats.items()}

    store.get("s")  # the first read also refreshes the scene key
    before = calls()
    for _ in range(5):
        assert store.get("s").version == 1
    after = calls()
    delta = {k: after.get(k, 0) - before.get(k, 0) for k in ("getex", "get", "multi", "exec", "pexpire")}
    assert delta == {"getex": 5, "get": 0, "multi": 0, "exec": 0, "pexpire": 0}, delta
    assert admin.pttl(k_state) > 3_000_000  # refreshed to the idle TTL (3600 s) by the read
    admin.close()
    store.close()


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


@pytest.mark.parametrize("backend", ["sqlite", "redis"])
def test_room_is_what_a_session_may_grow_to(backend, tmp_path, request):
    """``room``: the quota less the others' bytes (the session's own counted as free), expired
    sessions given back first; None without a quota."""
    if backend == "sqlite":
        s = SQLiteStore(tmp_path / "s.sqlite3", ttl_s=0.5, max_bytes=1000)
        unlimited = SQLiteStore(tmp_path / "u.sqlite3", ttl_s=60)
    else:
        url = request.getfixturevalue("redis_url")
        s = RedisStore(url, ttl_s=0.5, prefix="test-room:", max_bytes=1000)
        unlimited = RedisStore(url, ttl_s=60, prefix="test-room-u:")
    try:
        assert unlimited.room("a") is None
        s.create(state("a"), b"x" * 300)
        s.create(state("b"), b"x" * 200)
        assert s.room("a") == 1000 - 200 and s.room("b") == 1000 - 300 and s.room("c") == 500
        time.sleep(0.7)  # both expired: their bytes are given back
        assert s.room("c") == 1000
    finally:
        s.close()
        unlimited.close()
