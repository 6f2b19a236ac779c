"""The cost model of a frame (renderer/frame/cost.py) against measured traces on this machine.

Frames of every method over scenarios 1–3 and several sphere counts, modes, depths,
samples and sizes — degenerate trees (one leaf of n spheres) included — are traced once
after a warm-up. Each frame's measured GL time (upload + trace + read-back) is set beside
the model's terms: passes × pixels × rays, × node visits, × sphere tests, and the ray
engines' primitives × pixels × rays. The constants are fitted by non-negative least
squares on the relative error (every frame weighs the same whatever its size), with the
level decay picked from a grid; the table shows estimate against measured, and the fitted
constants are the ones to put in ``renderer/frame/cost.py``'s ``DEFAULT_MODEL``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.frame.cost import CostModel, terms
from renderer.frame.prepare import prepare_frame, sampled_level_rays
from renderer.frame.profiles import PROFILES
from renderer.scenes.scenarios import mesh_scene, scenario

from .context import Context, RunInfo
from .markdown import md_table
from .style import image_line, legend_outside, plt, save, series

NAME = "cost"
TITLE = "Cost model of a frame — estimate against measured"

DECAYS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)


def cases(quick: bool) -> list[tuple[str, object, RenderSettings]]:
    """(label, scene, settings) of the frames measured."""
    ns = (64, 512) if quick else (64, 512, 4096, 32768)
    sizes = ((64, 108),) if quick else ((160, 272), (320, 544))
    profiles = [
        dict(mode="primid", max_recursion_depth=1),
        dict(mode="color", max_recursion_depth=3),
        dict(mode="color", max_recursion_depth=8, min_weight=0.03, samples_per_pixel=4),
    ]
    out = []
    for sc, n, (w, h), prof in itertools.product((1, 2, 3), ns, sizes, profiles):
        scene = scenario(sc, n, seed=0)
        for method in ("bih", "bvh", "kdtree", "twolevel"):
            out.append(
                (
                    f"s{sc} n={n} {w}×{h} {method} {prof}",
                    scene,
                    RenderSettings(width=w, height=h, method=method, **prof),
                )
            )
        if n <= 512:
            out.append(
                (
                    f"s{sc} n={n} {w}×{h} bruteforce {prof}",
                    scene,
                    RenderSettings(width=w, height=h, method="bruteforce", **prof),
                )
            )
        if n <= 4096 and prof["mode"] == "primid":  # degenerate trees: one leaf of n spheres
            out.append(
                (
                    f"s{sc} n={n} {w}×{h} bih one leaf",
                    scene,
                    RenderSettings(width=w, height=h, method="bih", max_prims=n, **prof),
                )
            )
            out.append(
                (
                    f"s{sc} n={n} {w}×{h} bih depth 1",
                    scene,
                    RenderSettings(width=w, height=h, method="bih", max_tree_depth=1, **prof),
                )
            )
    # Dense scenes, the service's largest (POCKETRAY_MAX_SPHERES = 2^21): thousands of sphere tests
    # per ray through the hierarchy, which the frames above never reach (without them the fit made
    # small-leaf tests free and estimated a 2^21-sphere frame at a quarter of its time).
    for sc, n, prof in itertools.product((1, 3), (1 << 14,) if quick else (1 << 18, 1 << 21), profiles[:2]):
        scene = scenario(sc, n, seed=0)
        w, h = (48, 80) if quick else (80, 136)
        out.append((f"s{sc} n={n} {w}×{h} bih {prof}", scene, RenderSettings(width=w, height=h, method="bih", **prof)))
    # The demo meshes (triangles through the BIH; their ray trees counted on a sample, as the service does).
    for kind, prof in itertools.product(("room", "mixed"), profiles):
        w, h = (64, 108) if quick else (160, 272)
        out.append((f"{kind} {w}×{h} bih {prof}", mesh_scene(kind), RenderSettings(width=w, height=h, **prof)))
    for n, (w, h) in itertools.product((16, 64) if quick else (64, 256), ((48, 80),) if quick else ((96, 160),)):
        scene = scenario(3, n, seed=0)
        for method, mode in itertools.product(("rayengine", "hre"), ("primid", "color")):
            out.append(
                (
                    f"s3 n={n} {w}×{h} {method} {mode}",
                    scene,
                    RenderSettings(width=w, height=h, method=method, mode=mode, max_recursion_depth=3),
                )
            )
    return out


def measure_frames(ctx: Context) -> list[dict]:
    r = ctx.renderer
    rows = []
    for label, scene, s in ctx.bar(cases(ctx.quick), desc="cost frames"):
        method = METHODS[s.method]
        prepared = method.prepare(scene, s.max_prims, s.max_tree_depth, r.max_texture_width)
        r.render(scene, s)  # compile the variant, warm the caches
        res = r.render(scene, s)
        t = res.timings
        gl_ms = t.get("upload", 0.0) + t.get("trace", 0.0) + t.get("read", 0.0)
        mp = method.capabilities.multi_pass
        level_rays = sampled_level_rays(scene, s)
        rows.append(
            {
                "label": label,
                "ms": gl_ms,
                "multi_pass": mp,
                "terms": {
                    str(d): terms(s.method, prepared.stats, scene, s, d, mp, level_rays)[0].tolist() for d in DECAYS
                },
            }
        )
    return rows


# The estimate of the phone's frames of the demo meshes against their measured GL time, beside sphere
# frames the fit above estimates about right (the yardsticks): on a machine shared with other work
# every frame is slower by about the same factor, which the yardsticks' measured / estimated gives.
MESH_SIZES = ((320, 544), (640, 1088))
YARDSTICKS = (("scenario 1, 4,096", 1), ("scenario 3, 4,096", 3))


def mesh_frames(renderer, sizes=MESH_SIZES, repeats: int = 1, quick: bool = False) -> list[dict]:
    """Per demo mesh (room, mixed), client profile and size, and per yardstick: estimated and
    measured GL time (upload + trace + read-back; the variant compiled first), in ms. ``quick``: the
    room and one yardstick, the interactive profile."""
    scenes = [(label, scenario(n, 4096, seed=0), True) for label, n in YARDSTICKS[: 1 if quick else None]]
    scenes += [(kind, mesh_scene(kind), False) for kind in (("room",) if quick else ("room", "mixed"))]
    profiles = [("interactive", PROFILES["interactive"])] if quick else list(PROFILES.items())
    rows = []
    for _ in range(repeats):
        for (label, scene, yardstick), (name, prof), (w, h) in itertools.product(scenes, profiles, sizes):
            st = RenderSettings(
                width=w, height=h, format="png", **{k: v for k, v in prof.items() if k != "resolution_scale"}
            )
            frame = prepare_frame(scene, st)
            renderer.start(prepare_frame(scene, st.with_(width=16, height=16))).run()  # compile the variant
            t = renderer.start(frame).run().timings
            rows.append(
                {
                    "scene": label,
                    "profile": name,
                    "size": f"{w}×{h}",
                    "yardstick": yardstick,
                    "estimated_ms": frame.cost.ms,
                    "bound_ms": frame.cost.bound_ms,
                    "measured_ms": t.get("upload", 0.0) + t.get("trace", 0.0) + t.get("read", 0.0),
                }
            )
    return rows


def mesh_table(rows: list[dict]) -> str:
    """The mesh frames' estimate against measured, and against measured ÷ the yardsticks' median
    measured / estimated (the machine's slowness that run)."""
    slow = float(np.median([r["measured_ms"] / r["estimated_ms"] for r in rows if r["yardstick"]]))
    body = [
        (
            r["scene"],
            r["profile"],
            r["size"],
            f"{r['estimated_ms']:,.0f}",
            f"{r['bound_ms']:,.0f}",
            f"{r['measured_ms']:,.0f}",
            f"{r['estimated_ms'] / r['measured_ms']:.2f}",
            f"{r['estimated_ms'] * slow / r['measured_ms']:.2f}",
        )
        for r in rows
    ]
    head = [
        "scene",
        "profile",
        "size",
        "estimated ms",
        "bound ms",
        "measured ms",
        "est / measured",
        "est / (measured ÷ slow)",
    ]
    return f"yardsticks' measured / estimated (slow): {slow:.2f}\n\n" + md_table(head, body)


def main() -> None:
    """``python -m bench.experiments.cost`` — the demo meshes' table alone (a minute or two)."""
    import argparse

    from renderer.gl.renderer import GLRenderer

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--small", action="store_true", help="320 × 544 only")
    a = ap.parse_args()
    sizes = MESH_SIZES[:1] if a.small else MESH_SIZES
    print(mesh_table(mesh_frames(GLRenderer(), sizes, a.repeats)))


def fit(frames: list[dict]) -> tuple[CostModel, float]:
    """The constants (ns) minimising the relative error over the frames (each with its measured
    ``ms`` and its model terms per level decay), and the median |log(estimate / measured)|."""
    from scipy.optimize import nnls

    y = np.array([f["ms"] * 1e6 for f in frames])
    w = 1.0 / np.maximum(y, 1.0)
    best = None
    for decay in DECAYS:
        A = np.array([f["terms"][str(decay)] for f in frames])
        coef, _ = nnls(A * w[:, None], y * w)
        pred = A @ coef
        # Relative weights leave the fit low in the middle: scale it so the median frame is right.
        coef *= float(np.median(y / np.maximum(pred, 1.0)))
        pred = A @ coef
        err = float(np.median(np.abs(np.log(np.maximum(pred, 1.0) / np.maximum(y, 1.0)))))
        upper = float(np.quantile(y / np.maximum(pred, 1.0), 0.9))
        if best is None or err < best[1]:
            best = (CostModel(*map(float, coef), level_decay=decay, upper=upper), err)
    return best


def measure(ctx: Context) -> dict:
    """The frames measured, and the constants fitted to them with each frame's estimate."""
    frames = measure_frames(ctx)
    model, err = fit(frames)
    for f in frames:
        f["est"] = float(np.array(f["terms"][str(model.level_decay)]) @ model.vector()) / 1e6
    return {
        "model": model.__dict__,
        "terms": list(CostModel.TERMS),
        "median_abs_log_ratio": err,
        "frames": [
            {
                "label": f["label"],
                "measured_ms": f["ms"],
                "estimated_ms": f["est"],
                "multi_pass": f["multi_pass"],
                "terms": f["terms"],
            }
            for f in frames
        ],
        "meshes": mesh_frames(ctx.renderer, ((64, 108),) if ctx.quick else MESH_SIZES, quick=ctx.quick),
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    model, err = CostModel(**data["model"]), data["median_abs_log_ratio"]
    frames = [{"label": f["label"], "ms": f["measured_ms"], "est": f["estimated_ms"]} for f in data["frames"]]
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    ratios = np.array([f["est"] / max(f["ms"], 1e-3) for f in frames])
    worst = sorted(frames, key=lambda f: -abs(math.log(max(f["est"], 1e-3) / max(f["ms"], 1e-3))))[:8]
    table = md_table(
        ["frame", "measured ms", "estimated ms", "ratio"],
        [(f["label"], f"{f['ms']:.1f}", f"{f['est']:.1f}", f"{f['est'] / max(f['ms'], 1e-3):.2f}") for f in worst],
    )
    within2 = float(np.mean((ratios >= 0.5) & (ratios <= 2.0)))
    meshes = ""
    if data.get("meshes"):
        meshes = f"""
The client's frames of the demo meshes (`mesh_scene` room and mixed, profiles interactive and still):
the estimate against the measured GL time, and against it divided by how much slower than estimated
the sphere yardsticks ran beside them (a shared machine slows every frame alike).

{mesh_table(data["meshes"])}
"""
    consts = ", ".join(f"{name} {value:.3g}" for name, value in zip(CostModel.TERMS, model.vector(), strict=True))
    return f"""## {TITLE}

{run.caption(1, "one frame after a warm-up per configuration")}

{len(frames)} frames (every method; scenarios 1–3; primary rays, colour at depth 3, and the still
profile — depth 8, ε 0.03, 4 samples; degenerate BIHs of one leaf; dense scenes of 2^18 and 2^21
spheres through the BIH). Fitted constants, ns per
unit of each term of `renderer/frame/cost.py` (`DEFAULT_MODEL`): {consts}; level decay
{model.level_decay:.1f}; the constants are scaled so that the median frame is estimated right.
Median |log(estimate / measured)| = {err:.2f}; {within2:.0%} of the frames are estimated within
a factor of 2; 90 % are measured below {model.upper:.2f} × their estimate, the factor
(`upper`) the frame cost cap applies (`bound_ms`).

{img}

The frames the model misses most:

{table}
{meshes}"""


def plot(data: dict, figures, quick: bool = False) -> dict[str, str]:
    """``cost_model.png`` from ``cost.json``: estimated against measured frame time, log–log."""
    pyplot = plt()
    fig, ax = pyplot.subplots(figsize=(6.4, 5.2), layout="constrained")
    frames = data["frames"]
    for mp, label in ((False, "one-pass methods"), (True, "ray engines")):
        pts = [(f["measured_ms"], f["estimated_ms"]) for f in frames if bool(f.get("multi_pass")) == mp]
        if pts:
            m, e = zip(*pts, strict=True)
            ax.scatter(
                m,
                e,
                s=12,
                alpha=0.7,
                **{
                    k: v
                    for k, v in series(label, method="hre" if mp else "bih").items()
                    if k in ("color", "marker", "label")
                },
            )
    lo = max(0.1, min(min(f["measured_ms"] for f in frames), min(f["estimated_ms"] for f in frames)))
    hi = max(max(f["measured_ms"] for f in frames), max(f["estimated_ms"] for f in frames))
    ax.plot([lo, hi], [lo, hi], "k--", lw=0.8, label="estimate = measured")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("measured GL time per frame (ms)")
    ax.set_ylabel("estimated (ms)")
    ax.grid(True, which="both", alpha=0.3)
    legend_outside(fig, [ax])
    save(fig, figures, "cost_model", quick)
    return {"cost_model": "estimated against measured frame time"}


if __name__ == "__main__":
    main()
