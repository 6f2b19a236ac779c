"""Gesture → frame latency of the render service (issue: benchmark in bench/).

For scenario 3 with 4,096 spheres (radius 1), JPEG frames at 640 × 1088 and
320 × 544, with 1 and 4 concurrent clients (each its own session), every client
sends pan gestures with ``?frame=1`` (one round trip: the answer is the new
frame) back to back, with the settings of a render profile (``renderer.frame.profiles``,
the recursion depth capped at ``--depth`` as the client caps it at the session's):

- ``interactive`` — what the client asks for while a finger moves: 1 sample per
  pixel, ε = 0.3 (the frames the ≥ 10 frames/s target is about);
- ``still`` — the frames a session shows at rest: 4 samples per pixel, ε = 0.03.

Reported per profile and configuration: client-side latency p50 / p95
(ms), frames/s per client and in total, and the share of the mean latency spent
in each stage the server reports in ``Server-Timing`` (queue, build, upload,
trace, read, encode; "other" = HTTP, session store, scene lookup).

Then, at 320 × 544 with one client, the transports for one gesture → frame:
two round trips (POST gesture, then GET frame), one round trip (POST
gesture?frame=1), and a WebSocket (only when a WebSocket library is importable
by the server; ``pip install websockets``).

Usage::

    .venv/bin/python -m bench.latency                # starts its own server process
    .venv/bin/python -m bench.latency --url http://127.0.0.1:8000
    .venv/bin/python -m bench.latency --frames 10 --depth 3 --n 4096
    .venv/bin/python -m bench.latency --profiles interactive --no-transports

Target of the issue: ≥ 10 frames/s for one client at 320 × 544, depth 3, interactive profile.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import httpx

from bench.child import ServerChild
from renderer.frame.profiles import PROFILES

ROOT = Path(__file__).resolve().parent.parent

STAGES = ("queue", "build", "upload", "trace", "read", "encode")


def profile_params(name: str, depth: int) -> dict:
    """The frame query of a render profile, its depth capped at ``depth``."""
    p = PROFILES[name]
    return {
        "max_recursion_depth": min(int(p["max_recursion_depth"]), depth),
        "samples_per_pixel": int(p["samples_per_pixel"]),
        "min_weight": float(p["min_weight"]),
    }


def server_timing(header: str) -> dict[str, float]:
    out = {}
    for m in re.finditer(r"([\w-]+)(?:;[^,]*?)?;dur=([\d.]+)", header or ""):
        out[m.group(1)] = float(m.group(2))
    return out


def pct(values: list[float], q: float) -> float:
    v = sorted(values)
    if not v:
        return float("nan")
    k = (len(v) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (k - lo)


class Server(ServerChild):
    """A server child (bench/child.py) with a temporary SQLite file and a queue of ``queue_size``.

    ``base``: a commit whose ``renderer/`` and ``shaders/`` (extracted from git into a
    temporary directory) the server renders with, this checkout's ``server/`` otherwise
    (the base commit's unshaped shader and layouts beside today's service); ``settings``: more
    ``POCKETRAY_*`` settings of the child (``slice_ms=…``)."""

    def __init__(self, queue_size: int, base: str | None = None, **settings: object):
        self.code = tempfile.TemporaryDirectory()
        cwd, pythonpath = ROOT, None
        if base:
            archive = subprocess.run(
                ["git", "-C", str(ROOT), "archive", base, "renderer", "shaders"], check=True, capture_output=True
            ).stdout
            subprocess.run(["tar", "-x", "-C", self.code.name], input=archive, check=True)
            cwd, pythonpath = Path(self.code.name), f"{self.code.name}{os.pathsep}{ROOT}"
        super().__init__(cwd, {"queue_size": queue_size, **settings}, pythonpath=pythonpath, timeout_s=120)

    def close(self) -> None:
        super().close()
        self.code.cleanup()


def new_session(c: httpx.Client, n: int, depth: int, w: int, h: int) -> str:
    r = c.post(
        "/api/sessions",
        json={
            "scenario": 3,
            "n": n,
            "seed": 0,
            "radius": 1.0,
            "settings": {"width": w, "height": h, "max_recursion_depth": depth, "format": "jpeg", "quality": 85},
        },
    )
    r.raise_for_status()
    return r.json()["id"]


def run_clients(
    url: str, clients: int, frames: int, n: int, depth: int, w: int, h: int, profile: str = "interactive"
) -> dict:
    """``clients`` threads, each its own session, ``frames`` gesture?frame=1 each, with the
    settings of ``profile``."""
    samples: list[tuple[float, dict[str, float]]] = []
    errors: list[str] = []
    lock = threading.Lock()
    params = {"frame": 1, "width": w, "height": h, "format": "jpeg", **profile_params(profile, depth)}

    def client(i: int) -> None:
        with httpx.Client(base_url=url, timeout=300) as c:
            sid = new_session(c, n, depth, w, h)
            c.get(f"/api/sessions/{sid}/frame", params={k: v for k, v in params.items() if k != "frame"})  # warm
            barrier.wait()
            for k in range(frames):
                g = {"type": "pan", "dx": 6.0 if k % 2 == 0 else -6.0, "dy": 0.0}
                t0 = time.perf_counter()
                r = c.post(f"/api/sessions/{sid}/gesture", params=params, json=g)
                dt = (time.perf_counter() - t0) * 1e3
                if r.status_code != 200:
                    with lock:
                        errors.append(f"{r.status_code} {r.text[:100]}")
                    time.sleep(float(r.headers.get("retry-after", "1")))
                    continue
                with lock:
                    samples.append((dt, server_timing(r.headers.get("server-timing", ""))))

    barrier = threading.Barrier(clients + 1)
    threads = [threading.Thread(target=client, args=(i,)) for i in range(clients)]
    for t in threads:
        t.start()
    barrier.wait()
    t_start = time.perf_counter()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t_start
    lat = [s[0] for s in samples]
    mean_lat = statistics.fmean(lat) if lat else float("nan")
    shares = (
        {k: statistics.fmean(s[1].get(k, 0.0) for s in samples) / mean_lat * 100 for k in STAGES} if samples else {}
    )
    if shares:
        shares["other"] = 100.0 - sum(shares.values())
    return {
        "profile": profile,
        "size": f"{w}×{h}",
        "clients": clients,
        "frames": len(lat),
        "errors": len(errors),
        "p50": pct(lat, 0.5),
        "p95": pct(lat, 0.95),
        "fps_client": 1000.0 / mean_lat if lat else 0.0,
        "fps_total": len(lat) / wall if wall > 0 else 0.0,
        "shares": shares,
        "server_total_p50": pct([s[1].get("total", 0.0) for s in samples], 0.5),
        "trace_p50": pct([s[1].get("trace", 0.0) for s in samples], 0.5),
    }


def against_base(urls: dict[str, str], frames: int, n: int, depth: int, w: int, h: int, profile: str) -> dict:
    """One client per server (today's and the base commit's renderer), gestures alternating
    between them (A/B/A/B): p50 latency, server trace p50 and fps of each, and whether
    their JPEG frames are the same bytes."""
    params = {"frame": 1, "width": w, "height": h, "format": "jpeg", **profile_params(profile, depth)}
    clients = {k: httpx.Client(base_url=u, timeout=300) for k, u in urls.items()}
    lat: dict[str, list[float]] = {k: [] for k in urls}
    trace: dict[str, list[float]] = {k: [] for k in urls}
    same = 0
    try:
        sids = {k: new_session(c, n, depth, w, h) for k, c in clients.items()}
        for k, c in clients.items():
            c.get(f"/api/sessions/{sids[k]}/frame", params={q: v for q, v in params.items() if q != "frame"})
        for i in range(frames):
            g = {"type": "pan", "dx": 6.0 if i % 2 == 0 else -6.0, "dy": 0.0}
            bodies = {}
            for k, c in clients.items() if i % 2 == 0 else reversed(clients.items()):
                t0 = time.perf_counter()
                r = c.post(f"/api/sessions/{sids[k]}/gesture", params=params, json=g)
                r.raise_for_status()
                lat[k].append((time.perf_counter() - t0) * 1e3)
                trace[k].append(server_timing(r.headers.get("server-timing", "")).get("trace", float("nan")))
                bodies[k] = r.content
            same += len(set(bodies.values())) == 1
    finally:
        for c in clients.values():
            c.close()
    return {
        k: {
            "p50": pct(lat[k], 0.5),
            "p95": pct(lat[k], 0.95),
            "trace_p50": pct(trace[k], 0.5),
            "fps": 1000.0 / statistics.fmean(lat[k]),
        }
        for k in urls
    } | {"same_bytes": same, "frames": frames}


def transports(url: str, frames: int, n: int, depth: int, w: int, h: int) -> list[dict]:
    """p50/p95 of one gesture → frame by three transports (one client, 320 × 544)."""
    out = []
    params = {"width": w, "height": h, "format": "jpeg", **profile_params("interactive", depth)}
    with httpx.Client(base_url=url, timeout=300) as c:
        sid = new_session(c, n, depth, w, h)
        c.get(f"/api/sessions/{sid}/frame", params=params)  # warm-up (shader variant)

        def measure(name: str, once) -> None:
            lat, overhead = [], []
            for k in range(frames):
                g = {"type": "pan", "dx": 6.0 if k % 2 == 0 else -6.0, "dy": 0.0}
                t0 = time.perf_counter()
                server_total = once(g)
                dt = (time.perf_counter() - t0) * 1e3
                lat.append(dt)
                overhead.append(dt - server_total)
            out.append(
                {"transport": name, "p50": pct(lat, 0.5), "p95": pct(lat, 0.95), "overhead_p50": pct(overhead, 0.5)}
            )

        def two_trips(g) -> float:
            c.post(f"/api/sessions/{sid}/gesture", json=g).raise_for_status()
            r = c.get(f"/api/sessions/{sid}/frame", params=params)
            r.raise_for_status()
            return server_timing(r.headers["server-timing"])["total"]

        def one_trip(g) -> float:
            r = c.post(f"/api/sessions/{sid}/gesture", params={"frame": 1, **params}, json=g)
            r.raise_for_status()
            return server_timing(r.headers["server-timing"])["total"]

        measure("HTTP: POST gesture + GET frame (2 round trips)", two_trips)
        measure("HTTP: POST gesture?frame=1 (1 round trip)", one_trip)
        try:
            from websockets.sync.client import connect
        except ImportError:
            out.append({"transport": "WebSocket", "skipped": "no `websockets` package here"})
            return out
        ws_url = url.replace("http://", "ws://") + f"/api/sessions/{sid}/ws"
        try:
            ws = connect(ws_url, max_size=None, open_timeout=10)
        except Exception as e:  # the server has no WebSocket implementation
            out.append({"transport": "WebSocket", "skipped": f"server refused the upgrade ({e})"})
            return out
        with ws:

            def over_ws(g) -> float:
                ws.send(json.dumps({**g, "frame": params}))
                meta = json.loads(ws.recv())
                if "status" in meta:
                    raise RuntimeError(meta)
                ws.recv()  # the frame
                return meta["timings"]["total"]

            measure("WebSocket: gesture message → meta + frame", over_ws)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", help="an already running service (default: start one)")
    ap.add_argument("--n", type=int, default=4096, help="spheres (scenario 3)")
    ap.add_argument("--depth", type=int, default=3, help="max_recursion_depth")
    ap.add_argument("--frames", type=int, default=12, help="gestures per client at 320×544 (half at 640×1088)")
    ap.add_argument("--no-transports", action="store_true", help="skip the transport comparison")
    ap.add_argument("--profiles", default="interactive,still", help="render profiles, comma-separated")
    ap.add_argument("--sizes", default="640x1088,320x544", help="frame sizes, comma-separated")
    ap.add_argument("--clients", default="1,4", help="concurrent clients, comma-separated")
    ap.add_argument(
        "--base",
        default=None,
        metavar="COMMIT",
        help="also start a server rendering with COMMIT's renderer and shaders (e.g. cda5fce, the "
        "unshaped tracer) and compare one client at 320×544, interactive, gestures alternating",
    )
    args = ap.parse_args()
    profiles = [p for p in args.profiles.split(",") if p]
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",") if s]
    client_counts = [int(c) for c in args.clients.split(",") if c]

    server = None if args.url else Server(queue_size=8)
    url = args.url or server.url
    try:
        info = httpx.get(url + "/api/ready", timeout=10).json()
        print(
            f"# gesture → frame latency — scenario 3, n = {args.n}, radius 1, max_recursion_depth ≤ "
            f"{args.depth}, JPEG q85, BIH max_prims 8"
        )
        print(
            f"# GL: {info.get('gl_renderer')} | {info.get('gl_version')} | CPUs: {os.cpu_count()} | "
            f"load avg before: {os.getloadavg()[0]:.2f}"
        )
        results = []
        for profile in profiles:
            q = profile_params(profile, args.depth)
            print(
                f"\n## profile {profile}: depth {q['max_recursion_depth']}, {q['samples_per_pixel']} sample(s) "
                f"per pixel, ε = {q['min_weight']:g}\n"
            )
            print(
                "| size | clients | frames | p50 ms | p95 ms | fps/client | fps total | server trace p50 ms | "
                + " | ".join(f"{s} %" for s in (*STAGES, "other"))
                + " |"
            )
            print("|---|---|---|---|---|---|---|---|" + "---|" * (len(STAGES) + 1))
            for w, h in sizes:
                frames = args.frames if w * h <= 320 * 544 else max(2, args.frames // 2)
                for clients in client_counts:
                    per_client = frames if clients == 1 else max(2, frames // 2)
                    r = run_clients(url, clients, per_client, args.n, args.depth, w, h, profile)
                    results.append(r)
                    shed = f" (+{r['errors']} 503)" if r["errors"] else ""
                    print(
                        f"| {r['size']} | {clients} | {r['frames']}{shed} "
                        f"| {r['p50']:.0f} | {r['p95']:.0f} | {r['fps_client']:.2f} | {r['fps_total']:.2f} | "
                        f"{r['trace_p50']:.0f} | "
                        + " | ".join(f"{r['shares'].get(s, 0):.1f}" for s in (*STAGES, "other"))
                        + " |",
                        flush=True,
                    )
        one = next(
            (r for r in results if r["size"] == "320×544" and r["clients"] == 1 and r["profile"] == "interactive"), None
        )
        if one is not None:
            verdict = "met" if one["fps_client"] >= 10 else "NOT met"
            print()
            print(
                f"Target ≥ 10 frames/s, one client, 320×544, interactive profile, depth "
                f"{profile_params('interactive', args.depth)['max_recursion_depth']}: p50 {one['p50']:.0f} ms, "
                f"{one['fps_client']:.2f} fps → {verdict}"
            )
        if args.base:
            base = Server(queue_size=8, base=args.base)
            try:
                ab = against_base(
                    {"now": url, args.base: base.url}, max(8, args.frames), args.n, args.depth, 320, 544, "interactive"
                )
            finally:
                base.close()
            print()
            print(
                "| 320×544, 1 client, interactive, gestures alternating | p50 ms | p95 ms | server trace p50 ms | fps |"
            )
            print("|---|---|---|---|---|")
            for k in ("now", args.base):
                print(
                    f"| {'this checkout' if k == 'now' else 'renderer and shaders of ' + k} | {ab[k]['p50']:.0f} "
                    f"| {ab[k]['p95']:.0f} | {ab[k]['trace_p50']:.0f} | {ab[k]['fps']:.2f} |"
                )
            print(
                f"\np50 ratio now / {args.base}: {ab['now']['p50'] / ab[args.base]['p50']:.2f}×; "
                f"identical JPEG bytes in {ab['same_bytes']} of {ab['frames']} gestures"
            )
        if not args.no_transports:
            print()
            print("| transport (320×544, 1 client) | p50 ms | p95 ms | p50 latency − server total, ms |")
            print("|---|---|---|---|")
            for t in transports(url, max(6, args.frames), args.n, args.depth, 320, 544):
                if "skipped" in t:
                    print(f"| {t['transport']} | — | — | skipped: {t['skipped']} |")
                else:
                    print(f"| {t['transport']} | {t['p50']:.0f} | {t['p95']:.0f} | {t['overhead_p50']:.1f} |")
        print(f"\n# load avg after: {os.getloadavg()[0]:.2f}")
    finally:
        if server:
            server.close()


if __name__ == "__main__":
    main()
