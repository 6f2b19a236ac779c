"""Admission by a frame's true cost (docs/API.md, "Memory budget"), against a real ``python -m server``
of ``--root`` with its defaults:

- ``admission_lockout``: one session asks for a ``--lockout-side``² (4096²) path colour jpeg frame with
  ``accumulate=1`` (depth 1, 1 sample: under every cap), and meanwhile another session asks for a
  64 × 64 frame every 0.5 s for ``--lockout-s`` seconds: the large frame's status and time, the small
  frames' statuses and latencies (target: no 503, each within 1 s). Then the same with the largest
  such frame this checkout accepts (:func:`largest_side`), which runs.
- ``admission_rss``: ``--rss-frames`` (8) concurrent path+accumulate+``denoise=oidn`` jpeg frames of
  the largest side this checkout accepts (or ``--rss-side``), one session each (503s retried after
  their Retry-After): the server's peak resident memory above the idle process against the 3 GiB
  budget, and what it still holds ``--rss-settle-s`` after the last answer.
- ``admission_oidn_bytes``: the bytes a pixel OIDN adds over one denoise (VmHWM's rise, one process
  per side of ``--oidn-sides``), the measurement behind ``renderer.image.denoise.OIDN_BYTES_PER_PIXEL``.

The largest side is computed from this checkout's estimate (``server.frames.pipeline.frame_nbytes``)
and the default settings, so that the same workload runs against an older ``--root`` too (which
would admit larger frames: the side is never probed on the server). Loopback only; bounded loops.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx

MIB = 1 << 20
BUDGET_MIB = 3 * 1024  # docs/API.md, "Memory budget": above the idle process
SCENE = {"scenario": 3, "n": 64, "seed": 1, "radius": 1.0}
PATH = {"integrator": "path", "max_recursion_depth": 1, "samples_per_pixel": 1, "format": "jpeg", "min_weight": 0.0}


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--lockout-side", type=int, default=4096)
    ap.add_argument("--lockout-s", type=float, default=12.0)
    ap.add_argument("--rss-frames", type=int, default=8)
    ap.add_argument("--rss-side", type=int, default=0, help="0: the largest this checkout accepts")
    ap.add_argument("--rss-settle-s", type=float, default=5.0)
    ap.add_argument("--oidn-sides", default="512,1024")


def largest_side(denoise: str = "off", accumulate: bool = True) -> int:
    """The largest square path jpeg frame (depth 1, 1 sample) whose estimate fits one frame's bytes
    at the default settings of this checkout."""
    from renderer.config.settings import RenderSettings
    from server.config import ServerConfig
    from server.frames.pipeline import frame_nbytes

    config = ServerConfig()
    limit = min(getattr(config, "max_frame_bytes", config.max_frame_bytes_in_flight), config.max_frame_bytes_in_flight)
    settings = {k: v for k, v in PATH.items() if k != "min_weight"}
    lo, hi = 1, 4096
    while lo < hi:
        mid = (lo + hi + 1) // 2
        s = RenderSettings(**settings, width=mid, height=mid, mode="color", denoise=denoise)
        lo, hi = (mid, hi) if frame_nbytes(s, accumulate) <= limit else (lo, mid - 1)
    return lo


def _session(c: httpx.Client, seed: int = 1) -> str:
    r = c.post("/api/sessions", json={**SCENE, "seed": seed, "settings": PATH})
    r.raise_for_status()
    return r.json()["id"]


def _lockout_round(url: str, side: int, seconds: float) -> dict:
    with httpx.Client(base_url=url, timeout=600) as c:
        big_sid, small_sid = _session(c, 1), _session(c, 2)
        assert c.get(f"/api/sessions/{small_sid}/frame", params={"width": 64, "height": 64}).status_code == 200
    big: dict = {}

    def large() -> None:
        t0 = time.perf_counter()
        with httpx.Client(base_url=url, timeout=600) as c:
            r = c.get(f"/api/sessions/{big_sid}/frame", params={"width": side, "height": side, "accumulate": 1})
        big.update(status=r.status_code, seconds=round(time.perf_counter() - t0, 2))
        if r.status_code != 200:
            big["detail"] = r.text[:400]

    t = threading.Thread(target=large)
    t.start()
    time.sleep(0.3)  # the large frame planned and (if admitted) reserving
    codes: list[int] = []
    latency: list[float] = []
    slowest = ""
    t_end = time.perf_counter() + seconds
    with httpx.Client(base_url=url, timeout=60) as c:
        while time.perf_counter() < t_end or (t.is_alive() and time.perf_counter() < t_end + 120):
            t0 = time.perf_counter()
            r = c.get(f"/api/sessions/{small_sid}/frame", params={"width": 64, "height": 64})
            latency.append(time.perf_counter() - t0)
            codes.append(r.status_code)
            if latency[-1] >= max(latency):
                slowest = r.headers.get("server-timing", r.text[:200])
            time.sleep(max(0.0, 0.5 - (time.perf_counter() - t0)))
    t.join(600)
    return {
        "side": side,
        "large": big,
        "small_frames": len(codes),
        "small_codes": {str(k): codes.count(k) for k in sorted(set(codes))},
        "small_p50_ms": round(1e3 * statistics.median(latency), 1),
        "small_max_ms": round(1e3 * max(latency), 1),
        "small_over_1s": sum(x > 1.0 for x in latency),
        "slowest_small_timing": slowest,  # its stages (Server-Timing), or its answer
    }


def part_lockout(root: Path, args) -> dict:
    from bench.hostile import Server

    s = Server(root)
    try:
        out = {"over": _lockout_round(s.url, args.lockout_side, args.lockout_s)}
        out["largest_accepted"] = _lockout_round(s.url, largest_side(), args.lockout_s)
        out["rss_peak_mib"] = round(s.memory()["VmHWM"])
        return out
    finally:
        s.close()


def part_rss(root: Path, args) -> dict:
    from bench.hostile import Server

    side = args.rss_side or largest_side("oidn")
    count = args.rss_frames
    s = Server(root, render_timeout_s="600", queue_size=str(max(8, count)))
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            sids = [_session(c, i) for i in range(count)]
            warm = {"width": 64, "height": 64, "denoise": "oidn", "accumulate": 1}
            assert c.get(f"/api/sessions/{sids[0]}/frame", params=warm).status_code == 200  # OIDN loaded
        time.sleep(1)
        idle = s.memory()
        codes: list[int] = []
        retries = [0]
        t_start = time.perf_counter()

        def frame(sid: str) -> None:
            params = {"width": side, "height": side, "denoise": "oidn", "accumulate": 1}
            with httpx.Client(base_url=s.url, timeout=600) as c:
                while True:
                    r = c.get(f"/api/sessions/{sid}/frame", params=params)
                    if r.status_code == 503 and time.perf_counter() - t_start < 600:
                        retries[0] += 1
                        time.sleep(float(r.headers.get("retry-after", "1")))
                        continue
                    codes.append(r.status_code)
                    return

        threads = [threading.Thread(target=frame, args=(sid,)) for sid in sids]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        seconds = time.perf_counter() - t_start
        peak = s.memory()
        time.sleep(args.rss_settle_s)
        after = s.memory()
        return {
            "frames": count,
            "side": side,
            "codes": sorted(codes),
            "retries_503": retries[0],
            "seconds": round(seconds, 1),
            "rss_idle_mib": round(idle["VmRSS"]),
            "peak_above_idle_mib": round(peak["VmHWM"] - idle["VmRSS"]),
            "budget_mib": BUDGET_MIB,
            "held_after_mib": round(after["VmRSS"] - idle["VmRSS"]),
        }
    finally:
        s.close()


OIDN_PROBE = r"""
import ctypes, sys, numpy as np, pyoidn
def kib(field):
    for line in open('/proc/self/status'):
        if line.startswith(field):
            return int(line.split()[1]) * 1024
side = int(sys.argv[1])
rng = np.random.default_rng(0)
color, albedo, normal = (rng.random((side, side, 3), dtype=np.float32) for _ in range(3))
device = pyoidn.Device(); device.commit()
def run(images):
    f = pyoidn.Filter(device, pyoidn.OIDN_FILTER_TYPE_RT)
    for name, x in images:
        f.set_image(name, x, pyoidn.OIDN_FORMAT_FLOAT3)
    f.set_bool('hdr', True); f.set_quality(pyoidn.OIDN_QUALITY_HIGH); f.commit(); f.execute()
    return f
small = np.ones((16, 16, 3), np.float32)
run([('color', small), ('albedo', small), ('normal', small), ('output', small.copy())]).release()
ctypes.CDLL('libc.so.6').malloc_trim(0)
base = kib('VmRSS:')
open('/proc/self/clear_refs', 'w').write('5')  # VmHWM from here
out = np.empty_like(color)
f = run([('color', color), ('albedo', albedo), ('normal', normal), ('output', out)])
peak = kib('VmHWM:')
f.release()
released = kib('VmRSS:')
print(side, (peak - base) / side / side, (released - base) / side / side)
"""


def part_oidn_bytes(root: Path, args) -> dict:
    out = {}
    for side in (int(x) for x in args.oidn_sides.split(",")):
        proc = subprocess.run(
            [sys.executable, "-c", OIDN_PROBE, str(side)], capture_output=True, text=True, timeout=600, check=True
        )
        _, peak, released = proc.stdout.split()
        out[f"{side}²"] = {"bytes_per_pixel": round(float(peak), 1), "after_release": round(float(released), 1)}
    return out


PARTS = {"admission_lockout": part_lockout, "admission_rss": part_rss, "admission_oidn_bytes": part_oidn_bytes}
