"""The figures of issue #17 (hardening), measured against a real ``python -m server`` on loopback.

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
  and a few body bytes is closed (given up after ``--stall-wait`` s).

Usage::

    .venv/bin/python bench/hostile.py                      # all parts, this checkout
    .venv/bin/python bench/hostile.py --root /tmp/pre17 bad health stalled
    .venv/bin/python bench/hostile.py --json out.json

Loopback only; every loop is bounded.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from bench.child import ServerChild  # noqa: E402  (run as a script or imported)
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
    parts = [b'{"center":[%.4f,%.4f,%.4f],"radius":%.3f}' % (rnd.uniform(-40, 40), rnd.uniform(-40, 40),
                                                            rnd.uniform(-40, 40), rnd.uniform(0.05, 0.5))
             for _ in range(n)]
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
            sid = c.post("/api/sessions", json={"scenario": 3, "n": 64, "settings": {
                "max_recursion_depth": 1, "samples_per_pixel": 1, "format": "jpeg", "min_weight": 0.0}}).json()["id"]
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
        return {"sizes": [f"{v}²" for v in sizes], "frame_s": times, "rss_idle_mib": round(idle["VmRSS"]),
                "rss_after_mib": round(after["VmRSS"]), "rss_peak_mib": round(after["VmHWM"])}
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
        return {"body_mb": round(len(body) / 1e6, 1), "status": r.status_code, "answer_bytes": len(r.content),
                "errors_listed": len(detail) if isinstance(detail, list) else None, "seconds": round(elapsed, 2),
                "rss_before_mib": round(before["VmRSS"]), "rss_after_mib": round(after["VmRSS"]),
                "rss_peak_mib": round(after["VmHWM"]), "peak_above_idle_mib": round(after["VmHWM"] - before["VmRSS"])}
    finally:
        s.close()


def part_largest(root: Path, args) -> dict:
    out = {}
    body, n = largest_scene(args.max_body)
    for count in (1, args.queue):
        s = Server(root, max_body_bytes=str(args.max_body), queue_size=str(args.queue),
                   body_slots_per_client="0")      # every body comes from this one address
        try:
            idle = s.memory()
            codes: list[int] = []

            def create() -> None:
                with httpx.Client(base_url=s.url, timeout=600) as c:
                    codes.append(c.post("/api/sessions", content=body, headers=JSON).status_code)
            t0 = time.perf_counter()
            threads = [threading.Thread(target=create) for _ in range(count)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            mem = s.memory()
            out[f"x{count}"] = {"codes": sorted(codes), "seconds": round(time.perf_counter() - t0, 1),
                                "rss_idle_mib": round(idle["VmRSS"]), "rss_peak_mib": round(mem["VmHWM"]),
                                "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
                                "rss_after_mib": round(mem["VmRSS"])}
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

            def create() -> None:
                with httpx.Client(base_url=s.url, timeout=900) as c:
                    codes.append(c.post("/api/sessions", json={"scenario": 3, "n": args.max_spheres,
                                                               "seed": len(codes)}).status_code)
            t0 = time.perf_counter()
            threads = [threading.Thread(target=create) for _ in range(count)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            mem = s.memory()
            out[f"x{count}"] = {"codes": sorted(codes), "seconds": round(time.perf_counter() - t0, 1),
                                "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
                                "rss_after_mib": round(mem["VmRSS"])}
        finally:
            s.close()
    return {"n": args.max_spheres, **out}


def part_health(root: Path, args) -> dict:
    extra = {"max_spheres": "1000"} if args.parse_only else {}
    s = Server(root, max_body_bytes=str(args.max_body), queue_size=str(max(8, args.queue)),
               body_slots_per_client="0", **extra)      # every body comes from this one address
    try:
        body, n = largest_scene(args.max_body)
        codes: list[int] = []
        waits: list[float] = []
        with httpx.Client(base_url=s.url, timeout=60) as c:
            for _ in range(20):                      # the idle latency, for comparison
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
            for t in threads:
                t.start()
            while any(t.is_alive() for t in threads) and time.perf_counter() - t_start < 600:
                t0 = time.perf_counter()
                c.get("/api/health")
                waits.append(time.perf_counter() - t0)
                time.sleep(0.02)
            for t in threads:
                t.join()
            mem = s.memory()
        w = sorted(waits)
        return {"bodies": 6, "parse_only": args.parse_only, "body_mb": round(len(body) / 1e6, 2), "spheres": n, "codes": sorted(codes),
                "seconds": round(time.perf_counter() - t_start, 1), "health_calls": len(w),
                "idle_p50_ms": round(1e3 * statistics.median(idle), 1),
                "p50_ms": round(1e3 * statistics.median(w), 1), "p99_ms": round(1e3 * w[int(0.99 * (len(w) - 1))], 1),
                "max_ms": round(1e3 * w[-1], 1), "rss_peak_above_idle_mib": round(mem["VmHWM"] - idle_mem["VmRSS"])}
    finally:
        s.close()


def part_stalled(root: Path, args) -> dict:
    s = Server(root)
    try:
        sock = socket.create_connection(("127.0.0.1", s.port), timeout=args.stall_wait)
        sock.sendall(b"PUT /api/sessions/x/scene HTTP/1.1\r\nHost: b\r\ncontent-type: application/json\r\n"
                     b"content-length: 100000\r\n\r\n{\"mater")
        t0 = time.perf_counter()
        got = b""
        try:
            while chunk := sock.recv(65536):
                got += chunk
            closed = True
        except socket.timeout:
            closed = False
        waited = time.perf_counter() - t0
        sock.close()
        return {"closed": closed, "seconds": round(waited, 2) if closed else f"> {args.stall_wait:g}",
                "answer": got.split(b"\r\n", 1)[0].decode(errors="replace") if got else None}
    finally:
        s.close()


# ---- memory of frames in flight, and trickling large bodies (issue 24, items 8 and 9) ------------------
def part_frames(root: Path, args) -> dict:
    """``--frames`` concurrent ``--frame-side``² normal npy frames (depth 1, 1 sample, 64 spheres), one
    session each: the server's peak resident memory above idle. A 503 is retried after its
    Retry-After (as a client should), until 300 s have passed; the bodies are read and dropped."""
    side, count = args.frame_side, args.frames
    s = Server(root, max_work=str(max(side * side, 64 << 20)), max_frame_cost="1e9", render_timeout_s="600",
               queue_size=str(max(8, count)))
    try:
        settings = {"max_recursion_depth": 1, "samples_per_pixel": 1, "min_weight": 0.0}
        with httpx.Client(base_url=s.url, timeout=600) as c:
            sids = [c.post("/api/sessions", json={"scenario": 3, "n": 64, "seed": i, "settings": settings}).json()["id"]
                    for i in range(count)]
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
                    with c.stream("GET", f"/api/sessions/{sid}/frame",
                                  params={"width": side, "height": side, "mode": "normal", "format": "npy"}) as r:
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
        return {"frames": count, "side": side, "codes": sorted(codes), "retries_503": sum(retries),
                "body_mib": round(max(sizes) / MIB, 1), "seconds": round(seconds, 1),
                "rss_idle_mib": round(idle["VmRSS"]), "rss_peak_mib": round(mem["VmHWM"]),
                "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"])}
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
            sock.sendall(b"POST /api/sessions HTTP/1.1\r\nHost: b\r\ncontent-type: application/json\r\n"
                         b"content-length: 1000000\r\n\r\n{")
            got = b""
            while not stop.is_set():
                try:
                    chunk = sock.recv(65536)
                    if not chunk:
                        break
                    got += chunk
                except socket.timeout:
                    try:
                        sock.sendall(b" ")                     # one byte every 4 s
                    except OSError:
                        break
                except OSError:
                    break
            sock.close()
            if got:
                trickled.append(got.split(b" ", 2)[1].decode(errors="replace"))
            stop.wait(1.0)                                    # then again, on a new connection

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
        time.sleep(1.0)                                       # the trickles take their slots first
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
        counts = lambda xs: {str(k): xs.count(k) for k in sorted(set(xs))}   # noqa: E731
        return {"seconds": args.trickle_s, "honest_body_kb": round(len(body) / 1e3),
                "honest_answers": counts(honest), "trickle_answers": counts(trickled),
                "health_calls": len(w), "health_p50_ms": round(1e3 * statistics.median(w), 1),
                "health_p99_ms": round(1e3 * w[int(0.99 * (len(w) - 1))], 1)}
    finally:
        stop.set()
        s.close()
# ---- end of: memory of frames in flight, and trickling large bodies -------------------------------------


PARTS = {"targets": part_targets, "bad": part_bad, "largest": part_largest, "recipe": part_recipe,
         "health": part_health,
         "stalled": part_stalled,
         "frames": part_frames, "trickle": part_trickle}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("parts", nargs="*", help=f"any of {', '.join(PARTS)} (default: all)")
    ap.add_argument("--root", type=Path, default=ROOT, help="checkout whose server is measured")
    ap.add_argument("--max-body", type=int, default=16 * MIB, help="POCKETRAY_MAX_BODY_BYTES of the body parts")
    ap.add_argument("--max-spheres", type=int, default=1 << 21, help="POCKETRAY_MAX_SPHERES of the recipe part")
    ap.add_argument("--queue", type=int, default=8, help="POCKETRAY_QUEUE_SIZE (and the bodies at once of largest)")
    ap.add_argument("--target-side", type=int, default=4096, help="targets: the largest of the 11 sizes")
    ap.add_argument("--bad-spheres", type=int, default=150_000, help="bad: the invalid spheres of the body")
    ap.add_argument("--parse-only", action="store_true",
                    help="health: POCKETRAY_MAX_SPHERES=1000, so that the bodies are read, parsed, validated and "
                         "refused (422) — no build")
    ap.add_argument("--stall-wait", type=float, default=30.0, help="seconds to wait for a stalled body's close")
    ap.add_argument("--frames", type=int, default=8, help="frames: how many at once")
    ap.add_argument("--frame-side", type=int, default=4096, help="frames: their side (normal, npy)")
    ap.add_argument("--trickle-s", type=float, default=30.0, help="trickle: seconds of the attack")
    ap.add_argument("--json", type=Path, help="write the figures here too")
    return ap


def main() -> None:
    ap = parser()
    args = ap.parse_args()
    args.parts = args.parts or list(PARTS)
    if set(args.parts) - set(PARTS):
        ap.error(f"unknown part(s) {', '.join(sorted(set(args.parts) - set(PARTS)))}; any of {', '.join(PARTS)}")
    commit = subprocess.run(["git", "-C", str(args.root), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
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
