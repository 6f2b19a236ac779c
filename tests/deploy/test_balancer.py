"""The balancer's configuration (server/tools/stack.py:haproxy_config) run by the real HAProxy in front of
stand-in render processes (tests/deploy/fake_render.py: no GL, killed in milliseconds): its own
errors are JSON with Retry-After, each client address is capped with a 429, a request a process
dropped is re-sent only when that is harmless (a GET) — a gesture is never applied twice — and a
process whose port refuses is out of rotation at once, not after its health checks fail. The
whole stack with render processes runs in tests/server/tools/test_stack.py."""

from __future__ import annotations

import csv
import io
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from server.tools.stack import SESSION_HEADER, find_executable, free_port, haproxy_config

FAKE = Path(__file__).with_name("fake_render.py")


class Balancer:
    """HAProxy with ``haproxy_config`` before fake render processes of the given modes (``None``: a
    closed port), and its stats page as CSV."""

    def __init__(self, tmp: Path, modes: list[str | None], **config):
        self.tmp, self.procs, self.logs = tmp, [], []
        servers = []
        for i, mode in enumerate(modes):
            port = free_port()
            log = tmp / f"render{i}.log"
            log.touch()
            self.logs.append(log)
            if mode is not None:
                self.procs.append(subprocess.Popen([sys.executable, str(FAKE), str(port), mode, str(log)]))
            servers.append((f"render{i}", f"127.0.0.1:{port}"))
        self.ports = [int(address.rsplit(":", 1)[1]) for _, address in servers]
        self.port, self.stats_port = free_port(), free_port()
        self.haproxy = None
        try:
            cfg = tmp / "haproxy.cfg"
            cfg.write_text(
                haproxy_config(f"127.0.0.1:{self.port}", servers, stats_bind=f"127.0.0.1:{self.stats_port}", **config)
            )
            self.haproxy = subprocess.Popen(
                [find_executable("haproxy"), "-db", "-f", str(cfg)], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT
            )
            self.url = f"http://127.0.0.1:{self.port}"
            up = sum(mode is not None for mode in modes)
            deadline = time.monotonic() + 20
            # HAProxy listens (its stats page lists every server: it bound its ports, the front one too)
            # and every live stand-in passed a check; with none live, the first alone (a loaded machine
            # may take a while to start it).
            while len(st := self.status()) < len(modes) or sum(s == "UP" for s in st.values()) < up:
                assert time.monotonic() < deadline, st
                time.sleep(0.05)
        except BaseException:
            self.close()
            raise

    def stats(self) -> dict[str, dict[str, str]]:
        """Each server's row of HAProxy's stats page (``status``: UP, DOWN, …; ``wretr``: retries on
        it; ``wredis``: requests it failed that went on to another; ``stot``: requests sent to it)."""
        try:
            text = httpx.get(f"http://127.0.0.1:{self.stats_port}/;csv", timeout=5).text
        except httpx.HTTPError:
            return {}
        rows = csv.DictReader(io.StringIO(text.lstrip("# ")))
        return {r["svname"]: r for r in rows if r["pxname"] == "render" and r["svname"] not in ("FRONTEND", "BACKEND")}

    def status(self) -> dict[str, str]:
        """Each server's state on HAProxy's stats page (UP, DOWN, …)."""
        return {name: row["status"].split()[0] for name, row in self.stats().items()}

    def seen(self, i: int) -> list[str]:
        return self.logs[i].read_text().splitlines()

    def close(self) -> None:
        for p in (self.haproxy, *self.procs):
            if p is not None:
                p.kill()
                p.wait()


@pytest.fixture
def balancer(tmp_path):
    made: list[Balancer] = []

    def make(modes: list[str | None], **config) -> Balancer:
        made.append(Balancer(tmp_path, modes, **config))
        return made[-1]

    yield make
    for b in made:
        b.close()


def assert_balancer_json(r: httpx.Response, status: int, retry: bool = True) -> str:
    assert r.status_code == status, (r.status_code, r.text)
    assert r.headers["content-type"] == "application/json", r.headers
    assert ("retry-after" in r.headers) == retry and r.headers.get("retry-after", "1") == "1", r.headers
    assert "x-served-by" not in r.headers  # HAProxy's own answer, not a process's
    detail = r.json()["detail"]
    assert detail.startswith("balancer: "), detail
    return detail


def test_the_balancers_own_errors_are_json_with_retry_after(balancer):
    """Rules out: HAProxy's HTML pages ("<html><body><h1>503 Service Unavailable</h1>…"), no Retry-After."""
    b = balancer([None, None])  # no render process at all
    r = httpx.get(b.url + "/api/info", timeout=10)
    assert "no render process" in assert_balancer_json(r, 503)
    assert r.headers["connection"] == "close"


def _hold(port: int, source: str) -> tuple[socket.socket, bytes]:
    """A kept-alive connection from ``source`` that sent one GET: the socket and the answer's head."""
    s = socket.create_connection(("127.0.0.1", port), timeout=5, source_address=(source, 0))
    s.sendall(b"GET /api/info HTTP/1.1\r\nHost: pocketray\r\n\r\n")
    return s, s.recv(65536)


def test_each_client_address_is_capped_at_the_balancer_with_a_429(balancer):
    """Rules out: no cap at the balancer, and the render processes' own cap counted every client as the
    balancer's one address (80 clients: 429s, both processes ejected)."""
    b = balancer(["ok"], client_cap=2)
    held = [_hold(b.port, "127.0.0.1") for _ in range(2)]
    assert all(head.startswith(b"HTTP/1.1 200") for _, head in held)
    over, head = _hold(b.port, "127.0.0.1")  # the third at once from the same address
    assert head.startswith(b"HTTP/1.1 429"), head
    assert b"retry-after: 1" in head.lower() and b"application/json" in head and b"at most 2" in head
    other, head = _hold(b.port, "127.0.0.2")  # another client is not affected
    assert head.startswith(b"HTTP/1.1 200"), head
    for s in (over, other, *(s for s, _ in held)):
        s.close()
    time.sleep(0.2)
    assert httpx.get(b.url + "/api/info", timeout=5).status_code == 200  # closed ones no longer count


def test_the_render_processes_learn_each_clients_address(balancer):
    """Rules out: no X-Forwarded-For, so the limits a render process keeps per client address (sessions
    created, large-body slots) counted every client of the stack as the balancer's one address."""
    b = balancer(["ok"])
    for source in ("127.0.0.3", "127.0.0.4"):
        with httpx.Client(transport=httpx.HTTPTransport(local_address=source), timeout=10) as c:
            r = c.get(b.url + "/api/info")
        assert r.status_code == 200 and r.json()["forwarded_for"] == source, r.text


def test_a_dropped_get_is_resent_and_a_dropped_gesture_is_not(balancer):
    """A process that dies while it works on a request: a GET goes to the other process (was: 502), a
    POST is answered 502 and never sent a second time — the process may have applied it."""
    b = balancer(["drop", "ok"])
    for i in range(12):
        r = httpx.get(b.url + f"/api/sessions/s{i}/frame", headers={SESSION_HEADER: f"s{i}"}, timeout=10)
        assert r.status_code == 200, (i, r.status_code, r.text)
    assert b.seen(0), "no GET reached the dropping process: nothing was tested"
    answers = {}
    for i in range(12):  # a new connection each: the first request of one
        with httpx.Client(base_url=b.url, timeout=10) as c:
            answers[i] = c.post(
                f"/api/sessions/s{i}/gesture", content=f"gesture-{i}", headers={SESSION_HEADER: f"s{i}"}
            )
    sent = [line for i in (0, 1) for line in b.seen(i) if line.startswith("POST")]
    for i, r in answers.items():
        assert sum(line.endswith(f" gesture-{i}") for line in sent) == 1, (i, sent)  # never twice
        if r.status_code != 200:
            assert "may have been applied" in assert_balancer_json(r, 502)
    assert any(r.status_code == 502 for r in answers.values()), "no gesture reached the dropping process"


def test_a_killed_process_is_out_of_rotation_at_once(balancer):
    """Rules out: in rotation until two health checks failed (≈ 1–2 s): 648 requests answered 503 meanwhile."""
    b = balancer(["ok", "ok"])
    b.procs[0].send_signal(signal.SIGKILL)
    b.procs[0].wait()
    codes, waits = [], []
    with httpx.Client(base_url=b.url, timeout=10) as c:
        for i in range(8):
            t0 = time.monotonic()
            codes.append(c.get(f"/api/sessions/s{i}", headers={SESSION_HEADER: f"s{i}"}).status_code)
            waits.append(time.monotonic() - t0)
    stats = b.stats()
    status = {name: row["status"].split()[0] for name, row in stats.items()}
    assert codes == [200] * 8
    assert status["render0"] == "DOWN" and status["render1"] == "UP", (status, waits)
    # HAProxy's retry after a refused connection waits a whole second (its fixed turn-around) when it
    # retries the same server, and not when it redispatches: every request the killed process refused
    # went on to the other at once (read from HAProxy's counters, not from a clock a loaded machine slows).
    killed = {k: int(stats["render0"][k] or 0) for k in ("wretr", "wredis", "stot")}
    assert killed["wretr"] == 0 and killed["wredis"] == killed["stot"], (
        f"a refused connection was retried on the killed process (a second's wait) before the other: {killed}, {waits}"
    )
