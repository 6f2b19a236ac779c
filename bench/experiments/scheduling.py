"""The slice scheduler through the service: fairness, progressive frames, slice size.

Runs ``bench/scheduling.py``'s three measurements against render-service processes it
starts (loopback). Quick mode: the progressive timeline only, at a small size.
"""

from __future__ import annotations

from bench import scheduling as S

from .context import Context, RunInfo

NAME = "scheduling"
TITLE = "Frames as slices — fairness, progressive frames, slice size"


def measure(ctx: Context) -> dict:
    """The Markdown lines ``bench/scheduling.py`` prints as it measures (its tables)."""
    lines: list[str] = []
    out = lines.append
    if ctx.quick:
        S.progressive(1, out, size=(64, 96))
    else:
        runs = max(1, min(ctx.runs, 3))
        S.fairness(runs, 1024, out)
        S.progressive(ctx.runs, out)
        S.slices(max(1, runs - 1), 512, out)
    return {"lines": lines}


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    body = "\n".join(data["lines"])
    return f"""## {TITLE}

{run.caption(run.runs, "medians; each row from service processes started for it")}

The long frame (a BIH of one leaf over 16,384 spheres, so every ray tests every sphere) and a
light session's 32 × 32 frames beside it, with slicing off (one draw per pass, as before
slices) and on; the phone viewport's progressive timeline; the slice-size trade-off
(`POCKETRAY_SLICE_MS`). Targets: the small frame within 0.5 s beside the long one; the first
image ≤ 0.25 × the final image's time and ≤ 0.5 s.

{body}
"""
