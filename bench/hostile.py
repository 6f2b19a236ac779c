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


# ---- model files (issue 24: hostile glTF/GLB bodies; renderer/model_guard.py, server/model_worker.py) -------------
def accessor_gltf(count: int) -> bytes:
    """~250 bytes: one accessor of ``count`` VEC3 without a bufferView (zeros the file does not hold)."""
    return json.dumps({"asset": {"version": "2.0"}, "bufferViews": [],
                       "accessors": [{"componentType": 5126, "count": count, "type": "VEC3"}],
                       "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}],
                       "scenes": [{"nodes": [0]}], "scene": 0}).encode()


def chain_glb(n: int) -> bytes:
    """A GLB of one triangle under a chain of ``n`` nodes (the parser's cost grows with depth²)."""
    import struct
    tri = b"".join(struct.pack("<3f", *v) for v in ((0, 0, 0), (1, 0, 0), (0, 1, 0)))
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": 36}],
           "bufferViews": [{"buffer": 0, "byteLength": 36}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
           "nodes": [{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}],
           "scenes": [{"nodes": [0]}], "scene": 0}
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
    r = httpx.post(url + "/api/meshes", params={"format": fmt}, content=data,
                   headers={"content-type": "application/octet-stream"}, timeout=timeout)
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
                post_model(s.url, export_box_obj(), "obj", [])     # the first upload starts the parsers
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
                    "body_bytes": len(body), "codes": sorted(c for c, _, _ in got),
                    "seconds": round(time.perf_counter() - t0, 2), "each_s": sorted(x for _, x, _ in got),
                    "peak_above_idle_mib": round(mem["VmHWM"] - idle["VmRSS"]),
                    "workers_peak_mib": children_hwm_mib(s.proc.pid), "answer": got[0][2]}
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
                    waits = []
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
                    w = sorted(waits)
                    out[f"{n:,} x{k}"] = {
                        "body_mb": round(len(body) / 1e6, 2), "codes": sorted(c_ for c_, _, _ in got),
                        "each_s": sorted(x for _, x, _ in got), "health_calls": len(w),
                        "health_p50_ms": round(1e3 * statistics.median(w), 1) if w else None,
                        "health_p99_ms": round(1e3 * w[int(0.99 * (len(w) - 1))], 1) if w else None,
                        "health_max_ms": round(1e3 * w[-1], 1) if w else None, "answer": got[0][2]}
                    print(f"  {n:,} x{k}: {json.dumps(out[f'{n:,} x{k}'])}", flush=True)
    finally:
        s.close()
    return out


def part_model_overhead(root: Path, args) -> dict:
    """What a valid upload costs: POST /api/meshes of a small OBJ (80 triangles) and of a
    327,680-triangle PLY (8 MB), median of --model-repeats (one at a time, 0.2 s apart)."""
    from renderer.mesh_io import export_mesh
    from renderer.meshes import icosphere
    out = {}
    s = Server(root, max_body_bytes=str(32 * MIB))
    try:
        post_model(s.url, export_box_obj(), "obj", [])
        for name, data, fmt in (("obj_80_tris", export_mesh(icosphere(1), "obj"), "obj"),
                                ("ply_327680_tris", export_mesh(icosphere(7), "ply"), "ply")):
            got: list = []
            for _ in range(args.model_repeats):
                time.sleep(0.2)
                post_model(s.url, data, fmt, got)
            out[name] = {"bytes": len(data), "codes": sorted(set(c for c, _, _ in got)),
                         "median_s": round(statistics.median(x for _, x, _ in got), 3)}
    finally:
        s.close()
    return out
# ---- end of model files ---------------------------------------------------------------------------------------------


PARTS = {"targets": part_targets, "bad": part_bad, "largest": part_largest, "recipe": part_recipe,
         "health": part_health,
         "stalled": part_stalled,
         "model_accessor": part_model_accessor, "model_chain": part_model_chain,
         "model_overhead": part_model_overhead}


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
    ap.add_argument("--accessor-counts", type=lambda v: [int(x) for x in v.split(",")],
                    default=[30_000_000, 90_000_000], help="model_accessor: the VEC3 counts the glTF claims (comma-separated)")
    ap.add_argument("--chain-nodes", type=lambda v: [int(x) for x in v.split(",")], default=[25_000, 50_000, 100_000],
                    help="model_chain: the chains' node counts (comma-separated)")
    ap.add_argument("--model-parallel", type=int, default=3, help="model parts: the bodies sent at once")
    ap.add_argument("--model-repeats", type=int, default=9, help="model_overhead: uploads per file")
    ap.add_argument("--skip-model", type=lambda v: {(int(c), int(k)) for c, k in (p.split("x") for p in v.split(","))},
                    default=set(), help="model_accessor: COUNTxK cases not run (e.g. 90000000x3: ~20 GB before)")
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
