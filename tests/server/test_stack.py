"""The scale-out topology on loopback (server/stack.py, ``./dev stack``): Redis with its AOF,
two render processes and HAProxy hashing on X-Session-Id. Sessions are driven through the
balancer: both processes serve, each session stays on one process, a killed process is routed
around (its sessions move to the other, from Redis, with nothing lost), and every write that
was acknowledged is found afterwards."""

from __future__ import annotations

import json
from collections import Counter

import httpx
import pytest

from pocketray_server_support import SMALL, TEST_CAPS
from server.stack import SERVED_BY_HEADER, SESSION_HEADER, Stack

pytestmark = pytest.mark.gl   # the render processes make GL contexts

SESSIONS = 8
ROUNDS_BEFORE = 3     # gestures per session before the kill
ROUNDS_AFTER = 3      # and after it


def stack_env() -> dict[str, str]:
    env = {f"POCKETRAY_{k.upper()}": json.dumps(v) if isinstance(v, dict) else str(v) for k, v in TEST_CAPS.items()}
    env["POCKETRAY_LOG_LEVEL"] = "warning"
    return env


@pytest.fixture
def stack(tmp_path):
    with Stack(processes=2, workdir=tmp_path / "stack", env=stack_env()) as s:
        yield s


def test_sessions_through_the_balancer_survive_a_killed_process(stack, capsys):
    acked: dict[str, list[dict]] = {}   # session → the camera after each acknowledged write, in order
    served = Counter()
    home: dict[str, str] = {}           # session → the process its requests reach

    def gesture(c: httpx.Client, sid: str, i: int) -> httpx.Response:
        r = c.post(f"/api/sessions/{sid}/gesture", params={"frame": 1, "format": "npy", "mode": "primid"},
                   json={"type": "pan", "dx": 3 + i, "dy": -2}, headers={SESSION_HEADER: sid})
        served[r.headers.get(SERVED_BY_HEADER)] += 1
        return r

    with httpx.Client(base_url=stack.url, timeout=60) as c:
        for _ in range(SESSIONS):
            r = c.post("/api/sessions", json={"scenario": 3, "n": 64, "seed": 1, "settings": dict(SMALL)})
            assert r.status_code == 201, r.text
            served[r.headers.get(SERVED_BY_HEADER)] += 1
            acked[r.json()["id"]] = []
        for i in range(ROUNDS_BEFORE):
            for sid in acked:
                r = gesture(c, sid, i)
                assert r.status_code == 200, r.text
                assert r.headers["x-session-version"] == str(2 + i)
                owner = r.headers[SERVED_BY_HEADER]
                assert home.setdefault(sid, owner) == owner, "a session moved between healthy processes"
                acked[sid].append(c.get(f"/api/sessions/{sid}", headers={SESSION_HEADER: sid}).json()["camera"])
        before = Counter(home.values())
        assert set(before) == {"render0", "render1"}, f"one process served every session: {before}"

        stack.kill(0)   # SIGKILL: render0's scene cache and refit trees are gone; Redis has the sessions
        moved = {sid for sid, owner in home.items() if owner == "render0"}
        for i in range(ROUNDS_BEFORE, ROUNDS_BEFORE + ROUNDS_AFTER):
            for sid in acked:
                r = gesture(c, sid, i)
                assert r.status_code == 200, (sid, r.status_code, r.text)
                assert r.headers[SERVED_BY_HEADER] == "render1"
                assert r.headers["x-session-version"] == str(2 + i)
                acked[sid].append(c.get(f"/api/sessions/{sid}", headers={SESSION_HEADER: sid}).json()["camera"])

        found = {sid: c.get(f"/api/sessions/{sid}", headers={SESSION_HEADER: sid}).json() for sid in acked}
    writes_acked = sum(len(v) for v in acked.values())
    writes_found = sum(s["version"] - 1 for s in found.values())
    for sid, state in found.items():
        assert state["version"] == 1 + len(acked[sid])
        assert state["camera"] == acked[sid][-1]
    assert writes_found == writes_acked == SESSIONS * (ROUNDS_BEFORE + ROUNDS_AFTER)
    assert (stack.workdir / "appendonlydir").is_dir() or any(stack.workdir.glob("*.aof"))
    with capsys.disabled():
        print(f"\nstack: requests per process {dict(served)}; sessions per process before the kill "
              f"{dict(before)}, {len(moved)} moved to render1; writes acknowledged {writes_acked}, "
              f"found {writes_found}")


def test_a_stopping_process_drains_its_readiness_fails_at_once_and_the_balancer_routes_around_it(stack):
    import signal
    import time

    victim = stack.renders[1]
    with httpx.Client(base_url=stack.url, timeout=60) as c:
        sids = [c.post("/api/sessions", json={"scenario": 1, "n": 27, "settings": dict(SMALL)}).json()["id"]
                for _ in range(6)]
        victim.proc.send_signal(signal.SIGTERM)
        t0 = time.monotonic()
        r = httpx.get(f"http://127.0.0.1:{victim.port}/api/ready", timeout=5)
        assert r.status_code == 503 and r.json()["detail"].startswith("draining")
        assert httpx.get(f"http://127.0.0.1:{victim.port}/api/health", timeout=5).status_code == 200
        answers = []
        while victim.alive and time.monotonic() - t0 < 30:   # during the drain and after the exit
            for sid in sids:
                answers.append(c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 1.01},
                                      headers={SESSION_HEADER: sid}))
        victim.proc.wait(timeout=30)
        assert time.monotonic() - t0 >= stack.drain_s * 0.9   # it served for the drain, then stopped
        for sid in sids:
            answers.append(c.post(f"/api/sessions/{sid}/gesture", json={"type": "pinch", "scale": 1.01},
                                  headers={SESSION_HEADER: sid}))
    assert [r.status_code for r in answers] == [200] * len(answers)
    assert answers[-1].headers[SERVED_BY_HEADER] == "render0"
