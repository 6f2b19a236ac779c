"""The hardening figures, measured against a real ``python -m server`` on loopback.

Each part starts its own server (defaults but a temporary SQLite file; ``--root`` picks the
checkout it runs, so the same script measures an older commit for the "before" column) and
reads the server process's resident memory from ``/proc/<pid>/status`` (VmRSS now, VmHWM
the peak):

- ``targets``: frames at 11 sizes near 4096² (JPEG, depth 1, 1 sample, 64 spheres), then
  the resident memory (the render-target cache kept up to 9 sizes × two RGBA32F targets);
- ``bad``: one body of 150,000 invalid spheres (three errors each): the 422's size, time
  and the memory it took;
- ``largest``: the largest accepted request: a scene of as many spheres as
  ``POCKETRAY_MAX_BODY_BYTES`` holds, created as a session (parse, validate, build, plan):
  its peak resident memory above the idle server, and the same for ``--queue`` of them at
  once (the memory budget of docs/API.md);
- ``recipe``: the largest scene a recipe makes (scenario 3, n = ``--max-spheres``): one, and
  ``--queue`` at once;
- ``health``: ``/api/health`` latency (polled every 20 ms) while six maximum bodies arrive
  (``--parse-only``: and are refused after validation, so that no build follows);
- ``frames``: ``--frames`` (8) concurrent ``--frame-side``² (4096²) normal npy frames: the peak
  resident memory above the idle server (503s retried after their Retry-After);
- ``trickle``: eight connections trickling a byte every 4 s into 1 MB bodies, for
  ``--trickle-s`` seconds: what an honest client (another loopback address) gets for its
  100 kB bodies meanwhile, what the trickles get, and ``/api/health``'s p99;
- ``stalled``: seconds until a connection that sent headers with ``Content-Length: 100000``
  and a few body bytes is closed (given up after ``--stall-wait`` s);
- ``ws_keepalive``: a WebSocket that sends a gesture every 0.5 s for ``--ws-talk-s`` s and reads
  every answer: how long it lives, its close code;
- ``ws_slots``: ``--ws-count`` WebSockets opened and closed one after another, then a plain request;
- ``ws_flood``: ``--flood`` tiny invalid messages written at once on one WebSocket: the answers,
  the close code, ``/api/health`` p50/p99/max meanwhile;
- ``unread``: ``--unread-clients`` connections that never read ask for a ``--unread-side``²
  ``normal`` ``npy`` frame each: resident memory, peak and ``--unread-hold-s`` later;
- ``metrics``: ``--metrics-requests`` requests with made-up methods and paths, then ``/metrics``:
  its series, size and scrape time;
- ``flood``: sessions created from one address for ``--flood-s`` s (201 against 429), then
  ``--uploads`` sessions of a 3.2 MB scene each under a ``--flood-quota`` store quota;
- ``model_accessor``: glTF files whose accessor claims ``--accessor-counts`` VEC3 without data,
  one and ``--model-parallel`` at once: time to the answer, memory of the server and its parsers;
- ``model_chain``: GLB chains of ``--chain-nodes`` nodes over one triangle: time to the answer,
  ``/api/health`` meanwhile;
- ``model_overhead``: what a valid upload costs (``--model-repeats`` each);
- ``stack``: ``python -m server.tools.stack`` (Redis, two render processes, HAProxy) and
  ``--stack-clients`` clients (80), each from its own loopback address with its own session, a
  gesture then a small frame (48 × 64) every 50 ms: ``--stack-load-s`` (15) of load, then
  ``kill -9`` of render0 and ``--stack-kill-s`` (10) more, then Redis stopped (SIGSTOP) for
  ``--stack-pause-s`` (5) and as long after; per phase the requests, the failures by kind (the
  service's JSON, the balancer's JSON or page, a connection error; with Retry-After or not), then
  acknowledged gestures not found in Redis and what still runs. Both runs set
  ``POCKETRAY_QUEUE_SIZE`` to the clients and ``POCKETRAY_REDIS_TIMEOUT_S=2``.

Usage::

    .venv/bin/python -m bench.hostile                      # all parts, this checkout
    .venv/bin/python -m bench.hostile --root /tmp/pre17 bad health stalled
    .venv/bin/python -m bench.hostile --json out.json
    .venv/bin/python -m bench.hostile stack --root /tmp/base     # the stack's parts failing, an older commit

Loopback only; every loop is bounded.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx

from bench import hostile_parts
from bench.child import ServerChild, free_port

ROOT = Path(__file__).resolve().parent.parent

MIB = 1 << 20


class Server(ServerChild):
    """A server child (bench/child.py) of checkout ``root`` with a temporary SQLite file."""

    def __init__(self, root: Path, **settings: str):
        super().__init__(root, settings)


def scene_body(n: int, bad: bool = False, seed: int = 1) -> bytes:
    """A scene JSON of ``n`` spheres (``bad``: each with three errors), compact as a client writes it."""
    if bad:
        return b'{"materials":[{}],"spheres":[' + b",".join([b'{"center":[0,0],"radius":-1,"material":-1}'] * n) + b"]}"
    rnd = random.Random(seed)
    parts = [
        b'{"center":[%.4f,%.4f,%.4f],"radius":%.3f}'
        % (rnd.uniform(-40, 40), rnd.uniform(-40, 40), rnd.uniform(-40, 40), rnd.uniform(0.05, 0.5))
        for _ in range(n)
    ]
    return b'{"materials":[{}],"spheres":[' + b",".join(parts) + b"]}"


def largest_scene(max_bytes: int) -> tuple[bytes, int]:
    """The valid scene body with the most spheres under ``max_bytes`` (wrapped as a session create)."""
    per = len(scene_body(1000)) / 1000
    n = int((max_bytes - 200) / per)
    while True:
        body = b'{"scene":' + scene_body(n) + b"}"
        if len(body) <= max_bytes:
            return body, n
        n = int(n * 0.995)


JSON = {"content-type": "application/json"}


# ---- parts ------------------------------------------------------------------------------------------
def part_targets(root: Path, args) -> dict:
    s = Server(root, max_work=str(64 << 20), max_frame_cost="1e9", render_timeout_s="600")
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            sid = c.post(
                "/api/sessions",
                json={
                    "scenario": 3,
                    "n": 64,
                    "settings": {"max_recursion_depth": 1, "samples_per_pixel": 1, "format": "jpeg", "min_weight": 0.0},
                },
            ).json()["id"]
            idle = s.memory()
            sizes = [args.target_side - 8 * i for i in range(11)]
            times = []
            for side in sizes:
                t0 = time.perf_counter()
                r = c.get(f"/api/sessions/{sid}/frame", params={"width": side, "height": side})
                times.append(round(time.perf_counter() - t0, 2))
                if r.status_code != 200:
                    return {"error": f"{side}²: {r.status_code} {r.text[:300]}"}
            time.sleep(2)
            after = s.memory()
        return {
            "sizes": [f"{v}²" for v in sizes],
            "frame_s": times,
            "rss_idle_mib": round(idle["VmRSS"]),
            "rss_after_mib": round(after["VmRSS"]),
            "rss_peak_mib": round(after["VmHWM"]),
        }
    finally:
        s.close()


def part_bad(root: Path, args) -> dict:
    s = Server(root)
    try:
        body = b'{"scene":' + scene_body(args.bad_spheres, bad=True) + b"}"
        before = s.memory()
        t0 = time.perf_counter()
        r = httpx.post(s.url + "/api/sessions", content=body, headers=JSON, timeout=600)
        elapsed = time.perf_counter() - t0
        time.sleep(1)
        after = s.memory()
        detail = r.json().get("detail") if r.headers.get("content-type", "").startswith("application/json") else None
        return {
            "body_mb": round(len(body) / 1e6, 1),
            "status": r.status_code,
            "answer_bytes": len(r.content),
            "errors_listed": len(detail) if isinstance(detail, list) else None,
            "seconds": round(elapsed, 2),
            "rss_before_mib": round(before["VmRSS"]),
            "rss_after_mib": round(after["VmRSS"]),
            "rss_peak_mib": round(after["VmHWM"]),
            "peak_above_idle_mib": round(after["VmHWM"] - before["VmRSS"]),
        }
    finally:
        s.close()


def part_largest(root: Path, args) -> dict:
    out = {}
    body, n = largest_scene(args.max_body)
    for count in (1, args.queue):
        s = Server(
            root, max_body_bytes=str(args.max_body), queue_size=str(args.queue), body_slots_per_client="0"
        )  # every body comes from this one address
        try:
            idle = s.memory()
            codes: list[int] = []

            def create(url: str, codes: list[int]) -> None:
                with httpx.Client(base_url=url, timeout=600) as c:
                    codes.append(c.post("/api/sessions", content=body, headers=JSON).status_code)

            t0 = time.perf_counter()
            threads = [threading.Thread(target=create, args=(s.url, codes)) for _ in range(count)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            mem = s.memory()
            out[f"x{count}"] = {
                "codes": sorted(codes),
                "seconds": round(time.perf_counter() - t0, 1),
                "rss_idle_mib": round(idle["VmRSS"]),
                "rss_peak_mib": round(mem["VmHWM"]),
                "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
                "rss_after_mib": round(mem["VmRSS"]),
            }
        finally:
            s.close()
    return {"body_mb": round(len(body) / 1e6, 2), "spheres": n, **out}


def part_recipe(root: Path, args) -> dict:
    """The largest scene a recipe makes (scenario 3 with n = POCKETRAY_MAX_SPHERES): one, then --queue at once."""
    out = {}
    for count in (1, args.queue):
        s = Server(root, max_spheres=str(args.max_spheres), queue_size=str(args.queue), render_timeout_s="600")
        try:
            idle = s.memory()
            codes: list[int] = []

            def create(url: str, codes: list[int]) -> None:
                with httpx.Client(base_url=url, timeout=900) as c:
                    codes.append(
                        c.post(
                            "/api/sessions", json={"scenario": 3, "n": args.max_spheres, "seed": len(codes)}
                        ).status_code
                    )

            t0 = time.perf_counter()
            threads = [threading.Thread(target=create, args=(s.url, codes)) for _ in range(count)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            mem = s.memory()
            out[f"x{count}"] = {
                "codes": sorted(codes),
                "seconds": round(time.perf_counter() - t0, 1),
                "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
                "rss_after_mib": round(mem["VmRSS"]),
            }
        finally:
            s.close()
    return {"n": args.max_spheres, **out}


def wait_stats(waits: list[float], prefix: str = "health_") -> dict:
    """Calls, p50, p99 (nearest rank: never below p50) and max of /api/health waits, in ms."""
    w = sorted(waits)
    if not w:
        return {"health_calls": 0, f"{prefix}p50_ms": None, f"{prefix}p99_ms": None, f"{prefix}max_ms": None}

    def ms(x: float) -> float:
        return round(1e3 * x, 1)

    return {
        "health_calls": len(w),
        f"{prefix}p50_ms": ms(statistics.median(w)),
        f"{prefix}p99_ms": ms(w[math.ceil(0.99 * len(w)) - 1]),
        f"{prefix}max_ms": ms(w[-1]),
    }


def health_while(c: httpx.Client, threads: list[threading.Thread], limit_s: float = 600) -> list[float]:
    """Start ``threads``, time ``/api/health`` every 20 ms while any runs (``limit_s`` at most), join them:
    the answers' seconds."""
    waits: list[float] = []
    t_start = time.perf_counter()
    for t in threads:
        t.start()
    while any(t.is_alive() for t in threads) and time.perf_counter() - t_start < limit_s:
        t0 = time.perf_counter()
        c.get("/api/health")
        waits.append(time.perf_counter() - t0)
        time.sleep(0.02)
    for t in threads:
        t.join()
    return waits


def part_health(root: Path, args) -> dict:
    extra = {"max_spheres": "1000"} if args.parse_only else {}
    s = Server(
        root, max_body_bytes=str(args.max_body), queue_size=str(max(8, args.queue)), body_slots_per_client="0", **extra
    )  # every body comes from this one address
    try:
        body, n = largest_scene(args.max_body)
        codes: list[int] = []
        waits: list[float] = []
        with httpx.Client(base_url=s.url, timeout=60) as c:
            for _ in range(20):  # the idle latency, for comparison
                t0 = time.perf_counter()
                c.get("/api/health")
                waits.append(time.perf_counter() - t0)
            idle = sorted(waits)
            waits = []
            idle_mem = s.memory()

            def create() -> None:
                with httpx.Client(base_url=s.url, timeout=600) as cc:
                    codes.append(cc.post("/api/sessions", content=body, headers=JSON).status_code)

            threads = [threading.Thread(target=create) for _ in range(6)]
            t_start = time.perf_counter()
            waits += health_while(c, threads)
            mem = s.memory()
        w = sorted(waits)
        return {
            "bodies": 6,
            "parse_only": args.parse_only,
            "body_mb": round(len(body) / 1e6, 2),
            "spheres": n,
            "codes": sorted(codes),
            "seconds": round(time.perf_counter() - t_start, 1),
            "idle_p50_ms": round(1e3 * statistics.median(idle), 1),
            **wait_stats(w, prefix=""),
            "rss_peak_above_idle_mib": round(mem["VmHWM"] - idle_mem["VmRSS"]),
        }
    finally:
        s.close()


def part_stalled(root: Path, args) -> dict:
    s = Server(root)
    try:
        sock = socket.create_connection(("127.0.0.1", s.port), timeout=args.stall_wait)
        sock.sendall(
            b"PUT /api/sessions/x/scene HTTP/1.1\r\nHost: b\r\ncontent-type: application/json\r\n"
            b'content-length: 100000\r\n\r\n{"mater'
        )
        t0 = time.perf_counter()
        got = b""
        try:
            while chunk := sock.recv(65536):
                got += chunk
            closed = True
        except TimeoutError:
            closed = False
        waited = time.perf_counter() - t0
        sock.close()
        return {
            "closed": closed,
            "seconds": round(waited, 2) if closed else f"> {args.stall_wait:g}",
            "answer": got.split(b"\r\n", 1)[0].decode(errors="replace") if got else None,
        }
    finally:
        s.close()


# ---- metrics labels and session quotas: made-up methods, a session flood, a store filled ------------------
def _series(text: str) -> int:
    """Series of a /metrics exposition: its sample lines."""
    return sum(1 for line in text.splitlines() if line and not line.startswith("#"))


def _scrape(c: httpx.Client) -> tuple[httpx.Response, float]:
    t0 = time.perf_counter()
    r = c.get("/metrics")
    return r, time.perf_counter() - t0


def _gauge(text: str, name: str) -> float | None:
    for line in text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return None


def part_metrics(root: Path, args) -> dict:
    """``--metrics-requests`` requests with made-up methods on made-up paths, then /metrics: its
    series (sample lines), size and scrape time (median of 3)."""
    s = Server(root)
    try:
        with httpx.Client(base_url=s.url, timeout=60) as c:
            _scrape(c)
            before = _series(_scrape(c)[0].text)  # with the scrape's own series
            rnd = random.Random(24)
            codes: dict[int, int] = {}
            t0 = time.perf_counter()
            for _ in range(args.metrics_requests):
                method = "".join(rnd.choices("ABCDEFGHIJKLMNOPQRSTUVWXYZ", k=8))
                tok = f"{rnd.getrandbits(32):08x}"
                path = rnd.choice(("/api/sessions", f"/api/sessions/{tok}", f"/{tok}", f"/api/{tok}/{tok}"))
                code = c.request(method, path).status_code
                codes[code] = codes.get(code, 0) + 1
            seconds = time.perf_counter() - t0
            scrapes = [_scrape(c) for _ in range(3)]
        r = scrapes[-1][0]
        return {
            "requests": args.metrics_requests,
            "codes": codes,
            "seconds": round(seconds, 1),
            "series_before": before,
            "series_after": _series(r.text),
            "metrics_kib": round(len(r.content) / 1024),
            "scrape_ms": round(1e3 * statistics.median(dt for _, dt in scrapes), 1),
        }
    finally:
        s.close()


def part_flood(root: Path, args) -> dict:
    """``POST /api/sessions`` (a tiny recipe) from one address, 4 connections, for ``--flood-s`` s, the
    service's defaults: how many 201, how many 429; then ``--uploads`` sessions of a 3.2 MB scene each (0.8 MB
    stored) against ``POCKETRAY_MAX_STORE_BYTES=--flood-quota`` (a setting the base commit lacks): how many
    201 before 507, and the SQLite file's size."""
    out: dict = {}
    s = Server(root)
    try:
        codes: dict[int, int] = {}
        lock = threading.Lock()
        stop = time.monotonic() + args.flood_s

        def flood(i: int) -> None:
            with httpx.Client(base_url=s.url, timeout=60) as c:
                while time.monotonic() < stop:
                    code = c.post("/api/sessions", json={"scenario": 1, "n": 8, "seed": i}).status_code
                    with lock:
                        codes[code] = codes.get(code, 0) + 1

        threads = [threading.Thread(target=flood, args=(i,)) for i in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        text = httpx.get(s.url + "/metrics").text
        out["flood"] = {"seconds": args.flood_s, "codes": codes, "sessions": _gauge(text, "pocketray_sessions")}
    finally:
        s.close()
    s = Server(root, max_store_bytes=str(args.flood_quota), session_create_per_min="0")
    try:
        body = b'{"scene":' + scene_body(60_000) + b"}"
        codes = {}
        with httpx.Client(base_url=s.url, timeout=120) as c:
            for _ in range(args.uploads):
                code = c.post("/api/sessions", content=body, headers=JSON).status_code
                codes[code] = codes.get(code, 0) + 1
            text = c.get("/metrics").text
        db = Path(s.tmp.name) / "bench.sqlite3"
        wal = Path(str(db) + "-wal")
        out["uploads"] = {
            "quota_mib": round(args.flood_quota / MIB, 1),
            "body_mb": round(len(body) / 1e6, 2),
            "codes": codes,
            "store_bytes": _gauge(text, "pocketray_store_bytes"),
            "sqlite_mib": round((db.stat().st_size + (wal.stat().st_size if wal.exists() else 0)) / MIB, 1),
        }
    finally:
        s.close()
    return out


# ---- end of metrics labels and session quotas --------------------------------------------------------------


# ---- WebSockets and slow readers (ws_keepalive, ws_slots, ws_flood, unread) -------------------
def _session(url: str, **settings) -> str:
    body = {
        "scenario": 3,
        "n": 64,
        "seed": 1,
        "settings": {"width": 48, "height": 64, "max_recursion_depth": 2, "samples_per_pixel": 1, **settings},
    }
    r = httpx.post(url + "/api/sessions", json=body, timeout=60)
    r.raise_for_status()
    return r.json()["id"]


def _raw_ws(port: int, sid: str) -> socket.socket:
    """A WebSocket opened by hand (no extensions), to write frames as fast as the socket takes them."""
    import base64

    sock = socket.create_connection(("127.0.0.1", port), timeout=30)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET /api/sessions/{sid}/ws HTTP/1.1\r\nHost: b\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    if not head.startswith(b"HTTP/1.1 101 "):
        raise RuntimeError(f"no WebSocket: {head[:200]!r}")
    return sock


def _ws_text_frame(payload: bytes) -> bytes:
    mask = b"\x01\x02\x03\x04"
    return bytes([0x81, 0x80 | len(payload)]) + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def _read_ws(sock: socket.socket, quiet_s: float, limit_s: float) -> dict:
    """The server's frames until it closes, falls quiet for ``quiet_s`` or ``limit_s`` passes: text
    messages, the close code, and whether HTTP bytes came inside the WebSocket stream."""

    buf, texts, code, http_inside = b"", 0, None, False
    t0 = last = time.perf_counter()
    sock.settimeout(0.2)
    while time.perf_counter() - t0 < limit_s and time.perf_counter() - last < quiet_s:
        try:
            chunk = sock.recv(1 << 16)
        except TimeoutError:
            continue
        except ConnectionResetError:
            break
        if not chunk:
            break
        last = time.perf_counter()
        buf += chunk
        while len(buf) >= 2 and code is None:
            if buf.startswith(b"HTTP/"):
                http_inside, buf = True, b""
                break
            opcode, n, at = buf[0] & 0x0F, buf[1] & 0x7F, 2
            if n >= 126:
                at = 4 if n == 126 else 10
                if len(buf) < at:
                    break
                n = int.from_bytes(buf[2:at], "big")
            if len(buf) < at + n:
                break
            payload, buf = buf[at : at + n], buf[at + n :]
            texts += opcode == 0x1
            if opcode == 0x8:
                code = int.from_bytes(payload[:2], "big") if len(payload) >= 2 else 1005
        if code is not None:
            break
    return {"answers": texts, "close_code": code, "http_in_stream": http_inside, "seconds": round(last - t0, 2)}


def part_ws_keepalive(root: Path, args) -> dict:
    """A WebSocket sending a gesture every 0.5 s for --ws-talk-s and reading every answer: how long it lives."""
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    s = Server(root)
    try:
        sid = _session(s.url)
        answers, closed = 0, None
        t0 = time.perf_counter()
        with connect(f"ws://127.0.0.1:{s.port}/api/sessions/{sid}/ws", open_timeout=30) as ws:
            try:
                while time.perf_counter() - t0 < args.ws_talk_s:
                    ws.send(json.dumps({"type": "pan", "dx": 1, "dy": 0}))
                    ws.recv(timeout=60)
                    ws.recv(timeout=60)
                    answers += 1
                    time.sleep(0.5)
            except ConnectionClosed as e:
                closed = e
        lived = time.perf_counter() - t0
        code = reason = None
        if closed is not None:
            close = closed.rcvd or closed.sent
            code, reason = (close.code, close.reason) if close else (None, None)
        return {
            "talk_s": args.ws_talk_s,
            "answers": answers,
            "cut": closed is not None,
            "lived_s": round(lived, 1),
            "close_code": code,
            "close_reason": reason,
        }
    finally:
        s.close()


def part_ws_slots(root: Path, args) -> dict:
    """--ws-count WebSockets opened and closed one after another, then a plain request."""
    from websockets.sync.client import connect

    s = Server(root)
    try:
        sid = _session(s.url)
        opened, first_refused = 0, None
        for i in range(args.ws_count):
            try:
                with connect(f"ws://127.0.0.1:{s.port}/api/sessions/{sid}/ws", open_timeout=30):
                    opened += 1
            except Exception as e:  # the handshake answered 429
                if first_refused is None:
                    first_refused = {"index": i, "error": str(e)[:120]}
        time.sleep(0.5)
        r = httpx.get(s.url + "/api/health", timeout=10)
        return {
            "websockets": args.ws_count,
            "opened": opened,
            "first_refused": first_refused,
            "then_health": r.status_code,
        }
    finally:
        s.close()


def part_ws_flood(root: Path, args) -> dict:
    """--flood messages (one invalid byte each) written at once on one WebSocket, per count; /api/health
    polled every 20 ms meanwhile (p50/p99/max), and how the server answered."""
    out = {}
    s = Server(root)
    try:
        sid = _session(s.url)
        with httpx.Client(base_url=s.url, timeout=60) as c:
            idle = []
            for _ in range(20):
                t0 = time.perf_counter()
                c.get("/api/health")
                idle.append(time.perf_counter() - t0)
        for count in args.flood:
            waits: list[float] = []
            stop = threading.Event()

            def poll(stop: threading.Event, waits: list[float]) -> None:
                with httpx.Client(base_url=s.url, timeout=120) as c:
                    while not stop.is_set():
                        t0 = time.perf_counter()
                        c.get("/api/health")
                        waits.append(time.perf_counter() - t0)
                        time.sleep(0.02)

            sock = _raw_ws(s.port, sid)
            poller = threading.Thread(target=poll, args=(stop, waits))
            poller.start()
            time.sleep(0.3)
            flood = _ws_text_frame(b"x") * count
            t0 = time.perf_counter()
            sock.sendall(flood)
            sent_s = time.perf_counter() - t0
            got = _read_ws(sock, quiet_s=3.0, limit_s=90)
            time.sleep(0.5)
            stop.set()
            poller.join()
            sock.close()
            w = sorted(waits)
            out[str(count)] = {
                "sent_s": round(sent_s, 3),
                **got,
                **wait_stats(w),
            }
            print(f"  {count}: {json.dumps(out[str(count)])}", flush=True)
        return {"idle_health_p50_ms": round(1e3 * statistics.median(idle), 1), **out}
    finally:
        s.close()


def part_unread(root: Path, args) -> dict:
    """--unread-clients connections ask for an --unread-side² normal npy frame each (of a session each) and never read
    (SO_RCVBUF 4 KiB): the server's resident memory, peak and --unread-hold-s after the last answer
    started; then each one's status line (peeked) and whether the server still holds it open."""
    side = args.unread_side
    s = Server(
        root,
        max_frame_cost="1e9",
        render_timeout_s="600",
        queue_size=str(max(8, args.unread_clients)),
        max_connections_per_client=str(max(32, args.unread_clients + 4)),
    )
    socks: list[socket.socket] = []
    try:
        sids = [_session(s.url) for _ in range(args.unread_clients)]  # one each: a session's frames supersede
        idle = s.memory()
        t0 = time.perf_counter()
        for sid in sids:
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.connect(("127.0.0.1", s.port))
            sock.sendall(
                f"GET /api/sessions/{sid}/frame?width={side}&height={side}&mode=normal&format=npy"
                f"&max_recursion_depth=1&samples_per_pixel=1 HTTP/1.1\r\nHost: b\r\n\r\n".encode()
            )
            socks.append(sock)
        started: dict[int, float] = {}
        while len(started) < len(socks) and time.perf_counter() - t0 < 300:  # answers started (peeked)
            for i, sock in enumerate(socks):
                if i in started:
                    continue
                sock.settimeout(0.05)
                try:
                    if sock.recv(16, socket.MSG_PEEK):
                        started[i] = time.perf_counter() - t0
                except (TimeoutError, BlockingIOError):
                    pass
                except OSError:
                    started[i] = time.perf_counter() - t0
        last = max(started.values(), default=0.0)
        peak_while = 0.0
        rss_trace = []
        while time.perf_counter() - t0 < last + args.unread_hold_s:
            m = s.memory()
            peak_while = max(peak_while, m["VmRSS"])
            rss_trace.append(round(m["VmRSS"] - idle["VmRSS"]))
            time.sleep(1.0)
        held = s.memory()
        answers: dict[str, int] = {}
        still_open = 0
        for sock in socks:  # the status line (peeked) and whether the server kept it open
            sock.settimeout(2)
            try:
                got = sock.recv(64, socket.MSG_PEEK)
            except OSError:
                got = b""
            line = got.split(b"\r\n", 1)[0].decode(errors="replace") or "(nothing)"
            answers[line] = answers.get(line, 0) + 1
            still_open += sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 1)[0] == 1  # TCP_ESTABLISHED
        return {
            "clients": args.unread_clients,
            "frame_mib": round(side * side * 12 / 2**20),
            "answers": answers,
            "connections_still_open": still_open,
            "last_answer_started_s": round(last, 1),
            "rss_idle_mib": round(idle["VmRSS"]),
            "rss_peak_above_idle_mib": round(held["VmHWM"] - idle["VmRSS"]),
            f"rss_above_idle_{args.unread_hold_s:g}s_after_mib": round(held["VmRSS"] - idle["VmRSS"]),
            "rss_above_idle_trace_mib": rss_trace[:: max(1, len(rss_trace) // 12)],
        }
    finally:
        for sock in socks:
            sock.close()
        s.close()


# ---- end of WebSockets and slow readers ---------------------------------------------------------------------


# ---- memory of frames in flight, and trickling large bodies ------------------
def part_frames(root: Path, args) -> dict:
    """``--frames`` concurrent ``--frame-side``² normal npy frames (depth 1, 1 sample, 64 spheres), one
    session each: the server's peak resident memory above idle. A 503 is retried after its
    Retry-After (as a client should), until 300 s have passed; the bodies are read and dropped."""
    side, count = args.frame_side, args.frames
    s = Server(
        root,
        max_work=str(max(side * side, 64 << 20)),
        max_frame_cost="1e9",
        render_timeout_s="600",
        queue_size=str(max(8, count)),
    )
    try:
        settings = {"max_recursion_depth": 1, "samples_per_pixel": 1, "min_weight": 0.0}
        with httpx.Client(base_url=s.url, timeout=600) as c:
            sids = [
                c.post("/api/sessions", json={"scenario": 3, "n": 64, "seed": i, "settings": settings}).json()["id"]
                for i in range(count)
            ]
            assert c.get(f"/api/sessions/{sids[0]}/frame", params={"width": 64, "height": 64}).status_code == 200
        time.sleep(1)
        idle = s.memory()
        codes: list[int] = []
        retries: list[int] = []
        sizes: list[int] = []
        t_start = time.perf_counter()

        def frame(sid: str) -> None:
            tries = 0
            with httpx.Client(base_url=s.url, timeout=600) as c:
                while True:
                    with c.stream(
                        "GET",
                        f"/api/sessions/{sid}/frame",
                        params={"width": side, "height": side, "mode": "normal", "format": "npy"},
                    ) as r:
                        size = sum(len(chunk) for chunk in r.iter_bytes(1 << 20))
                        if r.status_code == 503 and time.perf_counter() - t_start < 300:
                            tries += 1
                            time.sleep(float(r.headers.get("retry-after", "1")))
                            continue
                        codes.append(r.status_code)
                        sizes.append(size)
                        retries.append(tries)
                        return

        threads = [threading.Thread(target=frame, args=(sid,)) for sid in sids]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        seconds = time.perf_counter() - t_start
        mem = s.memory()
        return {
            "frames": count,
            "side": side,
            "codes": sorted(codes),
            "retries_503": sum(retries),
            "body_mib": round(max(sizes) / MIB, 1),
            "seconds": round(seconds, 1),
            "rss_idle_mib": round(idle["VmRSS"]),
            "rss_peak_mib": round(mem["VmHWM"]),
            "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
        }
    finally:
        s.close()


def part_trickle(root: Path, args) -> dict:
    """Eight connections from 127.0.0.1 trickle one byte every 4 s into 1 MB JSON bodies (and
    reconnect when closed) for ``--trickle-s`` seconds; meanwhile an honest client on another
    loopback address (127.0.0.2) sends a 100 kB scene (a new session) every second, and
    ``/api/health`` is polled every 20 ms: the honest answers, the trickles' answers, the p99."""
    s = Server(root, queue_size="8")
    stop = threading.Event()
    trickled: list[str] = []
    honest: list[int] = []
    waits: list[float] = []
    body = b'{"scene":' + scene_body(2500) + b"}"
    assert len(body) > 64 * 1024

    def trickler() -> None:
        while not stop.is_set():
            sock = socket.create_connection(("127.0.0.1", s.port), timeout=4)
            sock.sendall(
                b"POST /api/sessions HTTP/1.1\r\nHost: b\r\ncontent-type: application/json\r\n"
                b"content-length: 1000000\r\n\r\n{"
            )
            got = b""
            while not stop.is_set():
                try:
                    chunk = sock.recv(65536)
                    if not chunk:
                        break
                    got += chunk
                except TimeoutError:
                    try:
                        sock.sendall(b" ")  # one byte every 4 s
                    except OSError:
                        break
                except OSError:
                    break
            sock.close()
            if got:
                trickled.append(got.split(b" ", 2)[1].decode(errors="replace"))
            stop.wait(1.0)  # then again, on a new connection

    def honest_client() -> None:
        transport = httpx.HTTPTransport(local_address="127.0.0.2")
        with httpx.Client(base_url=s.url, timeout=60, transport=transport) as c:
            while not stop.is_set():
                t0 = time.perf_counter()
                honest.append(c.post("/api/sessions", content=body, headers=JSON).status_code)
                stop.wait(max(0.0, 1.0 - (time.perf_counter() - t0)))

    try:
        attackers = [threading.Thread(target=trickler) for _ in range(8)]
        for t in attackers:
            t.start()
        time.sleep(1.0)  # the trickles take their slots first
        good = threading.Thread(target=honest_client)
        good.start()
        t_end = time.perf_counter() + args.trickle_s
        with httpx.Client(base_url=s.url, timeout=30) as c:
            while time.perf_counter() < t_end:
                t0 = time.perf_counter()
                c.get("/api/health")
                waits.append(time.perf_counter() - t0)
                time.sleep(0.02)
        stop.set()
        good.join()
        for t in attackers:
            t.join()
        w = sorted(waits)
        counts = lambda xs: {str(k): xs.count(k) for k in sorted(set(xs))}
        return {
            "seconds": args.trickle_s,
            "honest_body_kb": round(len(body) / 1e3),
            "honest_answers": counts(honest),
            "trickle_answers": counts(trickled),
            **{k: v for k, v in wait_stats(w).items() if k != "health_max_ms"},
        }
    finally:
        stop.set()
        s.close()


# ---- end of: memory of frames in flight, and trickling large bodies -------------------------------------


# ---- model files (hostile glTF/GLB bodies; renderer/io/model_guard.py, server/sessions/model_worker.py) -------
def accessor_gltf(count: int) -> bytes:
    """~250 bytes: one accessor of ``count`` VEC3 without a bufferView (zeros the file does not hold)."""
    return json.dumps(
        {
            "asset": {"version": "2.0"},
            "bufferViews": [],
            "accessors": [{"componentType": 5126, "count": count, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}],
            "scene": 0,
        }
    ).encode()


def chain_glb(n: int) -> bytes:
    """A GLB of one triangle under a chain of ``n`` nodes (the parser's cost grows with depth²)."""
    import struct

    tri = b"".join(struct.pack("<3f", *v) for v in ((0, 0, 0), (1, 0, 0), (0, 1, 0)))
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", 36, b"BIN\0") + tri
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def children_hwm_mib(pid: int) -> float:
    """The largest VmHWM of ``pid``'s child processes (the model-file workers), MiB; 0 without any."""
    kids: list[str] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            kids += (task / "children").read_text().split()
        except OSError:
            pass
    best = 0.0
    for kid in kids:
        try:
            for line in Path(f"/proc/{kid}/status").read_text().splitlines():
                if line.startswith("VmHWM:"):
                    best = max(best, int(line.split()[1]) / 1024)
        except OSError:
            pass
    return round(best)


def post_model(url: str, data: bytes, fmt: str, out: list, timeout: float = 600) -> None:
    t0 = time.perf_counter()
    r = httpx.post(
        url + "/api/meshes",
        params={"format": fmt},
        content=data,
        headers={"content-type": "application/octet-stream"},
        timeout=timeout,
    )
    detail = r.json().get("detail") if r.headers.get("content-type", "").startswith("application/json") else None
    msg = detail[0].get("msg") if isinstance(detail, list) and detail else detail
    out.append((r.status_code, round(time.perf_counter() - t0, 2), str(msg)[:140] if msg else None))


def part_model_accessor(root: Path, args) -> dict:
    """A ~250-byte glTF whose accessor claims N VEC3 without data: one, then --model-parallel at
    once (a fresh server each): seconds, answers, the server's peak memory above idle and the
    model-file workers' peak (0 when the parse runs in the server)."""
    out = {}
    for count in args.accessor_counts:
        body = accessor_gltf(count)
        for k in sorted({1, args.model_parallel}):
            if (count, k) in args.skip_model:
                out[f"{count:,} x{k}"] = "skipped (--skip-model)"
                continue
            s = Server(root)
            try:
                post_model(s.url, export_box_obj(), "obj", [])  # the first upload starts the parsers
                idle = s.memory()
                got: list = []
                t0 = time.perf_counter()
                threads = [threading.Thread(target=post_model, args=(s.url, body, "gltf", got)) for _ in range(k)]
                for t in threads:
                    t.start()
                for t in threads:
                    t.join()
                mem = s.memory()
                out[f"{count:,} x{k}"] = {
                    "body_bytes": len(body),
                    "codes": sorted(c for c, _, _ in got),
                    "seconds": round(time.perf_counter() - t0, 2),
                    "each_s": sorted(x for _, x, _ in got),
                    "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
                    "workers_peak_mib": children_hwm_mib(s.proc.pid),
                    "answer": got[0][2],
                }
                print(f"  {count:,} x{k}: {json.dumps(out[f'{count:,} x{k}'])}", flush=True)
            finally:
                s.close()
    return out


def export_box_obj() -> bytes:
    return b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def part_model_chain(root: Path, args) -> dict:
    """A GLB chain of N nodes over one triangle: its answer time, and /api/health latency
    (polled every 20 ms) while it is parsed, then while --model-parallel of them are."""
    out = {}
    s = Server(root)
    try:
        post_model(s.url, export_box_obj(), "obj", [])
        with httpx.Client(base_url=s.url, timeout=60) as c:
            idle = []
            for _ in range(20):
                t0 = time.perf_counter()
                c.get("/api/health")
                idle.append(time.perf_counter() - t0)
            out["idle_health_p50_ms"] = round(1e3 * statistics.median(idle), 1)
            for n in args.chain_nodes:
                body = chain_glb(n)
                for k in sorted({1, args.model_parallel}) if n == min(args.chain_nodes) else (1,):
                    got: list = []
                    threads = [threading.Thread(target=post_model, args=(s.url, body, "glb", got)) for _ in range(k)]
                    waits = health_while(c, threads)
                    w = sorted(waits)
                    out[f"{n:,} x{k}"] = {
                        "body_mb": round(len(body) / 1e6, 2),
                        "codes": sorted(c_ for c_, _, _ in got),
                        "each_s": sorted(x for _, x, _ in got),
                        **wait_stats(w),
                        "answer": got[0][2],
                    }
                    print(f"  {n:,} x{k}: {json.dumps(out[f'{n:,} x{k}'])}", flush=True)
    finally:
        s.close()
    return out


def part_model_overhead(root: Path, args) -> dict:
    """What a valid upload costs: POST /api/meshes of a small OBJ (80 triangles) and of a
    327,680-triangle PLY (8 MB), median of --model-repeats (one at a time, 0.2 s apart)."""
    from renderer.geometry.meshes import icosphere
    from renderer.io.mesh_io import export_mesh

    out = {}
    s = Server(root, max_body_bytes=str(32 * MIB))
    try:
        post_model(s.url, export_box_obj(), "obj", [])
        for name, data, fmt in (
            ("obj_80_tris", export_mesh(icosphere(1), "obj"), "obj"),
            ("ply_327680_tris", export_mesh(icosphere(7), "ply"), "ply"),
        ):
            got: list = []
            for _ in range(args.model_repeats):
                time.sleep(0.2)
                post_model(s.url, data, fmt, got)
            out[name] = {
                "bytes": len(data),
                "codes": sorted(set(c for c, _, _ in got)),
                "median_s": round(statistics.median(x for _, x, _ in got), 3),
            }
    finally:
        s.close()
    return out


# ---- end of model files ---------------------------------------------------------------------------------------------


# ---- the stack: its parts fail (80 clients through HAProxy; a render process killed; Redis paused) ----------
STACK_SETTINGS = {
    "width": 48,
    "height": 64,
    "max_recursion_depth": 2,
    "samples_per_pixel": 1,
    "min_weight": 0.0,
    "format": "npy",
}


def _stack_children(pid: int) -> dict:
    """The stack's children by role, from /proc: {"redis": pid, "haproxy": pid, "renders": {port: pid}}."""
    out: dict = {"redis": None, "haproxy": None, "renders": {}}
    try:
        kids = [int(k) for t in Path(f"/proc/{pid}/task").iterdir() for k in (t / "children").read_text().split()]
    except OSError:
        return out
    for k in kids:
        try:
            argv = Path(f"/proc/{k}/cmdline").read_bytes().decode(errors="replace").split("\0")
            state = next(
                line for line in Path(f"/proc/{k}/status").read_text().splitlines() if line.startswith("State:")
            )
        except (OSError, StopIteration):
            continue
        if "Z" in state.split()[1]:
            continue  # exited, not yet reaped
        if "redis-server" in argv[0]:  # it rewrites its title: "redis-server 127.0.0.1:port"
            out["redis"] = k
        elif argv[0].endswith("haproxy"):
            out["haproxy"] = k
        elif "serve" in argv and "--port" in argv:
            out["renders"][int(argv[argv.index("--port") + 1])] = k
    return out


async def _stack_load(url: str, sids: list[str], t0: float, until: float, log: list) -> None:
    """One client per session, each from its own loopback address (a phone each): a gesture, then a small
    frame, and so on until ``until``; every request logged as (start, end, kind, status, json, retry_after,
    served_by, version, error)."""
    import asyncio

    async def client(i: int, sid: str) -> None:
        transport = httpx.AsyncHTTPTransport(local_address=f"127.0.1.{1 + i}")
        headers = {"X-Session-Id": sid}
        async with httpx.AsyncClient(base_url=url, transport=transport, timeout=30, headers=headers) as c:
            k = 0
            while time.monotonic() < until:
                gesture = k % 2 == 0
                k += 1
                start = time.monotonic() - t0
                try:
                    if gesture:
                        r = await c.post(f"/api/sessions/{sid}/gesture", json={"type": "pan", "dx": 2, "dy": -1})
                    else:
                        r = await c.get(f"/api/sessions/{sid}/frame")
                    log.append(
                        (
                            start,
                            time.monotonic() - t0,
                            "gesture" if gesture else "frame",
                            r.status_code,
                            r.headers.get("content-type", "").startswith("application/json"),
                            "retry-after" in r.headers,
                            r.headers.get("x-served-by"),
                            r.json()["version"] if gesture and r.status_code == 200 else None,
                            None if r.status_code < 400 else r.text[:120],
                            sid,
                        )
                    )
                    ok = r.status_code < 400
                except httpx.HTTPError as e:
                    log.append(
                        (
                            start,
                            time.monotonic() - t0,
                            "gesture" if gesture else "frame",
                            None,
                            False,
                            False,
                            None,
                            None,
                            f"{type(e).__name__}: {e}"[:120],
                            sid,
                        )
                    )
                    ok = False
                await asyncio.sleep(0.05 if ok else 0.2)  # a finger's pace; a little longer after a refusal

    await asyncio.gather(*(client(i, sid) for i, sid in enumerate(sids)))


def _stack_phase(log: list, lo: float, hi: float) -> dict:
    """The requests that ended in [lo, hi) (a request in flight when a phase begins is that phase's)."""
    rows = [r for r in log if lo <= r[1] < hi]
    failed = [r for r in rows if r[3] is None or r[3] >= 400]
    kinds: dict[str, int] = {}
    for r in failed:
        key = (
            "connection error"
            if r[3] is None
            else f"{r[3]} {'service JSON' if r[6] else 'balancer JSON' if r[4] else 'balancer page'}"
            f"{' +Retry-After' if r[5] else ''}"
        )
        kinds[key] = kinds.get(key, 0) + 1
    return {
        "requests": len(rows),
        "failed": len(failed),
        "failed_pct": round(100 * len(failed) / max(1, len(rows)), 2),
        "failures": kinds,
        "examples": sorted({f"{r[2]} {r[8]}" for r in failed if r[8]})[:4],
    }


def part_stack(root: Path, args) -> dict:
    """``python -m server.tools.stack`` of ``root`` (Redis, two render processes, HAProxy); ``--stack-clients``
    clients for ``--stack-load-s``, then ``kill -9`` of render0 and ``--stack-kill-s`` more, then Redis
    stopped (SIGSTOP) for ``--stack-pause-s`` and ``--stack-pause-s`` more after it is back."""
    import asyncio
    import signal
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="bench-stack-"))
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
    env.update(
        POCKETRAY_LOG_LEVEL="warning", POCKETRAY_QUEUE_SIZE=str(args.stack_clients), POCKETRAY_REDIS_TIMEOUT_S="2"
    )
    err = open(tmp / "stack.err", "wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "server.tools.stack", "--port", str(port), "--dir", str(tmp / "stack")],
        cwd=root,
        env=env,
        stdout=err,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    out: dict = {"clients": args.stack_clients}
    try:
        deadline = time.monotonic() + 180
        while b"the balancer is" not in (tmp / "stack.err").read_bytes():
            if proc.poll() is not None or time.monotonic() > deadline:
                return {"error": (tmp / "stack.err").read_text()[-1500:]}
            time.sleep(0.2)
        cfg = (tmp / "stack" / "haproxy.cfg").read_text()
        render0_port = int(cfg.split("server render0 127.0.0.1:")[1].split()[0])
        sids = []
        with httpx.Client(base_url=url, timeout=60) as c:
            while len(sids) < args.stack_clients:
                r = c.post(
                    "/api/sessions", json={"scenario": 3, "n": 64, "seed": len(sids), "settings": STACK_SETTINGS}
                )
                if r.status_code == 201:
                    sids.append(r.json()["id"])
                else:
                    time.sleep(0.2)
        log: list = []
        t_kill = args.stack_load_s
        t_pause = t_kill + args.stack_kill_s
        t_cont = t_pause + args.stack_pause_s
        t_end = t_cont + args.stack_pause_s
        events: dict = {}

        async def chaos(t0: float) -> None:
            await asyncio.sleep(t_kill - (time.monotonic() - t0))
            victim = _stack_children(proc.pid)["renders"].get(render0_port) if args.stack_kill_s > 0 else None
            if victim:
                os.kill(victim, signal.SIGKILL)
                events["killed"] = f"render0 (pid {victim}) at {time.monotonic() - t0:.1f} s"
            await asyncio.sleep(t_pause - (time.monotonic() - t0))
            redis_pid = _stack_children(proc.pid)["redis"]
            if proc.poll() is not None or not redis_pid:
                events["paused"] = "no: the stack had stopped"
                return
            os.kill(redis_pid, signal.SIGSTOP)
            events["paused"] = f"redis at {time.monotonic() - t0:.1f} s"
            try:
                await asyncio.sleep(t_cont - (time.monotonic() - t0))
            finally:
                os.kill(redis_pid, signal.SIGCONT)
            events["continued"] = round(time.monotonic() - t0, 2)

        async def run() -> None:
            t0 = time.monotonic()
            await asyncio.gather(_stack_load(url, sids, t0, t0 + t_end, log), chaos(t0))

        asyncio.run(run())
        out["events"] = events
        out["load"] = _stack_phase(log, 0, t_kill)
        if args.stack_kill_s > 0:
            out["kill"] = _stack_phase(log, t_kill, t_pause)
            back = min((r[1] for r in log if r[0] > t_kill + 0.5 and r[6] == "render0"), default=None)
            out["kill"]["render0_serving_again_after_s"] = round(back - t_kill, 1) if back else None
        if "continued" in events:
            cont = events["continued"]
            out["redis_paused"] = _stack_phase(log, t_pause, cont)
            out["redis_back"] = _stack_phase(log, cont, t_end + 60)
            late = [r for r in log if (r[3] is None or r[3] >= 400) and r[1] > cont]
            first_ok = min((r[1] for r in log if r[0] >= cont and r[3] is not None and r[3] < 400), default=None)
            out["redis_back"]["last_failure_after_return_s"] = round(max((r[1] for r in late), default=cont) - cont, 2)
            out["redis_back"]["first_success_after_return_s"] = round(first_ok - cont, 2) if first_ok else None
        served = {}
        for r in log:
            if r[6]:
                served[r[6]] = served.get(r[6], 0) + 1
        out["served_by"] = served
        # Every acknowledged gesture is in Redis: a session's version is at least the last one acknowledged.
        acked: dict[str, int] = {}
        for r in log:
            if r[7] is not None:
                acked[r[9]] = max(acked.get(r[9], 0), r[7])
        lost = unread = 0
        with httpx.Client(base_url=url, timeout=30) as c:
            for sid, version in acked.items():
                try:
                    r = c.get(f"/api/sessions/{sid}", headers={"X-Session-Id": sid})
                    if r.status_code != 200:
                        unread += 1
                    elif r.json()["version"] < version:
                        lost += 1
                except httpx.HTTPError:
                    unread += 1
        kids = _stack_children(proc.pid)
        out["end"] = {
            "acknowledged_gestures": sum(1 for r in log if r[7] is not None),
            "lost_writes": lost,
            "sessions_unreadable": unread,
            "stack_running": proc.poll() is None,
            "render_processes": len(kids["renders"]),
            "redis": bool(kids["redis"]),
            "haproxy": bool(kids["haproxy"]),
        }
        out["stack_log"] = [line for line in (tmp / "stack.err").read_text().splitlines() if line.startswith("stack:")][
            -6:
        ]
        for part in ("load", "kill", "redis_paused", "redis_back"):
            if part in out:
                print(f"stack {part}: {out[part]}", flush=True)
        print(f"stack end: {out['end']}", flush=True)
        return out
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
        kids = _stack_children(proc.pid)
        for pid in [kids["redis"], kids["haproxy"], *kids["renders"].values()]:
            if pid:
                os.kill(pid, signal.SIGKILL)
        err.close()
        shutil.rmtree(tmp, ignore_errors=True)


# ---- end of the stack part --------------------------------------------------------------------------------


PARTS = {
    "targets": part_targets,
    "bad": part_bad,
    "largest": part_largest,
    "recipe": part_recipe,
    "health": part_health,
    "stalled": part_stalled,
    "metrics": part_metrics,
    "flood": part_flood,
    # WebSockets and slow readers
    "ws_keepalive": part_ws_keepalive,
    "ws_slots": part_ws_slots,
    "ws_flood": part_ws_flood,
    "unread": part_unread,
    "frames": part_frames,
    "trickle": part_trickle,
    "model_accessor": part_model_accessor,
    "model_chain": part_model_chain,
    "model_overhead": part_model_overhead,
    "stack": part_stack,
    # the later passes' attacks, one module each (bench/hostile_parts/)
    **hostile_parts.parts(),
}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("parts", nargs="*", help=f"any of {', '.join(PARTS)} (default: all)")
    ap.add_argument("--root", type=Path, default=ROOT, help="checkout whose server is measured")
    ap.add_argument("--max-body", type=int, default=16 * MIB, help="POCKETRAY_MAX_BODY_BYTES of the body parts")
    ap.add_argument("--max-spheres", type=int, default=1 << 21, help="POCKETRAY_MAX_SPHERES of the recipe part")
    ap.add_argument("--queue", type=int, default=8, help="POCKETRAY_QUEUE_SIZE (and the bodies at once of largest)")
    ap.add_argument("--target-side", type=int, default=4096, help="targets: the largest of the 11 sizes")
    ap.add_argument("--bad-spheres", type=int, default=150_000, help="bad: the invalid spheres of the body")
    ap.add_argument(
        "--parse-only",
        action="store_true",
        help="health: POCKETRAY_MAX_SPHERES=1000, so that the bodies are read, parsed, validated and "
        "refused (422) — no build",
    )
    ap.add_argument("--stall-wait", type=float, default=30.0, help="seconds to wait for a stalled body's close")
    ap.add_argument("--metrics-requests", type=int, default=4000, help="metrics: requests with made-up methods")
    ap.add_argument("--flood-s", type=float, default=10, help="flood: seconds of session creation from one address")
    ap.add_argument("--uploads", type=int, default=30, help="flood: sessions created with a 3.2 MB scene each")
    ap.add_argument("--flood-quota", type=int, default=16 * MIB, help="flood: POCKETRAY_MAX_STORE_BYTES of the uploads")
    # WebSockets and slow readers
    ap.add_argument("--ws-talk-s", type=float, default=20.0, help="ws_keepalive: seconds of a gesture every 0.5 s")
    ap.add_argument("--ws-count", type=int, default=64, help="ws_slots: WebSockets opened and closed in turn")
    ap.add_argument(
        "--flood",
        type=int,
        nargs="+",
        default=[20_000, 60_000],
        help="ws_flood: messages written at once (one run per count)",
    )
    ap.add_argument("--unread-clients", type=int, default=10, help="unread: connections that never read")
    ap.add_argument("--unread-side", type=int, default=4096, help="unread: the frame's side (normal npy)")
    ap.add_argument(
        "--unread-hold-s",
        type=float,
        default=45.0,
        help="unread: seconds after the last answer started when the memory is read",
    )
    ap.add_argument("--frames", type=int, default=8, help="frames: how many at once")
    ap.add_argument("--frame-side", type=int, default=4096, help="frames: their side (normal, npy)")
    ap.add_argument("--trickle-s", type=float, default=30.0, help="trickle: seconds of the attack")
    ap.add_argument(
        "--accessor-counts",
        type=lambda v: [int(x) for x in v.split(",")],
        default=[30_000_000, 90_000_000],
        help="model_accessor: the VEC3 counts the glTF claims (comma-separated)",
    )
    ap.add_argument(
        "--chain-nodes",
        type=lambda v: [int(x) for x in v.split(",")],
        default=[25_000, 50_000, 100_000],
        help="model_chain: the chains' node counts (comma-separated)",
    )
    ap.add_argument("--model-parallel", type=int, default=3, help="model parts: the bodies sent at once")
    ap.add_argument("--model-repeats", type=int, default=9, help="model_overhead: uploads per file")
    ap.add_argument(
        "--skip-model",
        type=lambda v: {(int(c), int(k)) for c, k in (p.split("x") for p in v.split(","))},
        default=set(),
        help="model_accessor: COUNTxK cases not run (e.g. 90000000x3: ~20 GB before)",
    )
    ap.add_argument("--stack-clients", type=int, default=80, help="stack: concurrent clients (one session each)")
    ap.add_argument("--stack-load-s", type=float, default=15, help="stack: seconds of load before the kill")
    ap.add_argument(
        "--stack-kill-s", type=float, default=10, help="stack: seconds after kill -9 of render0 (0: no kill)"
    )
    ap.add_argument("--stack-pause-s", type=float, default=5, help="stack: seconds Redis is stopped (and after)")
    ap.add_argument("--json", type=Path, help="write the figures here too")
    hostile_parts.add_arguments(ap)
    return ap


def main() -> None:
    ap = parser()
    args = ap.parse_args()
    args.parts = args.parts or list(PARTS)
    if set(args.parts) - set(PARTS):
        ap.error(f"unknown part(s) {', '.join(sorted(set(args.parts) - set(PARTS)))}; any of {', '.join(PARTS)}")
    commit = subprocess.run(
        ["git", "-C", str(args.root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    results = {"root": str(args.root), "commit": commit, "loadavg": os.getloadavg()[0], "cpus": os.cpu_count()}
    for name in args.parts:
        print(f"--- {name}", flush=True)
        results[name] = PARTS[name](args.root, args)
        print(json.dumps(results[name]), flush=True)
    results["loadavg_end"] = os.getloadavg()[0]
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
