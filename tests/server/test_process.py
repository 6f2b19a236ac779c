"""Against real ``python -m server`` processes (uvicorn): restart, crash, load, scale-out."""

from __future__ import annotations

import io
import json
import signal
from concurrent.futures import ThreadPoolExecutor

import httpx
import numpy as np
import pytest
from pocketray_server_support import SMALL, new_session

pytestmark = pytest.mark.long  # server processes, Redis, crashes and restarts


def test_sessions_survive_a_crash_and_a_restart(spawn_server):
    a = spawn_server()
    a.wait_ready()
    with httpx.Client(base_url=a.url, timeout=30) as c:
        sid = new_session(c)["id"]
        c.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": 12, "dy": -7})
        c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 1.5})
        c.patch(f"/api/sessions/{sid}/settings", json={"mode": "normal", "format": "npy"})
        before = c.get(f"/api/sessions/{sid}").json()
        other = new_session(c, scenario=2, n=40)["id"]
    assert before["version"] == 4
    a.kill(signal.SIGKILL)  # a crash: no shutdown code runs

    b = spawn_server()  # same SQLite file
    b.wait_ready()
    with httpx.Client(base_url=b.url, timeout=30) as c:
        assert c.get(f"/api/sessions/{sid}").json() == before
        assert c.get(f"/api/sessions/{other}").json()["scene_info"]["n"] == 40
        r = c.get(f"/api/sessions/{sid}/frame")
        assert r.status_code == 200 and r.headers["x-session-version"] == "4"
        assert np.load(io.BytesIO(r.content)).shape == (SMALL["height"], SMALL["width"], 3)
        # and a clean restart
        c.post(f"/api/sessions/{sid}/gesture", json={"type": "reset"})
    b.kill(signal.SIGTERM)
    c2 = spawn_server()
    with httpx.Client(base_url=c2.url, timeout=30) as c:
        got = c.get(f"/api/sessions/{sid}").json()
        assert got["version"] == 5 and got["camera"]["position"] == [0.0, 0.0, 100.0]
        assert "/api/sessions" in c.get("/openapi.json").json()["paths"]
        assert c.get("/docs").status_code == 200


def test_twenty_parallel_renders_answer_200_or_503_and_the_service_stays_healthy(spawn_server):
    s = spawn_server(queue_size=3)
    s.wait_ready()
    with httpx.Client(base_url=s.url, timeout=60) as c:
        sid = new_session(c)["id"]
    scene = {"materials": [{}], "spheres": [{"center": [0, 0, 0], "radius": 5}]}

    def one(i: int) -> httpx.Response:
        with httpx.Client(base_url=s.url, timeout=60) as c:
            if i % 2:
                return c.get(f"/api/sessions/{sid}/frame", params={"width": 64, "height": 96, "max_recursion_depth": 2})
            return c.post(
                "/api/render", json={"scene": scene, "settings": {"width": 64, "height": 96, "max_recursion_depth": 2}}
            )

    with ThreadPoolExecutor(20) as pool:
        answers = list(pool.map(one, range(20)))
    codes = [r.status_code for r in answers]
    # 409: a session frame superseded by a newer one of the same session (latest wins).
    assert set(codes) <= {200, 409, 503}, codes
    assert 200 in codes
    for i, r in enumerate(answers):
        if r.status_code == 409:
            assert i % 2 and "superseded" in r.json()["detail"]
        elif r.status_code == 503:
            assert int(r.headers["retry-after"]) >= 1 and "queue" in r.json()["detail"]
        else:
            assert r.headers["content-type"] == "image/png"
    with httpx.Client(base_url=s.url, timeout=60) as c:
        assert c.get("/api/health").json() == {"status": "ok"}
        assert c.get("/api/ready").json()["ready"] is True
        assert c.get(f"/api/sessions/{sid}/frame").status_code == 200


def test_scale_out_two_processes_share_sessions_through_redis(spawn_server, redis_url, tmp_path):
    conf = {"state_backend": "redis", "redis_url": redis_url, "redis_prefix": f"t{tmp_path.name}:"}
    a = spawn_server(**conf)
    b = spawn_server(**conf)
    a.wait_ready()
    b.wait_ready()
    with httpx.Client(base_url=a.url, timeout=30) as ca, httpx.Client(base_url=b.url, timeout=30) as cb:
        sid = new_session(ca, n=50)["id"]
        q = {"format": "npy", "mode": "primid"}
        first = np.load(io.BytesIO(ca.get(f"/api/sessions/{sid}/frame", params=q).content))
        # gestures on B …
        assert cb.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": 10, "dy": 4}).status_code == 200
        r = cb.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 2})
        moved = r.json()
        assert moved["version"] == 3
        # … are seen and rendered by A
        got = ca.get(f"/api/sessions/{sid}").json()
        assert got["version"] == 3 and got["camera"] == moved["camera"]
        fa = ca.get(f"/api/sessions/{sid}/frame", params=q)
        assert fa.status_code == 200 and fa.headers["x-session-version"] == "3"
        frame_a = np.load(io.BytesIO(fa.content))
        frame_b = np.load(io.BytesIO(cb.get(f"/api/sessions/{sid}/frame", params=q).content))
        assert np.array_equal(frame_a, frame_b) and not np.array_equal(frame_a, first)
        # a scene replaced through B is the one A renders (no stale per-process cache)
        scene = {"materials": [{}], "spheres": [{"center": [0, 0, 0], "radius": 3}, {"center": [8, 0, 0], "radius": 2}]}
        assert cb.put(f"/api/sessions/{sid}/scene", json=scene).json() == {"version": 4}
        r = ca.get(f"/api/sessions/{sid}/frame")
        assert json.loads(r.headers["x-stats"])["primitives"] == 2
        assert len(ca.get(f"/api/sessions/{sid}/scene").json()["spheres"]) == 2
        assert ca.delete(f"/api/sessions/{sid}").status_code == 204
        assert cb.get(f"/api/sessions/{sid}").status_code == 404
        assert ca.get("/api/info").json()["state_backend"] == "redis"


def test_redis_outage_is_503_not_500(spawn_server, tmp_path):
    from pocketray_server_support import free_port

    s = spawn_server(state_backend="redis", redis_url=f"redis://127.0.0.1:{free_port()}/0")  # nobody there
    # past its warm-up frame (ready's 503 while it starts is not the outage's): ready speaks of Redis alone
    s.wait_ready()
    with httpx.Client(base_url=s.url, timeout=30) as c:
        r = c.post("/api/sessions", json={"scenario": 1, "n": 8})
        assert r.status_code == 503 and r.headers["retry-after"] == "1" and "state" in r.json()["detail"]
        # Redis is every process's: its outage is the requests' 503, not this process out of a balancer
        # (which would take them all out at once and answer its own 503 instead of this one).
        assert c.get("/api/ready").status_code == 200
        assert c.get("/api/health").status_code == 200
