"""Frames whose work the cost model did not see: spheres that all cover the same pixels.

``overdraw``: per case, a fresh server (defaults); one session holds ``n`` coincident spheres, each
covering the whole frame (the default camera, 100 units away; radius 90), or thesis scenario 3 of
65,536 spheres. Its client asks for one ``--overdraw-side``² depth frame (scenario 3: 2048²) with
``first_hits`` raster, tiles, auto or trace and is gone after 3 s; meanwhile another session asks for a
64 × 64 frame every 0.5 s for ``--overdraw-watch-s`` seconds. Reported: the big frame's status (422: refused up
front; ``gone``: the client gave up first), and the small frames' statuses and latencies — the target
is no 503 and at most 1 s each, however the big frame was answered.

    .venv/bin/python -m bench.hostile overdraw
    .venv/bin/python -m bench.hostile overdraw --root /tmp/base --overdraw-cases 20000:raster,s3:auto
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path

import httpx

HOWS = ("raster", "tiles", "auto", "trace")
DEFAULT_CASES = ",".join(f"{n}:{how}" for n in ("20000", "100000", "s3") for how in HOWS)
SMALL = {"width": 64, "height": 64, "format": "png"}


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument(
        "--overdraw-cases",
        default=DEFAULT_CASES,
        help="overdraw: comma-separated n:first_hits (n coincident spheres, or s3: scenario 3 of 65,536 at 2048²)",
    )
    ap.add_argument("--overdraw-side", type=int, default=1024, help="overdraw: the coincident spheres' frame side")
    ap.add_argument("--overdraw-watch-s", type=float, default=15.0, help="overdraw: how long the small frames go on")
    ap.add_argument(
        "--overdraw-max-frame-cost",
        default=None,
        help="overdraw: POCKETRAY_MAX_FRAME_COST of the servers (a large one admits the frames: slices are tried)",
    )


def coincident_body(n: int) -> bytes:
    """A scene of ``n`` spheres at the origin, each covering the default camera's whole frame."""
    sphere = b'{"center":[0,0,0],"radius":90}'
    settings = b'"settings":{"mode":"depth","width":64,"height":64}'  # admitted: the big frame is asked for later
    return b'{"scene":{"materials":[{}],"spheres":[' + b",".join([sphere] * n) + b"]}," + settings + b"}"


def one_case(root: Path, n: str, how: str, side: int, watch_s: float, cap: str | None = None) -> dict:
    from bench.hostile import Server

    s = Server(root, **({"max_frame_cost": cap} if cap else {}))
    try:
        with httpx.Client(base_url=s.url, timeout=60) as c:
            small = c.post("/api/sessions", json={"scenario": 1, "n": 64}).json()["id"]
            if n == "s3":
                settings = {"mode": "depth", "width": 64, "height": 64}
                big = c.post("/api/sessions", json={"scenario": 3, "n": 65536, "settings": settings})
                frame_side = 2048
            else:
                big = c.post(
                    "/api/sessions", content=coincident_body(int(n)), headers={"content-type": "application/json"}
                )
                frame_side = side
            if big.status_code != 201:
                return {"session": big.status_code, "detail": big.text[:200]}
            big_id = big.json()["id"]
            assert c.get(f"/api/sessions/{small}/frame", params=SMALL).status_code == 200  # warm
        out: dict = {}

        def attack() -> None:
            t0 = time.perf_counter()
            params = {
                "width": frame_side,
                "height": frame_side,
                "mode": "depth",
                "first_hits": how,
                "format": "png",
                "max_recursion_depth": 1,  # (a depth frame traces one level: past POCKETRAY_MAX_WORK's product)
                "samples_per_pixel": 1,
            }
            try:
                with httpx.Client(base_url=s.url, timeout=3.0) as c:  # the client gives up after 3 s
                    r = c.get(f"/api/sessions/{big_id}/frame", params=params)
                out["big"] = r.status_code
                if r.status_code == 422:
                    out["big_detail"] = r.json()["detail"][0]["msg"][:160]
            except httpx.TimeoutException:
                out["big"] = "gone"
            out["big_s"] = round(time.perf_counter() - t0, 2)

        t = threading.Thread(target=attack)
        t.start()
        time.sleep(0.2)
        codes: list[int] = []
        lat: list[float] = []
        t_end = time.perf_counter() + watch_s
        with httpx.Client(base_url=s.url, timeout=300) as c:
            while time.perf_counter() < t_end:
                t0 = time.perf_counter()
                r = c.get(f"/api/sessions/{small}/frame", params=SMALL)
                lat.append(time.perf_counter() - t0)
                codes.append(r.status_code)
                time.sleep(max(0.0, 0.5 - (time.perf_counter() - t0)))
        t.join()
        lat.sort()
        return {
            **out,
            "small_frames": len(codes),
            "small_503": codes.count(503),
            "small_other": sorted({x for x in codes if x not in (200, 503)}),
            "small_p50_ms": round(1e3 * lat[len(lat) // 2]) if lat else None,
            "small_max_ms": round(1e3 * lat[-1]) if lat else None,
        }
    finally:
        s.close()


def part_overdraw(root: Path, args) -> dict:
    results = {}
    for case in args.overdraw_cases.split(","):
        n, _, how = case.strip().partition(":")
        results[f"{n} {how}"] = one_case(
            root, n, how or "auto", args.overdraw_side, args.overdraw_watch_s, args.overdraw_max_frame_cost
        )
        print(json.dumps({f"{n} {how}": results[f"{n} {how}"]}), file=sys.stderr, flush=True)  # a long run's progress
    return results


PARTS = {"overdraw": part_overdraw}
