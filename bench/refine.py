"""Refinement while still (docs/API.md, "Refinement"): what the accumulations of refining sessions
hold, and what they cost another session's interactive frames.

1. **Memory.** ``--sessions`` (8) Cornell-box sessions (``integrator=path``, ``--width`` ×
   ``--height`` png) refine at once (``GET …/frame?refine=1``, each to ``--samples`` samples): the
   server's resident memory (VmRSS, and its high-water mark VmHWM) before, the highest sampled while
   they refine, after, and ``pocketray_accumulation_bytes`` (the float32 sums held) at the end.
2. **A light session's latency.** While ``--busy`` (4) sessions refine (to a target they do not
   reach during the measurement), a light session (scenario 1, 16 spheres, Whitted, depth 2) asks
   ``--frames`` (≥ 10) 32 × 32 png frames one after another: client-side latency median and p90,
   beside the same frames with nothing else running. Target: ≤ 0.5 s.

Usage::

    .venv/bin/python -m bench.refine
    .venv/bin/python -m bench.refine --url http://127.0.0.1:8000 --frames 20
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import threading
import time
from pathlib import Path

import httpx

from bench.child import ServerChild

ROOT = Path(__file__).resolve().parent.parent
CORNELL = {"mesh_scene": {"kind": "cornell", "detail": 0}}
LIGHT = {"scenario": 1, "n": 16, "seed": 0, "radius": 1.0}
# Room for the sessions' frames at once (the service's defaults admit fewer frames in flight).
SERVER_SETTINGS = {"queue_size": 16, "max_frame_bytes_in_flight": 1 << 30, "max_refine_ms": 600_000}


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))]


def accumulation_bytes(c: httpx.Client) -> float:
    m = re.search(r"^pocketray_accumulation_bytes(?:\{[^}]*\})? (\S+)$", c.get("/metrics").text, re.M)
    return float(m.group(1)) if m else float("nan")


def session(c: httpx.Client, body: dict, settings: dict) -> str:
    r = c.post("/api/sessions", json={**body, "settings": settings})
    r.raise_for_status()
    return r.json()["id"]


def refine_until_done(url: str, sid: str, params: dict, out: list, stop: threading.Event | None = None) -> None:
    """One refinement stream read to its end (or until ``stop``); appends the samples of each part."""
    with httpx.Client(base_url=url, timeout=600) as c:
        with c.stream("GET", f"/api/sessions/{sid}/frame", params={**params, "refine": 1}) as r:
            r.raise_for_status()
            for chunk in r.iter_bytes():
                out.extend(int(v) for v in re.findall(rb"X-Samples: (\d+)", chunk))
                if stop is not None and stop.is_set():
                    return


def light_frames(c: httpx.Client, sid: str, frames: int) -> list[float]:
    """Client-side latency of ``frames`` 32 × 32 frames of the light session, ms."""
    out = []
    for _ in range(frames):
        t0 = time.perf_counter()
        r = c.get(f"/api/sessions/{sid}/frame", params={"width": 32, "height": 32, "format": "png"})
        r.raise_for_status()
        out.append((time.perf_counter() - t0) * 1e3)
    return out


def measure(
    url: str,
    server: ServerChild | None,
    *,
    sessions: int = 8,
    busy: int = 4,
    width: int = 180,
    height: int = 370,
    samples: int = 64,
    depth: int = 4,
    frames: int = 12,
) -> dict:
    """Both measurements against the service at ``url`` (``server``: the process started for them,
    whose memory is read; None: an outside one, memory not read)."""
    path = {
        "integrator": "path",
        "width": width,
        "height": height,
        "format": "png",
        "max_recursion_depth": depth,
        "samples_per_pixel": 1,
    }
    results: dict = {}
    with httpx.Client(base_url=url, timeout=600) as c:
        # 1. memory of `sessions` refining at once
        sids = [session(c, CORNELL, path) for _ in range(sessions)]
        before = server.memory() if server else {}
        counts: list[list[int]] = [[] for _ in sids]
        params = {"refine_samples": samples, "refine_time_ms": 600_000}
        threads = [
            threading.Thread(target=refine_until_done, args=(url, s, params, counts[i])) for i, s in enumerate(sids)
        ]
        t0 = time.perf_counter()
        for t in threads:
            t.start()
        peak = 0.0
        while any(t.is_alive() for t in threads):
            if server:
                peak = max(peak, server.memory()["VmRSS"])
            time.sleep(0.2)
        wall = time.perf_counter() - t0
        after = server.memory() if server else {}
        results["memory"] = {
            "sessions": sessions,
            "size": f"{width}x{height}",
            "depth": depth,
            "samples": samples,
            "frames_per_stream": [len(x) for x in counts],
            "final_samples": [x[-1] if x else 0 for x in counts],
            "wall_s": round(wall, 1),
            "rss_before_mib": before.get("VmRSS"),
            "rss_peak_mib": peak or None,
            "rss_after_mib": after.get("VmRSS"),
            "hwm_mib": after.get("VmHWM"),
            "accumulation_bytes": accumulation_bytes(c),
            "expected_bytes": sessions * width * height * 12,
        }

        # 2. a light session's 32 × 32 frames, alone and while `busy` sessions refine
        light = session(c, LIGHT, {"width": 32, "height": 32, "max_recursion_depth": 2, "samples_per_pixel": 1})
        light_frames(c, light, 2)  # its shader variant compiled, its tree built
        alone = light_frames(c, light, frames)
        busy_sids = [session(c, CORNELL, path) for _ in range(busy)]
        stop = threading.Event()
        seen: list[list[int]] = [[] for _ in busy_sids]
        long = {"refine_samples": 65536, "refine_time_ms": 600_000}
        threads = [
            threading.Thread(target=refine_until_done, args=(url, s, long, seen[i], stop), daemon=True)
            for i, s in enumerate(busy_sids)
        ]
        for t in threads:
            t.start()
        while min(len(x) for x in seen) < 2:  # every stream past its first frame: accumulating
            time.sleep(0.1)
        during = light_frames(c, light, frames)
        refined = [x[-1] for x in seen]
        stop.set()
        for s in busy_sids:  # any interactive frame of a session ends its stream's frame: the streams stop
            c.get(f"/api/sessions/{s}/frame", params={"width": 8, "height": 8, "format": "png"})
        results["latency"] = {
            "busy": busy,
            "frames": frames,
            "alone_ms": [round(x, 1) for x in alone],
            "during_ms": [round(x, 1) for x in during],
            "alone_p50_ms": round(statistics.median(alone), 1),
            "alone_p90_ms": round(pct(alone, 0.9), 1),
            "during_p50_ms": round(statistics.median(during), 1),
            "during_p90_ms": round(pct(during, 0.9), 1),
            "during_max_ms": round(max(during), 1),
            "busy_samples_reached": refined,
        }
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", help="an already running service (default: start one; memory needs one started here)")
    ap.add_argument("--sessions", type=int, default=8)
    ap.add_argument("--busy", type=int, default=4)
    ap.add_argument("--width", type=int, default=180)
    ap.add_argument("--height", type=int, default=370)
    ap.add_argument("--samples", type=int, default=64, help="refine_samples of the memory run")
    ap.add_argument("--depth", type=int, default=4, help="path segments")
    ap.add_argument("--frames", type=int, default=12)
    args = ap.parse_args()
    server = None if args.url else ServerChild(ROOT, SERVER_SETTINGS)
    url = args.url or server.url
    try:
        info = httpx.get(url + "/api/ready", timeout=10).json()
        print(f"# refinement while still — GL: {info.get('gl_renderer')} | CPUs: {os.cpu_count()}")
        print(f"# load avg before: {os.getloadavg()[0]:.2f}")
        r = measure(
            url,
            server,
            sessions=args.sessions,
            busy=args.busy,
            width=args.width,
            height=args.height,
            samples=args.samples,
            depth=args.depth,
            frames=args.frames,
        )
        print(json.dumps(r["memory"]))
        print(json.dumps(r["latency"]))
        lat = r["latency"]
        print(
            f"\n| light 32×32 frame | p50 ms | p90 ms |\n|---|---|---|\n"
            f"| alone | {lat['alone_p50_ms']} | {lat['alone_p90_ms']} |\n"
            f"| while {args.busy} sessions refine | {lat['during_p50_ms']} | {lat['during_p90_ms']} |"
        )
    finally:
        if server:
            server.close()


if __name__ == "__main__":
    main()
