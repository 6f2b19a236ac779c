"""Soak: honest clients and a hostile one against one ``python -m server`` for a while.

For ``--seconds`` (bounded loops, loopback only):

- ``--users`` clients, each with its own session, loop: a pan (JSON answer), a read of the
  session, a pinch with ``?frame=1`` (the frame), a frame; 503 and 409 are retried as told
  (``Retry-After``). Each client counts the changes the service acknowledged;
- one hostile client loops through the attack of the issue at a bounded rate: stalled bodies
  (headers with ``Content-Length: 100000`` and a few bytes), bodies of 20,000 bad spheres,
  duplicate keys, 1,000-deep nesting, UTF-16, loose types, a refused ``mode=cones`` gesture;
- ``/api/health`` is polled every 100 ms, the server's resident memory sampled every 2 s.

At the end the server is killed (``kill -9``) and restarted on the same SQLite file: every
session's version must be 1 + the changes acknowledged to its client — nothing lost, nothing
applied twice (a refused or timed-out gesture changes nothing).

Usage::

    .venv/bin/python -m bench.soak --seconds 300 --users 4 [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import statistics
import tempfile
import threading
import time
from collections import Counter, defaultdict
from pathlib import Path

import httpx

from bench.child import ServerChild, free_port

ROOT = Path(__file__).resolve().parent.parent

FRAME = {"width": 96, "height": 160, "max_recursion_depth": 2, "samples_per_pixel": 1, "format": "jpeg"}


class Server(ServerChild):
    """A server child (bench/child.py) on ``port`` with the soak's SQLite file and log: killed
    and restarted on the same ones."""

    def __init__(self, root: Path, sqlite: Path, port: int, log: Path):
        super().__init__(root, {"default_render": json.dumps(FRAME)}, sqlite=sqlite, port=port, log=log)

    def rss_mib(self) -> float:
        return self.memory().get("VmRSS", float("nan"))


def pct(values: list[float], q: float) -> float:
    v = sorted(values)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))] if v else float("nan")


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.latency: dict[str, list[float]] = defaultdict(list)
        self.codes: dict[str, Counter] = defaultdict(Counter)

    def add(self, kind: str, seconds: float, code: int) -> None:
        with self.lock:
            self.latency[kind].append(seconds)
            self.codes[kind][code] += 1


def user(url: str, stop: float, stats: Stats, sessions: dict, index: int) -> None:
    with httpx.Client(base_url=url, timeout=120) as c:
        sid = c.post("/api/sessions", json={"scenario": 3, "n": 512, "seed": index}).json()["id"]
        sessions[sid] = 0  # changes acknowledged so far

        def call(kind: str, method: str, path: str, **kw) -> httpx.Response:
            while True:
                t0 = time.perf_counter()
                r = c.request(method, path, **kw)
                stats.add(kind, time.perf_counter() - t0, r.status_code)
                if r.status_code in (409, 503) and time.monotonic() < stop:
                    time.sleep(min(5.0, float(r.headers.get("retry-after", 1))) if r.status_code == 503 else 0.05)
                    continue  # retried as told
                return r

        step = 0
        while time.monotonic() < stop:
            step += 1
            if (
                call(
                    "gesture", "POST", f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": 3, "dy": -2}
                ).status_code
                == 200
            ):
                sessions[sid] += 1
            call("read", "GET", f"/api/sessions/{sid}")
            r = call(
                "gesture+frame",
                "POST",
                f"/api/sessions/{sid}/gesture",
                params={"frame": 1},
                json={"type": "pinch", "scale": 1.01 if step % 2 else 1 / 1.01},
            )
            if r.status_code == 200:
                sessions[sid] += 1
            call("frame", "GET", f"/api/sessions/{sid}/frame")


def hostile(url: str, port: int, stop: float, stats: Stats) -> None:
    bad = (
        b'{"scene":{"materials":[{}],"spheres":['
        + b",".join([b'{"center":[0,0],"radius":-1,"material":-1}'] * 20_000)
        + b"]}}"
    )
    bodies = [
        b'{"type": "pinch", "scale": 2, "scale": 0.5}',
        b"[" * 1000 + b"]" * 1000,
        '{"type": "pinch", "scale": 2}'.encode("utf-16"),
        b'{"type": "pan", "dx": "1", "dy": true}',
    ]
    stalled: list[tuple[float, socket.socket]] = []
    with httpx.Client(base_url=url, timeout=60) as c:
        sid = c.post("/api/sessions", json={"scenario": 1, "n": 8}).json()["id"]
        i = 0
        while time.monotonic() < stop:
            i += 1
            if len(stalled) < 8:  # well below the per-address cap the users share
                s = socket.create_connection(("127.0.0.1", port), timeout=30)
                s.sendall(
                    b"PUT /api/sessions/x/scene HTTP/1.1\r\nHost: s\r\ncontent-type: application/json\r\n"
                    b'content-length: 100000\r\n\r\n{"mat'
                )
                stalled.append((time.monotonic(), s))
            for t_open, s in list(stalled):  # the service closes them (408)
                s.setblocking(False)
                try:
                    got = s.recv(65536)
                except BlockingIOError:
                    continue
                except OSError:
                    got = b""
                stats.add("stalled→closed", time.monotonic() - t_open, 408 if got.startswith(b"HTTP/1.1 408") else 0)
                s.close()
                stalled.remove((t_open, s))
            t0 = time.perf_counter()
            r = c.post("/api/sessions", content=bad, headers={"content-type": "application/json"})
            stats.add("bad 20k spheres", time.perf_counter() - t0, r.status_code)
            for body in bodies:
                t0 = time.perf_counter()
                r = c.post(f"/api/sessions/{sid}/gesture", content=body, headers={"content-type": "application/json"})
                stats.add("bad body", time.perf_counter() - t0, r.status_code)
            t0 = time.perf_counter()
            r = c.post(
                f"/api/sessions/{sid}/gesture",
                params={"frame": 1, "mode": "cones"},
                json={"type": "pan", "dx": 1, "dy": 1},
            )
            stats.add("refused gesture", time.perf_counter() - t0, r.status_code)
            time.sleep(0.5)
        version = c.get(f"/api/sessions/{sid}").json()["version"]
        stats.add("hostile session unchanged", 0.0, 200 if version == 1 else 500)
    for _, s in stalled:
        s.close()


def run_soak(root: Path, seconds: float, users: int) -> dict:
    """The soak against ``root``'s server; the figures (see the module docstring)."""
    tmp = Path(tempfile.mkdtemp(prefix="pocketray-soak-"))
    port = free_port()
    server = Server(root, tmp / "soak.sqlite3", port, tmp / "server.log")
    stats, sessions = Stats(), {}
    t_start = time.monotonic()
    stop = t_start + seconds
    memory: list[tuple[float, float]] = []
    health: list[float] = []

    def sample() -> None:
        with httpx.Client(base_url=server.url, timeout=30) as c:
            next_mem = 0.0
            while time.monotonic() < stop:
                now = time.monotonic()
                if now >= next_mem:
                    memory.append((round(now - t_start), round(server.rss_mib())))
                    next_mem = now + 2.0
                t0 = time.perf_counter()
                c.get("/api/health")
                health.append(time.perf_counter() - t0)
                time.sleep(0.1)

    threads = [threading.Thread(target=user, args=(server.url, stop, stats, sessions, i)) for i in range(users)]
    threads += [threading.Thread(target=hostile, args=(server.url, port, stop, stats)), threading.Thread(target=sample)]
    load0 = os.getloadavg()[0]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    elapsed = time.monotonic() - t_start
    server.kill(signal.SIGKILL)  # a crash: then every acknowledged change must be there
    restarted = Server(root, tmp / "soak.sqlite3", port, tmp / "server.log")
    lost = {}
    with httpx.Client(base_url=restarted.url, timeout=30) as c:
        for sid, acked in sessions.items():
            version = c.get(f"/api/sessions/{sid}").json()["version"]
            if version != 1 + acked:
                lost[sid] = {"acknowledged": acked, "version": version}
    restarted.kill(signal.SIGTERM)
    kinds = {}
    for kind, values in stats.latency.items():
        kinds[kind] = {
            "n": len(values),
            "per_s": round(len(values) / elapsed, 2),
            "p50_ms": round(1e3 * statistics.median(values), 1),
            "p99_ms": round(1e3 * pct(values, 0.99), 1),
            "codes": {str(k): v for k, v in stats.codes[kind].items()},
        }
    rss = [m for _, m in memory]
    return {
        "seconds": round(elapsed),
        "users": users,
        "loadavg_start": load0,
        "loadavg_end": os.getloadavg()[0],
        "honest_requests_per_s": round(
            sum(len(stats.latency[k]) for k in ("gesture", "read", "gesture+frame", "frame")) / elapsed, 2
        ),
        "kinds": kinds,
        "health": {
            "n": len(health),
            "p50_ms": round(1e3 * statistics.median(health), 1),
            "p99_ms": round(1e3 * pct(health, 0.99), 1),
            "max_ms": round(1e3 * max(health), 1),
        },
        "rss_mib": {
            "start": rss[0],
            "max": max(rss),
            "end": rss[-1],
            "every_60_s": [m for t, m in memory if t % 60 < 2],
        },
        "memory": memory,
        "sessions": len(sessions),
        "acknowledged_changes": sum(sessions.values()),
        "lost": lost,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=300)
    ap.add_argument("--users", type=int, default=4)
    ap.add_argument("--root", type=Path, default=ROOT)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    result = run_soak(args.root, args.seconds, args.users)
    print(json.dumps({k: v for k, v in result.items() if k != "memory"}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
