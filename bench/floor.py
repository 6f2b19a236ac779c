"""The floor of a frame: what a 640 × 1088 frame costs with nothing in it, stage by stage.

Two scenes with nothing to trace — *empty* (scenario 1's camera and light, no sphere, no
plane) and *plane* (scenario 1's plane alone) — in the frames the service makes: depth (jpeg)
and primid (png) through the RGBA8 image-only target, colour at the interactive profile (jpeg,
one sample: RGBA8 too) and at the still profile (png, 2 × 2 samples: five passes into two
RGBA32F targets). Each frame as the service makes it (``GLRenderer.render``, then
``server.frames.encode.encode``), its stages:

- ``set-up``: the frame's total less the stages below (plan and build, upload, the program,
  the background regions);
- ``trace``: the draws and ``glFinish`` (the frame's ``trace`` timing);
- ``read``: the read-backs (``read``);
- ``compose``: the result made of them (``TracerFrame._compose``: flips, box filter, copies);
- ``encode``: the body (``encode``, the service's jpeg quality and png level);
- ``frame``: all of them.

Sides: ``before`` — the renderer, shaders and service of ``--base`` (default: the commit this
work started from), extracted from git into a temporary directory; ``after`` — this checkout.
Each side is a worker process with its own GL context; one untimed warm-up frame per
configuration (the compile), then ``--runs`` frames; ``--rounds`` rounds of the two sides in
turn (a shared machine's load drifts); medians over all of a side's frames.

``limit``: what llvmpipe and the libraries here need at least for the same bytes, measured in
the same run — a trivial fragment shader (a constant into the same target(s), once per pass) for
``trace``; a memcpy of the bytes read back for ``read`` and ``compose``; PIL's encoder alone on
the same image, held already (libjpeg-turbo; zlib-ng at the service's level), for ``encode``.

    .venv/bin/python -m bench.floor                 # 3 rounds × 5 runs, before and after
    .venv/bin/python -m bench.floor --quick         # 1 × 2 runs, small frames (smoke)
    .venv/bin/python -m bench.floor --base 0221c09 --rounds 5 --json out.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BASE_COMMIT = "0221c09"  # main when this benchmark was written: the floor before it was lowered

# (name, RenderSettings keywords, passes, float targets)
CONFIGS = (
    ("depth jpeg", {"mode": "depth", "format": "jpeg"}, 1, False),
    ("primid png", {"mode": "primid", "format": "png"}, 1, False),
    (
        "colour jpeg, interactive",
        {"mode": "color", "format": "jpeg", "samples_per_pixel": 1, "max_recursion_depth": 8, "min_weight": 0.3},
        1,
        False,
    ),
    (
        "colour png, still",
        {"mode": "color", "format": "png", "samples_per_pixel": 4, "max_recursion_depth": 8, "min_weight": 0.03},
        5,
        True,
    ),
)
SCENES = ("empty", "plane")
STAGES = ("set-up", "trace", "read", "compose", "encode", "frame")
JPEG_QUALITY, PNG_LEVEL = 85, 1  # the service's defaults (server/config.py)


def _scene(name: str):
    import dataclasses

    import numpy as np

    from renderer.scenes.scenarios import scenario

    s1 = scenario(1, 16)
    empty = dataclasses.replace(
        s1,
        sphere_centers=np.zeros((0, 3)),
        sphere_radii=np.zeros(0),
        sphere_materials=np.zeros(0, np.int32),
        planes=(),
    )
    return empty if name == "empty" else dataclasses.replace(empty, planes=s1.planes)


def worker(width: int, height: int, runs: int) -> dict:
    """Every scene × configuration with the ``renderer`` and ``server`` on sys.path: medians (ms) of
    each stage."""
    import io

    from PIL import Image

    from renderer.config.settings import RenderSettings
    from renderer.gl import frame as gl_frame
    from renderer.gl.renderer import GLRenderer
    from server.frames.encode import encode

    compose_ms: list[float] = []
    inner = gl_frame.TracerFrame._compose

    def timed_compose(self):
        t0 = time.perf_counter()
        try:
            return inner(self)
        finally:
            compose_ms.append((time.perf_counter() - t0) * 1e3)

    gl_frame.TracerFrame._compose = timed_compose  # type: ignore[method-assign]
    renderer = GLRenderer()
    out: dict = {}
    for scene_name in SCENES:
        scene = _scene(scene_name)
        for name, kw, _, _ in CONFIGS:
            settings = RenderSettings(width=width, height=height, **kw)
            rows: dict[str, list[float]] = {k: [] for k in (*STAGES, "encoder")}
            for i in range(runs + 1):
                compose_ms.clear()
                t0 = time.perf_counter()
                result = renderer.render(scene, settings)
                body, enc = encode(result, settings.format, JPEG_QUALITY, PNG_LEVEL)
                frame = (time.perf_counter() - t0) * 1e3
                if i == 0:
                    continue  # the compile
                t = result.timings
                comp = sum(compose_ms)
                rows["trace"].append(t["trace"])
                rows["read"].append(t["read"])
                rows["compose"].append(comp)
                rows["encode"].append(enc)
                rows["frame"].append(frame)
                rows["set-up"].append(frame - t["trace"] - t["read"] - comp - enc)
                # The encoder alone, on this frame's image held by PIL already (the limit of ``encode``).
                held = Image.fromarray(result.image_u8(), "RGB")
                opts = {"quality": JPEG_QUALITY} if settings.format == "jpeg" else {"compress_level": PNG_LEVEL}
                t1 = time.perf_counter()
                held.save(io.BytesIO(), settings.format.upper(), **opts)
                rows["encoder"].append((time.perf_counter() - t1) * 1e3)
            out[f"{scene_name} / {name}"] = {k: v for k, v in rows.items()} | {"bytes": len(body)}
    return out


def limits(width: int, height: int, runs: int) -> dict:
    """The physical limits here (ms): a constant fragment shader into one RGBA8 target and into two
    RGBA32F ones (draw + glFinish), a memcpy of their bytes (the encoders' are the workers':
    ``encoder``)."""

    import moderngl
    import numpy as np

    from renderer.gl.context import create_context

    def median_ms(f) -> float:
        ts = []
        for i in range(runs + 1):
            t0 = time.perf_counter()
            f()
            if i:
                ts.append((time.perf_counter() - t0) * 1e3)
        return statistics.median(ts)

    ctx = create_context()
    vs = "#version 300 es\nin vec2 a_position; void main() { gl_Position = vec4(a_position, 0.0, 1.0); }"
    fs8 = (
        "#version 300 es\nprecision highp float; layout(location = 0) out vec4 o;\n"
        "void main() { o = vec4(0.0, 0.0, 0.0, 1.0); }"
    )
    fs32 = (
        "#version 300 es\nprecision highp float; layout(location = 0) out vec4 o; layout(location = 1) out vec4 p;\n"
        "void main() { o = vec4(0.0, 0.0, 0.0, -1.0); p = vec4(0.0, 0.0, 0.0, -1.0); }"
    )
    quad = ctx.buffer(np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], np.float32).tobytes())
    out: dict = {}
    for key, fs, fbo in (
        ("rgba8", fs8, ctx.framebuffer(color_attachments=[ctx.texture((width, height), 4, dtype="f1")])),
        (
            "rgba32f",
            fs32,
            ctx.framebuffer(color_attachments=[ctx.texture((width, height), 4, dtype="f4") for _ in range(2)]),
        ),
    ):
        prog = ctx.program(vertex_shader=vs, fragment_shader=fs)
        vao = ctx.vertex_array(prog, [(quad, "2f", "a_position")])

        def draw(fbo=fbo, vao=vao):
            fbo.use()
            vao.render(moderngl.TRIANGLES)
            ctx.finish()

        out[f"trace {key}"] = median_ms(draw)
    src8 = np.zeros((height, width, 4), np.uint8)
    src32 = np.zeros((height, width, 8), np.float32)
    out["memcpy rgba8"] = median_ms(lambda: np.copyto(np.empty_like(src8), src8))
    out["memcpy rgba32f"] = median_ms(lambda: np.copyto(np.empty_like(src32), src32))
    return out


def limit_of(lim: dict, after: dict, config: tuple, stage: str) -> float | None:
    name, kw, passes, floats = config
    target = "rgba32f" if floats else "rgba8"
    if stage == "trace":
        return passes * lim[f"trace {target}"]
    if stage == "read":
        return passes * lim[f"memcpy {target}"]
    if stage == "compose":
        return 0.0 if not floats else lim[f"memcpy {target}"]  # image-only: nothing to make
    if stage == "encode":
        return after["encoder"]
    if stage == "frame":
        return sum(limit_of(lim, after, config, s) or 0.0 for s in ("trace", "read", "compose", "encode"))
    return None


def _medians(rounds: list[dict]) -> dict:
    """Each frame's stages: the medians over every round's runs."""
    return {
        key: {k: statistics.median(x for r in rounds for x in r[key][k]) for k in rounds[0][key] if k != "bytes"}
        for key in rounds[0]
    }


def _run_side(tree: Path, what: str, width: int, height: int, runs: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    # The renderer and service from ``tree`` (first on the path), this module from this checkout.
    code = (
        f"import json, sys; sys.path[:0] = [{str(tree)!r}, {str(ROOT)!r}]; from bench import floor; "
        f"print(json.dumps(floor.{what}({width}, {height}, {runs})))"
    )
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=tree)
    if proc.returncode:
        raise SystemExit(f"{what} in {tree} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _extract(commit: str, into: Path) -> None:
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", commit, "renderer", "shaders", "server"], check=True, capture_output=True
    )
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive.stdout, check=True)


def table(before: dict, after: dict, lim: dict) -> str:
    lines = ["| frame | stage | before ms | after ms | limit ms |", "|:---|:---|---:|---:|---:|"]
    for scene in SCENES:
        for config in CONFIGS:
            key = f"{scene} / {config[0]}"
            for stage in STAGES:
                b, a = before[key][stage], after[key][stage]
                li = limit_of(lim, after[key], config, stage)
                lines.append(
                    f"| {key if stage == STAGES[0] else ''} | {stage} | {b:.2f} | {a:.2f} | "
                    f"{'—' if li is None else f'{li:.2f}'} |"
                )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", default=BASE_COMMIT, help="the commit of the 'before' side")
    ap.add_argument("--runs", type=int, default=5, help="frames per configuration in each round")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of both sides in turn")
    ap.add_argument("--size", default="640x1088", help="W x H")
    ap.add_argument("--quick", action="store_true", help="64 × 108, 2 runs (smoke)")
    ap.add_argument("--json", help="also write the figures here")
    args = ap.parse_args()
    w, h = (64, 108) if args.quick else map(int, args.size.lower().split("x"))
    runs = 2 if args.quick else args.runs
    args.rounds = 1 if args.quick else args.rounds
    sides: dict[str, list[dict]] = {"before": [], "after": []}
    with tempfile.TemporaryDirectory(prefix="pocketray-floor-") as tmp:
        base = Path(tmp)
        _extract(args.base, base)
        # Rounds of both sides in turn: a shared machine's load drifts, and each side sees it alike.
        for _ in range(args.rounds):
            sides["before"].append(_run_side(base, "worker", w, h, runs))
            sides["after"].append(_run_side(ROOT, "worker", w, h, runs))
    lim = _run_side(ROOT, "limits", w, h, runs)
    before, after = (_medians(sides[k]) for k in ("before", "after"))
    print(
        f"Frame floor at {w} × {h}, medians of {args.rounds} × {runs} runs (rounds of the sides in turn); "
        f"before = {args.base}, after = this checkout."
    )
    print(table(before, after, lim))
    print(f"load average {os.getloadavg()[0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"rounds": sides, "limits": lim}, indent=1))


if __name__ == "__main__":
    main()
