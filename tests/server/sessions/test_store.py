"""State backends (SQLite, Redis) behind one interface: atomic changes, versions, expiry."""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import pytest
from pocketray_server_support import new_session

from server.sessions.store import RedisStore, SessionState, SQLiteStore, StoreUnavailable

CAM = {"position": [0.0, 0.0, 100.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 60.0}


def state(sid: str = "s1") -> SessionState:
    return SessionState(
        id=sid,
        version=1,
        camera=CAM,
        home_camera=CAM,
        settings={"width": 8},
        scene_info={"n_spheres": 1, "n_planes": 0},
        scene_rev="r1",
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
