"""Shader variants: one client walks through ``--programs-variants`` (≥ 500) distinct legal 16 × 16
frames, each a variant the server has not compiled (method × mode × recursion depth × integrator ×
specialize × format × first hits × denoise guides, enumerated from ``renderer.config.settings.SETTINGS``
and deduplicated by ``renderer.frame.features.frame_features``), on one session, one frame at a time.

Reported: the server's resident memory idle, after the walk and after deleting the session (and its
peak), the answers by status (429: the session's rate of new variants), ``/api/health`` p50/p99/max
polled every 20 ms meanwhile — and, as the control that says what the machine's load and the
frames themselves cost, the same while ``--programs-control`` frames of one variant (compiled
once) are asked first. The server gets a Mesa shader cache of its own, empty (``MESA_SHADER_CACHE_DIR``):
a variant no earlier run compiled costs what a new variant costs. ``--programs-no-rate`` runs the server with
``POCKETRAY_NEW_VARIANTS_PER_MIN=0`` (every variant compiled: what the program cache bounds and what
compiling costs the event loop); an older checkout (``--root``) ignores the setting.
"""

from __future__ import annotations

import argparse
import itertools
import os
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

import httpx

SCENE = {"scenario": 3, "n": 64, "seed": 1, "radius": 1.0}
SIDE = 16


def variants(limit: int) -> list[dict]:
    """Up to ``limit`` frame queries of distinct shader variants of SCENE, cheapest first."""
    from renderer.config.methods import METHODS
    from renderer.config.settings import SETTINGS, RenderSettings
    from renderer.frame.features import frame_features
    from renderer.integrators import Denoiser
    from renderer.scenes.scenarios import scenario

    choices = {s.name: s.choices for s in SETTINGS if s.choices}
    one_pass = [m for m in choices["method"] if m != "auto" and not METHODS[m].capabilities.multi_pass]
    scene = scenario(SCENE["scenario"], SCENE["n"], seed=SCENE["seed"], radius=SCENE["radius"])
    out: list[dict] = []
    seen: set[tuple] = set()
    # the method and the mode vary fastest: the walk mixes every kind of variant from the start
    candidates = itertools.product(
        range(1, 17),
        ("png", "npy"),
        (False, True),  # specialize
        choices["first_hits"],
        choices["denoise"],
        choices["integrator"],
        choices["mode"],
        one_pass,
    )
    for depth, fmt, specialize, first_hits, denoise, integrator, mode, method in candidates:
        query = dict(
            width=SIDE,
            height=SIDE,
            method=method,
            mode=mode,
            max_recursion_depth=depth,
            integrator=integrator,
            specialize=specialize,
            format=fmt,
            first_hits=first_hits,
            denoise=denoise,
            samples_per_pixel=1,
        )
        try:
            settings = RenderSettings(**query)  # type: ignore[arg-type]
        except Exception:  # not a legal combination (a path's depth in Whitted, cones of a tracer …)
            continue
        if mode not in METHODS[method].capabilities.modes:
            continue
        guides = settings.denoise != Denoiser.OFF
        features, d = frame_features(scene, settings, guides=guides)
        image = fmt == "png" and not settings.path_traced
        primary = first_hits if mode in ("depth", "primid", "normal") else ""
        key = (method, mode, d, features.defines(), image, primary)
        if key in seen:
            continue
        seen.add(key)
        out.append(query)
        if len(out) >= limit:
            break
    return out


def part_programs(root: Path, args: argparse.Namespace) -> dict:
    from bench.hostile import Server, health_while, wait_stats

    queries = variants(args.programs_variants + 1)  # the first is the control's
    settings = {"new_variants_per_min": "0"} if args.programs_no_rate else {}
    mesa_cache = tempfile.TemporaryDirectory()
    before = os.environ.get("MESA_SHADER_CACHE_DIR")
    os.environ["MESA_SHADER_CACHE_DIR"] = mesa_cache.name  # the child's environment is this one's
    try:
        s = Server(root, **settings)
    finally:
        if before is None:
            del os.environ["MESA_SHADER_CACHE_DIR"]
        else:
            os.environ["MESA_SHADER_CACHE_DIR"] = before
    try:
        with httpx.Client(base_url=s.url, timeout=120) as c:
            r = c.post("/api/sessions", json=SCENE)
            r.raise_for_status()
            sid = r.json()["id"]
            c.get(f"/api/sessions/{sid}/frame", params=queries[0]).raise_for_status()  # compiled: the control's
            control_codes: Counter[int] = Counter()

            def control() -> None:
                with httpx.Client(base_url=s.url, timeout=600) as cc:
                    for _ in range(args.programs_control):
                        control_codes[cc.get(f"/api/sessions/{sid}/frame", params=queries[0]).status_code] += 1

            control_waits = health_while(c, [threading.Thread(target=control)], limit_s=3600)
            time.sleep(1.0)
            idle = s.memory()["VmRSS"]
            codes: Counter[int] = Counter()
            t_start = time.perf_counter()

            def walk() -> None:
                with httpx.Client(base_url=s.url, timeout=600) as cc:
                    for q in queries[1:]:
                        codes[cc.get(f"/api/sessions/{sid}/frame", params=q).status_code] += 1

            waits = health_while(c, [threading.Thread(target=walk)], limit_s=3600)
            seconds = time.perf_counter() - t_start
            after = s.memory()
            c.delete(f"/api/sessions/{sid}")
            time.sleep(2.0)
            deleted = s.memory()["VmRSS"]
        return {
            "variants": len(queries) - 1,
            "rate_limit": not args.programs_no_rate,
            "codes": dict(sorted(codes.items())),
            "seconds": round(seconds, 1),
            "rss_idle_mib": round(idle),
            "rss_after_mib": round(after["VmRSS"]),
            "rss_peak_mib": round(after["VmHWM"]),
            "rss_after_delete_mib": round(deleted),
            "rss_growth_mib": round(after["VmRSS"] - idle),
            **wait_stats(waits),
            "control_frames": dict(sorted(control_codes.items())),
            **{f"control_{k}": v for k, v in wait_stats(control_waits).items()},
        }
    finally:
        s.close()
        mesa_cache.cleanup()


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument(
        "--programs-variants", type=int, default=500, help="programs: distinct shader variants the client asks for"
    )
    ap.add_argument(
        "--programs-control",
        type=int,
        default=100,
        help="programs: frames of one variant asked first (the control of the health figures)",
    )
    ap.add_argument(
        "--programs-no-rate",
        action="store_true",
        help="programs: POCKETRAY_NEW_VARIANTS_PER_MIN=0 (no rate of new variants: every one compiled)",
    )


PARTS = {"programs": part_programs}
