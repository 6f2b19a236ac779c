"""The tracer shaped for llvmpipe (issue 18), against the shader before it, in one run.

``bench/shader.py`` traces every configuration with three sides, each a worker process:
the renderer, shaders and layouts of the commit before issue 18 (extracted from git),
this checkout as the service runs it (record arrays in uniform blocks where they fit, an
RGBA8 target for jpeg frames at one sample per pixel), and this checkout with textures
only (the device's layout). Process CPU time of the frame's draws (``glFinish``
included, read-back apart), interleaved, medians; ratios against the base from the same
run. The images are bit for bit the base's (``tests/renderer/gl/test_base_images.py``).
"""

from __future__ import annotations

import statistics

from bench import shader as S

from .common import Context

NAME = "shader"
TITLE = "The tracer shaped for llvmpipe (issue 18) — CPU time against the shader before it"

SIDES = ["base", "new", "new/tex"]
TARGETS = {"colour_d3": 0.55, "primary": 0.80}    # issue 18: at most these ratios against the base


def run(ctx: Context) -> str:
    configs = S.CONFIGS if not ctx.quick else [c for c in S.CONFIGS if c.name in ("colour_d3", "primary",
                                                                                  "floor_primid")]
    data = S.measure(configs, SIDES, ctx.runs, quick=ctx.quick, progress=ctx.log)
    ctx.save_data("shader", data)
    res = data["results"]
    med = {c.name: {s: statistics.median(res[c.name][s]["trace"]) for s in SIDES} for c in configs}
    lines = [f"## {TITLE}", "",
             "CPU time of one frame's trace (`time.process_time` around the draws and `glFinish`: llvmpipe's "
             "threads included; read-back apart, last columns) for three sides traced in turn — **base**: "
             f"renderer, shaders and layouts of `{data['base']}`, the commit before issue 18; **new**: this "
             "checkout as the service runs it (record arrays in uniform blocks where they fit 64 KiB, one RGBA8 "
             "target for jpeg frames at 1 sample per pixel); **new/tex**: this checkout with textures only "
             "(the device's layout, and the server's above 64 KiB). Every image is bit for bit the base's "
             "(`tests/renderer/gl/test_base_images.py`). Written by `bench/shader.py` (standalone: "
             "`.venv/bin/python bench/shader.py`).", "",
             S.table(data, configs), "",
             ctx.caption(ctx.runs, "median, configurations and sides interleaved, one untimed warm-up frame each"),
             ""]
    verdicts = []
    for name, limit in TARGETS.items():
        if name in med:
            r = med[name]["new"] / med[name]["base"]
            what = next(c.what for c in configs if c.name == name)
            verdicts.append(f"- {what}: **{r:.2f}×** the base (target ≤ {limit:.2f}×: "
                            f"{'met' if r <= limit else 'NOT met'})")
    if verdicts:
        lines += ["Targets of issue 18 (same run):", "", *verdicts, ""]
    if "floor_primid" in med:
        f = med["floor_primid"]
        lines += [f"The floor — what a frame costs with no sphere at all (the plane only, 640 × 1088): "
                  f"{f['new']:.0f} ms (base {f['base']:.0f} ms) for primid"
                  + (f", {med['floor_colour']['new']:.0f} ms (base {med['floor_colour']['base']:.0f} ms) for colour "
                     f"at depth 3" if "floor_colour" in med else "")
                  + ": ray set-up, the plane, the outputs, and the traversal's loops, which llvmpipe runs once "
                  "with every lane masked off even when no lane enters them.", ""]
    return "\n".join(lines)
