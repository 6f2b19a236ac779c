"""The denoiser: time to 30 dB with and without OIDN on the Cornell box (``bench/denoise.py``).

Quick mode: a 48 × 96 frame, a 64-sample reference, curves to 16 samples.
"""

from __future__ import annotations

from bench import denoise as D

from .context import Context, RunInfo

NAME = "denoise"
TITLE = "Denoising — time to 30 dB with and without Intel Open Image Denoise"


def measure(ctx: Context) -> dict:
    """The table's lines as ``bench/denoise.py`` prints them, and when each curve reaches 30 dB."""
    lines: list[str] = []
    width, height, reference, top = (48, 96, 64, 16) if ctx.quick else (*D.PHONE, 1024, 256)
    data = D.measure(width, height, reference, top, 8, lines.append, renderer=ctx.renderer)
    return {
        "lines": lines,
        "reached": D.reached(data, top),
        "rows": data["rows"],
        "reach": data["reach"],
        "width": width,
        "height": height,
        "reference_spp": reference,
    }


def findings(data: dict) -> str:
    """What the rows say: the guides against colour only, and the denoised curve's head start."""
    diffs = [r["oidn_db"] - r["colour_db"] for r in data["rows"]]
    said = (
        f"Guided minus colour-only: {min(diffs):+.2f} … {max(diffs):+.2f} dB over the rows (the Cornell "
        "box's walls are flat colours, with no texture for an albedo guide to keep sharp)."
    )
    noisy, guided = data["reach"].get("noisy"), data["reach"].get("oidn")
    if noisy and guided:
        said += (
            f" 30 dB: {noisy[0] / guided[0]:,.0f}× fewer samples and {noisy[1] / guided[1]:,.1f}× less time "
            "denoised than noisy."
        )
    return said


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    body = "\n".join(data["lines"])
    reached = "\n".join(data["reached"])
    return f"""## {TITLE}

{run.caption(1, "")}

The Cornell box (`mesh_scene("cornell", 0)`, depth 8) at {data["width"]} × {data["height"]} (a
360 × 740 phone screen at a third of its CSS pixels), its samples accumulated frame after frame
(each frame as many as are held: the service's `accumulate=1`), every mean compared with a
converged image — the same integrator at {data["reference_spp"]:,} samples of its own (sample indices from 2^20 on) —
by PSNR of linear radiance clipped to [0, 1], as the tests measure. *GL s*: the frames' time up
to that row (upload, trace, read-back); a denoised row adds that mean's denoising (*ms*). Guides:
the first hit's albedo and normal averaged over the frame's samples (the `GUIDES` variant,
`docs/SHADING.md`, "Denoising"); *colour only*: OIDN without guides.

{body}

{reached}

{findings(data)}
"""
