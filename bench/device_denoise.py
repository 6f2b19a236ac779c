"""Time to 30 dB on the device, with and without the à-trous filter: the Cornell box path-traced by
the browser's WebGL2 (device mode: ANGLE on SwiftShader here, no GPU), at a small size.

For each total sample count (4, 8, 16, …) the device traces one frame of that many samples, as
the resting view's accumulation reaches it pass by pass (the same sample indices, the same sum),
once with ``denoise=off`` (the variant without guides) and once with ``denoise=atrous`` (the
guides' variant, its mean filtered before tone mapping); each mean, read back, is compared with
Mitsuba 3's image of the same scene JSON (``--reference-spp``, independent noise). PSNR as the
tests measure it: linear radiance clipped to [0, 1]. A row's time is the device's whole frame:
its passes traced (one band each, tasks in between), resolved, filtered and shown.

Usage::

    .venv/bin/python -m bench.device_denoise                 # 64 × 64, Mitsuba 1,024 samples
    .venv/bin/python -m bench.device_denoise --side 48 --max-spp 256
"""

from __future__ import annotations

import argparse
import base64
import math
import os

import httpx
import numpy as np

from bench.device import device_page
from bench.latency import Server
from renderer import mitsuba_scene
from renderer.scenarios import mesh_scene

TARGET_DB = 30.0
DEPTH = 8
CORNELL = {"kind": "cornell", "detail": 0, "smooth": False}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=64, help="the frame's width and height")
    ap.add_argument("--max-spp", type=int, default=1024, help="the largest sample count measured")
    ap.add_argument("--reference-spp", type=int, default=1024, help="Mitsuba's samples per pixel")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    side = args.side
    reference = mitsuba_scene.render(mesh_scene("cornell", 0, smooth=False), side, side, args.reference_spp, DEPTH)
    server = Server(queue_size=8)
    load0 = os.getloadavg()[0]
    try:
        with sync_playwright() as pw, httpx.Client(base_url=server.url, timeout=300) as http:
            browser, page, probe = device_page(pw, server.url)
            sid = http.post("/api/sessions", json={"mesh_scene": CORNELL}).json()["id"]

            def frame(spp: int, denoise: str) -> tuple[float, np.ndarray]:
                p = dict(
                    session=sid, width=side, height=side, method="bih", mode="color", integrator="path",
                    max_recursion_depth=DEPTH, samples_per_pixel=spp, denoise=denoise, band_ms=60_000,
                    between="task",
                )  # fmt: skip
                r = page.evaluate("(p) => window.pocketray.device.renderOnce(p)", p)
                key = "denoised" if denoise == "atrous" else "radiance"
                image = np.frombuffer(base64.b64decode(r[key]), np.float32).reshape(side, side, 3)
                return r["ms"]["total"] / 1e3, image

            frame(4, "off")  # warm-up: both programs compiled
            frame(4, "atrous")
            print(f"Device: {probe['renderer']}; {side} × {side}, depth {DEPTH}; Mitsuba {args.reference_spp} samples")
            print("| samples | noisy s | noisy dB | à-trous s | à-trous dB |")
            print("|---|---|---|---|---|")
            reach: dict[str, tuple[int, float] | None] = {"noisy": None, "atrous": None}
            spp = 4
            while spp <= args.max_spp:
                t_n, noisy = frame(spp, "off")
                t_a, filtered = frame(spp, "atrous")
                db_n, db_a = psnr(noisy, reference), psnr(filtered, reference)
                print(f"| {spp:,} | {t_n:.2f} | {db_n:.2f} | {t_a:.2f} | {db_a:.2f} |", flush=True)
                for name, db, t in (("noisy", db_n, t_n), ("atrous", db_a, t_a)):
                    if reach[name] is None and db >= TARGET_DB:
                        reach[name] = (spp, t)
                if all(reach.values()):
                    break
                spp *= 2
            for name, r in reach.items():
                print(f"{name}: " + (f"{TARGET_DB:.0f} dB at {r[0]:,} samples, {r[1]:.2f} s" if r else "not reached"))
            print(f"load average {load0:.1f} → {os.getloadavg()[0]:.1f} (2 cores shared)")
            browser.close()
    finally:
        server.close()


if __name__ == "__main__":
    main()
