"""The slice scheduler through the service: fairness, progressive frames, slice size.

(a) **Fairness** — one session renders a long frame (a BIH of one leaf over many spheres,
    ~30 s); meanwhile another session asks for 32 × 32 frames one after another. Their
    latency with slicing off (``POCKETRAY_SLICE_MS`` huge: each pass is one draw, the
    behaviour before slices) and on (the default).
(b) **Progressive timeline** on the phone viewport: 390 × 844 CSS px at device pixel ratio 3,
    the client's default full frame (the screen's aspect, long side 1,088 device px),
    scenario 1 with 512 spheres, the still profile (depth 8, 4 samples, ε 0.03): load → first
    image → final image, and gesture (a pinch) → first → final, from the multipart parts'
    arrival times (``progressive=1``).
(c) **Slice-size sweep** — the long frame alone (the cost of slicing: more draws and
    glFinish calls) and the small frames' latency beside it, per ``POCKETRAY_SLICE_MS``.

Usage::

    .venv/bin/python -m bench.scheduling              # all three, servers started here
    .venv/bin/python -m bench.scheduling --only fairness,progressive --runs 5

Targets: (a) ≤ 0.5 s for the small frame beside a 30 s one; (b) first image
≤ 0.25 × the final image's time and ≤ 0.5 s after load or after the finger lifts.
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time
from pathlib import Path

import httpx

from bench.latency import Server, pct

ROOT = Path(__file__).resolve().parent.parent

PHONE = (502, 1088)  # 390 × 844 CSS px at DPR 3, fitted to a long side of 1,088 device px
STILL = {"max_recursion_depth": 8, "samples_per_pixel": 4, "min_weight": 0.03}
UNSLICED_MS = 1e4  # a slice this big (the largest allowed) never splits a pass: as before slices
HEAVY_N = 16384


def session(c: httpx.Client, scenario: int, n: int, **settings) -> str:
    r = c.post(
        "/api/sessions",
        json={"scenario": scenario, "n": n, "seed": 0, "radius": 1.0, "settings": {"format": "png", **settings}},
        timeout=120,
    )
    r.raise_for_status()
    return r.json()["id"]


def heavy_settings(width: int) -> dict:
    return {
        "width": width,
        "height": width,
        "max_recursion_depth": 1,
        "samples_per_pixel": 1,
        "method": "bih",
        "max_prims": HEAVY_N,
        "mode": "primid",
    }


def fairness_run(url: str, heavy_width: int, light_frames: int) -> dict:
    """The long frame of session A, and session B's small frames while it runs."""
    with httpx.Client(base_url=url, timeout=600) as c:
        heavy = session(c, 2, HEAVY_N, **heavy_settings(heavy_width))
        light = session(c, 1, 64, width=32, height=32, max_recursion_depth=2, samples_per_pixel=1)
        c.get(f"/api/sessions/{light}/frame").raise_for_status()  # compiled, warm
        done: dict = {}

        def long_frame():
            t0 = time.perf_counter()
            r = httpx.get(f"{url}/api/sessions/{heavy}/frame", timeout=600)
            done["status"], done["s"] = r.status_code, time.perf_counter() - t0

        t = threading.Thread(target=long_frame)
        t.start()
        time.sleep(1.0)  # it is being traced now
        waits = []
        while t.is_alive() and len(waits) < light_frames:
            t0 = time.perf_counter()
            c.get(f"/api/sessions/{light}/frame").raise_for_status()
            waits.append(time.perf_counter() - t0)
        t.join()
    return {"heavy_s": done["s"], "heavy_status": done["status"], "light": waits}


def fairness(runs: int, heavy_width: int, out=print) -> None:
    out("### (a) Fairness: a 32 × 32 frame of session B while session A traces a long frame\n")
    out(
        f"Session A: scenario 2, {HEAVY_N:,} spheres, a BIH of one leaf (max_prims {HEAVY_N:,}), "
        f"primid at {heavy_width} × {heavy_width}. Session B: scenario 1, 64 spheres, 32 × 32, one after "
        f"another while A's frame runs; {runs} run(s).\n"
    )
    out("| slicing | long frame s | B frames during it | B p50 s | B p95 s | B max s |")
    out("|---|---:|---:|---:|---:|---:|")
    for label, slice_ms in (("off (one draw per pass)", UNSLICED_MS), ("on (POCKETRAY_SLICE_MS default)", None)):
        settings = {"max_frame_cost": 1e7}
        if slice_ms is not None:
            settings["slice_ms"] = slice_ms
        server = Server(queue_size=8, **settings)
        try:
            heavy_s, waits = [], []
            for _ in range(runs):
                r = fairness_run(server.url, heavy_width, 200)
                heavy_s.append(r["heavy_s"])
                waits += r["light"]
            out(
                f"| {label} | {statistics.median(heavy_s):.1f} | {len(waits)} | {pct(waits, 0.5):.3f} | "
                f"{pct(waits, 0.95):.3f} | {max(waits):.3f} |"
            )
        finally:
            server.close()
    out("")


def parts_timeline(url: str, path: str, method: str = "GET", json=None, params=None) -> list[float]:
    """Seconds from sending to the arrival of each part of a progressive answer."""
    t0 = time.perf_counter()
    out = []
    with httpx.Client(base_url=url, timeout=600) as c:
        with c.stream(method, path, json=json, params={**(params or {}), "progressive": 1}) as r:
            r.raise_for_status()
            boundary = r.headers["content-type"].split("boundary=")[1].encode()
            buf = b""
            for chunk in r.iter_bytes():
                buf += chunk
                while True:
                    i = buf.find(b"--" + boundary + b"\r\n")
                    j = buf.find(b"\r\n\r\n", i)
                    if i < 0 or j < 0:
                        break
                    head = buf[i:j].decode()
                    length = int(
                        next(
                            line.split(":")[1]
                            for line in head.split("\r\n")
                            if line.lower().startswith("content-length")
                        )
                    )
                    if len(buf) < j + 4 + length:
                        break
                    out.append(time.perf_counter() - t0)
                    buf = buf[j + 4 + length :]
    return out


def progressive(runs: int, out=print, size: tuple[int, int] = PHONE) -> None:
    w, h = size
    out(f"### (b) Progressive timeline on the phone viewport ({w} × {h}, scenario 1, 512 spheres, still profile)\n")
    out(
        f"Seconds from the request to each part of its `progressive=1` answer; medians of {runs} run(s) after one "
        "that compiles the variants.\n"
    )
    server = Server(queue_size=8)
    try:
        rows = {"load": [], "gesture": []}
        with httpx.Client(base_url=server.url, timeout=600) as c:
            for _ in range(runs + 1):
                sid = session(c, 1, 512, width=w, height=h, **STILL)
                rows["load"].append(parts_timeline(server.url, f"/api/sessions/{sid}/frame"))
                rows["gesture"].append(
                    parts_timeline(
                        server.url,
                        f"/api/sessions/{sid}/gesture",
                        "POST",
                        json={"type": "pinch", "scale": 1.1},
                        params={"frame": 1},
                    )
                )
        out("| after | first image s | final image s | first / final | parts |")
        out("|---|---:|---:|---:|---:|")
        for what, timelines in rows.items():
            timelines = timelines[1:]  # the first run compiles the variants
            first = statistics.median(t[0] for t in timelines)
            final = statistics.median(t[-1] for t in timelines)
            out(f"| {what} | {first:.3f} | {final:.3f} | {first / final:.2f} | {len(timelines[0])} |")
        out("")
    finally:
        server.close()


def slices(runs: int, heavy_width: int, out=print, sizes=(5, 10, 20, 40, 80, 160, UNSLICED_MS)) -> None:
    out("### (c) Slice size: the long frame's own time and the small frames' latency beside it\n")
    out(
        f"The long frame of (a) at {heavy_width} × {heavy_width}: alone (median of {runs}), then with B's frames "
        "beside it.\n"
    )
    out("| POCKETRAY_SLICE_MS | long frame alone s | long frame with B s | B p50 s | B p95 s |")
    out("|---:|---:|---:|---:|---:|")
    for slice_ms in sizes:
        server = Server(queue_size=8, max_frame_cost=1e7, slice_ms=slice_ms)
        try:
            alone = []
            with httpx.Client(base_url=server.url, timeout=600) as c:
                sid = session(c, 2, HEAVY_N, **heavy_settings(heavy_width))
                c.get(f"/api/sessions/{sid}/frame").raise_for_status()
                for _ in range(runs):
                    t0 = time.perf_counter()
                    c.get(f"/api/sessions/{sid}/frame").raise_for_status()
                    alone.append(time.perf_counter() - t0)
            r = fairness_run(server.url, heavy_width, 200)
            label = "∞ (off)" if slice_ms == UNSLICED_MS else f"{slice_ms:g}"
            out(
                f"| {label} | {statistics.median(alone):.2f} | {r['heavy_s']:.2f} | {pct(r['light'], 0.5):.3f} | "
                f"{pct(r['light'], 0.95):.3f} |"
            )
        finally:
            server.close()
    out("")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default="fairness,progressive,slices")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--heavy-width", type=int, default=512, help="side of the long frame (≈30 s at 512 here)")
    args = ap.parse_args()
    only = set(args.only.split(","))
    print(f"# Slice scheduler — {os.cpu_count()} CPUs, load avg {os.getloadavg()[0]:.2f}\n")
    if "fairness" in only:
        fairness(args.runs, args.heavy_width)
    if "progressive" in only:
        progressive(args.runs)
    if "slices" in only:
        slices(max(1, args.runs - 1), args.heavy_width // 2)
    print(f"# load avg after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
