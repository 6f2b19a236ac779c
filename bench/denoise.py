"""Time to 30 dB with and without the denoiser (renderer/image/denoise.py): the Cornell box at a
phone-ish size, its samples accumulated frame after frame as the service's ``accumulate=1`` does,
each mean compared with a converged image — noisy, denoised by OIDN with the albedo and normal
guides (``denoise=oidn``), and denoised by OIDN from the colour alone (what the guides add).

The converged image is the same integrator at ``--reference-spp`` samples drawn from sample
index 2^20 on (the accumulation's frames start at 0), so its noise is independent of the curves'.
PSNR as the tests measure it: linear radiance clipped to [0, 1]. A row's time is the GL time of
the frames up to it (each one uploaded, traced and read back, as the service's) plus, for a
denoised row, that mean's denoising.

Usage::

    .venv/bin/python -m bench.denoise                         # 120 × 248, reference 1,024 samples
    .venv/bin/python -m bench.denoise --width 180 --height 370 --reference-spp 2048 --max-spp 512
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from renderer.config.settings import RenderSettings
from renderer.image.denoise import denoise_result
from renderer.scenes.scenarios import mesh_scene

TARGET_DB = 30.0
REFERENCE_FIRST = 1 << 20  # the reference's first sample index: none of the curves' samples
PHONE = (120, 248)  # a 360 × 740 phone screen at a third of its CSS pixels


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


def colour_only(image: np.ndarray) -> np.ndarray:
    import pyoidn

    return np.asarray(pyoidn.denoise(np.ascontiguousarray(image, np.float32), hdr=True), np.float32)


def measure(
    width: int,
    height: int,
    reference_spp: int,
    max_spp: int,
    depth: int,
    out: Callable[[str], None],
    renderer: Any = None,
) -> dict:
    """The curves (rows: total samples, seconds, dB of each) and the time each reaches TARGET_DB;
    ``out`` gets the table's lines as they are measured."""
    if renderer is None:
        from renderer.gl.renderer import GLRenderer

        renderer = GLRenderer()
    scene = mesh_scene("cornell", 0)

    def settings(spp: int) -> RenderSettings:  # denoise on: the frames write the guides (radiance unchanged)
        return RenderSettings(
            width=width,
            height=height,
            integrator="path",
            samples_per_pixel=spp,
            max_recursion_depth=depth,
            format="npy",
            denoise="oidn",
        )

    denoise_result(renderer.render(scene, settings(1)), scene, "oidn")  # warm-up: programs, OIDN's device
    t0 = time.perf_counter()
    left, total = reference_spp, None
    while left:  # the reference in frames of at most 4,096 samples, from sample REFERENCE_FIRST on
        n = min(left, 4096)
        r = renderer.begin(scene, settings(n), accumulated=(total, REFERENCE_FIRST + reference_spp - left)).run()
        total = r.sample_sum
        left -= n
    assert total is not None
    reference = total / reference_spp  # of its own samples only (its "held" count is an index offset)
    out(f"reference: {reference_spp:,} samples, {time.perf_counter() - t0:.1f} s of GL")
    out("")
    out("| samples | GL s | noisy dB | oidn dB | oidn ms | colour-only dB | colour-only ms |")
    out("|---:|---:|---:|---:|---:|---:|---:|")
    rows = []
    held: tuple[np.ndarray | None, int] = (None, 0)
    gl_s = 0.0
    spp, step = 1, 1
    while spp <= max_spp:
        t = time.perf_counter()
        r = renderer.begin(scene, settings(step), accumulated=held).run()
        gl_s += time.perf_counter() - t
        held = (r.sample_sum, spp)
        t = time.perf_counter()
        guided = denoise_result(r, scene, "oidn").image
        guided_s = time.perf_counter() - t
        t = time.perf_counter()
        plain = colour_only(r.image)
        plain_s = time.perf_counter() - t
        row = {
            "spp": spp,
            "gl_s": gl_s,
            "noisy_db": psnr(r.image, reference),
            "oidn_db": psnr(guided, reference),
            "oidn_s": guided_s,
            "colour_db": psnr(plain, reference),
            "colour_s": plain_s,
        }
        rows.append(row)
        out(
            f"| {spp:,} | {gl_s:.2f} | {row['noisy_db']:.2f} | {row['oidn_db']:.2f} | {guided_s * 1e3:.0f} "
            f"| {row['colour_db']:.2f} | {plain_s * 1e3:.0f} |"
        )
        step = spp  # doubling: the next frame adds as many as are held
        spp *= 2
    reach = {}
    for name, db, extra in (
        ("noisy", "noisy_db", None),
        ("oidn", "oidn_db", "oidn_s"),
        ("colour", "colour_db", "colour_s"),
    ):
        first = next((r for r in rows if r[db] >= TARGET_DB), None)
        reach[name] = None if first is None else (first["spp"], first["gl_s"] + (first[extra] if extra else 0.0))
    return {"rows": rows, "reach": reach, "width": width, "height": height, "reference_spp": reference_spp}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=PHONE[0])
    ap.add_argument("--height", type=int, default=PHONE[1])
    ap.add_argument("--reference-spp", type=int, default=1024)
    ap.add_argument("--max-spp", type=int, default=256)
    ap.add_argument("--depth", type=int, default=8, help="max_recursion_depth: segments of a path")
    args = ap.parse_args(argv)
    print(f"Cornell box, {args.width} × {args.height}, depth {args.depth}; PSNR against the converged image")
    data = measure(args.width, args.height, args.reference_spp, args.max_spp, args.depth, print)
    print()
    for line in reached(data, args.max_spp):
        print(line)
    return 0


def reached(data: dict, max_spp: int) -> list[str]:
    """When each curve first reaches TARGET_DB, as Markdown list items."""
    lines = []
    for name, label in (("noisy", "noisy"), ("oidn", "OIDN, albedo + normal guides"), ("colour", "OIDN, colour only")):
        got = data["reach"][name]
        said = f"not within {max_spp:,} samples" if got is None else f"{got[0]:,} samples, {got[1]:.2f} s"
        lines.append(f"- {TARGET_DB:g} dB, {label}: {said}")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
