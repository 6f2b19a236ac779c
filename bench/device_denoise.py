"""Time to 30 dB on the device, with and without the à-trous filter: the Cornell box path-traced by
the browser's WebGL2 (device mode: ANGLE on SwiftShader here, no GPU), at a small size.

For each total sample count (4, 8, 16, …) the device traces one frame of that many samples, as
the resting view's accumulation reaches it pass by pass (the same sample indices, the same sum),
once with ``denoise=off`` (the variant without guides) and once with ``denoise=atrous`` (the
guides' variant, its mean filtered before tone mapping); each mean, read back, is compared with
Mitsuba 3's image of the same scene JSON (``--reference-spp``, independent noise). PSNR as the
tests measure it: linear radiance clipped to [0, 1]. A row's time is the device's whole frame:
its passes traced (one band each, tasks in between), resolved, filtered and shown.

``--numpy``: the filters themselves, without a browser — the Cornell box and the table framed for a
phone-ish 96 × 208 (the phone's 390 × 844 CSS px at about a quarter), traced by the service's path
integrator (GLRenderer, depth 8) at 1, 4 and 16 samples with the guides, each mean shown off,
filtered by the à-trous filter of ``BEFORE`` (taken out of git), by this one and by OIDN, against
1,024 samples of the same integrator from sample index 2^20 on (independent noise): PSNR (linear
radiance clipped to [0, 1]) and SSIM (scikit-image, of the tone-mapped 8-bit images), and how far
the filter moves the converged image itself (its 1,024-sample mean filtered, against itself).

Usage::

    .venv/bin/python -m bench.device_denoise                 # 64 × 64, Mitsuba 1,024 samples
    .venv/bin/python -m bench.device_denoise --side 48 --max-spp 256
    .venv/bin/python -m bench.device_denoise --numpy         # off / old / new à-trous / OIDN, 96 × 208
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
from renderer.oracle import mitsuba_scene
from renderer.scenes.scenarios import mesh_scene

TARGET_DB = 30.0
DEPTH = 8
CORNELL = {"kind": "cornell", "detail": 0, "smooth": False}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


BEFORE = "4d332a2"  # the à-trous filter with one colour width per sample count
NUMPY_SIZE = (96, 208)
NUMPY_SCENES = ("cornell", "table")


def old_atrous():
    """``BEFORE``'s renderer/image/atrous.py's ``atrous`` (colour, albedo, normal, samples), out of git."""
    import subprocess
    import types
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    text = subprocess.run(
        ["git", "-C", str(root), "show", f"{BEFORE}:renderer/atrous.py"], check=True, capture_output=True, text=True
    ).stdout
    module = types.ModuleType("atrous_before")
    exec(compile(text, f"{BEFORE}:renderer/atrous.py", "exec"), module.__dict__)
    return module.atrous


def numpy_table(reference_spp: int) -> None:
    """The filters on the service's own frames (``--numpy``, the module's docstring)."""
    from skimage.metrics import structural_similarity

    from renderer.config.settings import RenderSettings
    from renderer.gl.renderer import GLRenderer
    from renderer.image.atrous import atrous
    from renderer.image.denoise import oidn
    from renderer.image.tonemap import display_u8
    from renderer.scenes.scenarios import framed

    def ssim(a: np.ndarray, b: np.ndarray) -> float:
        u8 = [display_u8(x, "clamp", 0.0) for x in (a, b)]
        return float(structural_similarity(*u8, channel_axis=2, data_range=255))

    before = old_atrous()
    width, height = NUMPY_SIZE
    renderer = GLRenderer()
    load0 = os.getloadavg()[0]

    def settings(spp: int) -> RenderSettings:  # denoise named: the frames carry the guides
        return RenderSettings(
            width=width, height=height, integrator="path", samples_per_pixel=spp, max_recursion_depth=DEPTH,
            format="npy", denoise="oidn",
        )  # fmt: skip

    print(f"{width} × {height}, depth {DEPTH}; reference {reference_spp:,} samples; PSNR dB / SSIM")
    for kind in NUMPY_SCENES:
        scene = framed(mesh_scene(kind), width / height)
        left, total = reference_spp, None
        while left:  # from sample 2^20 on: none of the rows' samples
            n = min(left, 256)
            r = renderer.begin(scene, settings(n), accumulated=(total, (1 << 20) + reference_spp - left)).run()
            total, left = r.sample_sum, left - n
        assert total is not None
        reference = total / reference_spp
        print(f"\n{kind}\n\n| samples | off | à-trous {BEFORE} | à-trous | OIDN |\n|---:|---:|---:|---:|---:|")
        for spp in (1, 4, 16):
            r = renderer.render(scene, settings(spp))
            assert r.guides is not None
            albedo, normal = r.guides
            images = [r.image, before(r.image, albedo, normal, spp), atrous(r.image, albedo, normal, spp)]
            images.append(oidn(r.image, albedo, normal))
            cells = [f"{psnr(x, reference):.2f} / {ssim(x, reference):.3f}" for x in images]
            print(f"| {spp} | " + " | ".join(cells) + " |", flush=True)
        moved = [psnr(f(reference, albedo, normal, reference_spp), reference) for f in (before, atrous)]
        said = f"{BEFORE} {moved[0]:.1f} dB, now {moved[1]:.1f} dB"
        print(f"\nthe {reference_spp:,}-sample mean filtered, against itself: {said}")
    print(f"\nload average {load0:.1f} → {os.getloadavg()[0]:.1f} (2 cores shared)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--numpy", action="store_true", help="the filters on the service's frames, no browser")
    ap.add_argument("--side", type=int, default=64, help="the frame's width and height")
    ap.add_argument("--max-spp", type=int, default=1024, help="the largest sample count measured")
    ap.add_argument("--reference-spp", type=int, default=1024, help="Mitsuba's samples per pixel")
    args = ap.parse_args()
    if args.numpy:
        numpy_table(args.reference_spp)
        return
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
