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
- ``stalled``: seconds until a connection that sent headers with ``Content-Length: 100000``
  and a few body bytes is closed (given up after ``--stall-wait`` s);
- ``stack``: ``python -m server.stack`` (Redis, two render processes, HAProxy) and
  ``--stack-clients`` clients (80), each from its own loopback address with its own session, a
  gesture then a small frame (48 × 64) every 50 ms: ``--stack-load-s`` (15) of load, then
  ``kill -9`` of render0 and ``--stack-kill-s`` (10) more, then Redis stopped (SIGSTOP) for
  ``--stack-pause-s`` (5) and as long after; per phase the requests, the failures by kind (the
  service's JSON, the balancer's JSON or page, a connection error; with Retry-After or not), then
  acknowledged gestures not found in Redis and what still runs. Both runs set
  ``POCKETRAY_QUEUE_SIZE`` to the clients and ``POCKETRAY_REDIS_TIMEOUT_S=2``.

Usage::

    .venv/bin/python bench/hostile.py                      # all parts, this checkout
    .venv/bin/python bench/hostile.py --root /tmp/pre17 bad health stalled
    .venv/bin/python bench/hostile.py --json out.json
    .venv/bin/python bench/hostile.py stack --root /tmp/base     # the stack's parts failing, an older commit

Loopback only; every loop is bounded.
"""

from __future__ import annotations

import argparse
import json
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

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from bench.child import ServerChild, free_port  # noqa: E402  (run as a script or imported)
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
        s = Server(root, max_body_bytes=str(args.max_body), queue_size=str(args.queue))
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
    s = Server(root, max_body_bytes=str(args.max_body), queue_size=str(max(8, args.queue)), **extra)
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


# ---- the stack: its parts fail (80 clients through HAProxy; a render process killed; Redis paused) ----------
STACK_SETTINGS = {"width": 48, "height": 64, "max_recursion_depth": 2, "samples_per_pixel": 1, "min_weight": 0.0,
                  "format": "npy"}


def _stack_children(pid: int) -> dict:
    """The stack's children by role, from /proc: {"redis": pid, "haproxy": pid, "renders": {port: pid}}."""
    out: dict = {"redis": None, "haproxy": None, "renders": {}}
    try:
        kids = [int(k) for t in Path(f"/proc/{pid}/task").iterdir()
                for k in (t / "children").read_text().split()]
    except OSError:
        return out
    for k in kids:
        try:
            argv = Path(f"/proc/{k}/cmdline").read_bytes().decode(errors="replace").split("\0")
            state = next(line for line in Path(f"/proc/{k}/status").read_text().splitlines()
                         if line.startswith("State:"))
        except (OSError, StopIteration):
            continue
        if "Z" in state.split()[1]:
            continue                     # exited, not yet reaped
        if "redis-server" in argv[0]:      # it rewrites its title: "redis-server 127.0.0.1:port"
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
                    log.append((start, time.monotonic() - t0, "gesture" if gesture else "frame", r.status_code,
                                r.headers.get("content-type", "").startswith("application/json"),
                                "retry-after" in r.headers, r.headers.get("x-served-by"),
                                r.json()["version"] if gesture and r.status_code == 200 else None,
                                None if r.status_code < 400 else r.text[:120], sid))
                    ok = r.status_code < 400
                except httpx.HTTPError as e:
                    log.append((start, time.monotonic() - t0, "gesture" if gesture else "frame", None, False, False,
                                None, None, f"{type(e).__name__}: {e}"[:120], sid))
                    ok = False
                await asyncio.sleep(0.05 if ok else 0.2)   # a finger's pace; a little longer after a refusal

    await asyncio.gather(*(client(i, sid) for i, sid in enumerate(sids)))


def _stack_phase(log: list, lo: float, hi: float) -> dict:
    """The requests that ended in [lo, hi) (a request in flight when a phase begins is that phase's)."""
    rows = [r for r in log if lo <= r[1] < hi]
    failed = [r for r in rows if r[3] is None or r[3] >= 400]
    kinds: dict[str, int] = {}
    for r in failed:
        key = ("connection error" if r[3] is None else
               f"{r[3]} {'service JSON' if r[6] else 'balancer JSON' if r[4] else 'balancer page'}"
               f"{' +Retry-After' if r[5] else ''}")
        kinds[key] = kinds.get(key, 0) + 1
    return {"requests": len(rows), "failed": len(failed),
            "failed_pct": round(100 * len(failed) / max(1, len(rows)), 2), "failures": kinds,
            "examples": sorted({f"{r[2]} {r[8]}" for r in failed if r[8]})[:4]}


def part_stack(root: Path, args) -> dict:
    """``python -m server.stack`` of ``root`` (Redis, two render processes, HAProxy); ``--stack-clients``
    clients for ``--stack-load-s``, then ``kill -9`` of render0 and ``--stack-kill-s`` more, then Redis
    stopped (SIGSTOP) for ``--stack-pause-s`` and ``--stack-pause-s`` more after it is back."""
    import asyncio
    import signal
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="bench-stack-"))
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCKETRAY_")}
    env.update(POCKETRAY_LOG_LEVEL="warning", POCKETRAY_QUEUE_SIZE=str(args.stack_clients),
               POCKETRAY_REDIS_TIMEOUT_S="2")
    err = open(tmp / "stack.err", "wb")
    proc = subprocess.Popen([sys.executable, "-m", "server.stack", "--port", str(port), "--dir", str(tmp / "stack")],
                            cwd=root, env=env, stdout=err, stderr=subprocess.STDOUT)
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
                r = c.post("/api/sessions", json={"scenario": 3, "n": 64, "seed": len(sids),
                                                  "settings": STACK_SETTINGS})
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
        out["end"] = {"acknowledged_gestures": sum(1 for r in log if r[7] is not None), "lost_writes": lost,
                      "sessions_unreadable": unread, "stack_running": proc.poll() is None,
                      "render_processes": len(kids["renders"]), "redis": bool(kids["redis"]),
                      "haproxy": bool(kids["haproxy"])}
        out["stack_log"] = [line for line in (tmp / "stack.err").read_text().splitlines()
                            if line.startswith("stack:")][-6:]
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


PARTS = {"targets": part_targets, "bad": part_bad, "largest": part_largest, "recipe": part_recipe,
         "health": part_health,
         "stalled": part_stalled,
         "stack": part_stack}


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
    ap.add_argument("--stack-clients", type=int, default=80, help="stack: concurrent clients (one session each)")
    ap.add_argument("--stack-load-s", type=float, default=15, help="stack: seconds of load before the kill")
    ap.add_argument("--stack-kill-s", type=float, default=10,
                    help="stack: seconds after kill -9 of render0 (0: no kill)")
    ap.add_argument("--stack-pause-s", type=float, default=5, help="stack: seconds Redis is stopped (and after)")
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
