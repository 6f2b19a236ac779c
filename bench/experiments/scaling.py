"""Beyond the thesis: build cost up to n = 1,048,576 and trace cost up to 65,536, log–log, fitted exponents."""

from __future__ import annotations

import math
from pathlib import Path

from renderer.accel.bih import build_for_spheres
from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings, method_names
from .style import image_line, legend_outside, plt, save, series
from .timing import Stat, fit_power, measure as time_it

NAME = "scaling"
TITLE = "Scaling — build and trace cost against n"

BUILD_NS = tuple(64 * 4**k for k in range(8))  # 64 … 1,048,576
BUILD_NS_QUICK = (64, 256, 1024, 4096)
BUILD_MAX_PRIMS = (1, 8)
TRACE_NS = tuple(64 * 4**k for k in range(6))  # 64 … 65,536
TRACE_NS_QUICK = (64, 256)
TRACE_DEPTHS = (1, 5)
TRACE_DEPTHS_QUICK = (1,)
DEEP_METHODS = ("bih", "bruteforce")  # depth > 1 is measured for these only (time: every method at depth 1)
SIZE = (640, 1088)
SIZE_QUICK = (64, 108)
FIT_FROM = 1024  # fits use n ≥ this (small n is dominated by fixed costs)
BUILD_BUDGET_S = 20.0  # timing of one build point stops after this much time (≥ 1 run)


def measure(ctx: Context) -> dict:
    b_ns = BUILD_NS_QUICK if ctx.quick else BUILD_NS
    t_ns = TRACE_NS_QUICK if ctx.quick else TRACE_NS
    depths = TRACE_DEPTHS_QUICK if ctx.quick else TRACE_DEPTHS
    w, h = SIZE_QUICK if ctx.quick else SIZE
    budget = ctx.frame_budget_s
    fit_from = min(b_ns) if ctx.quick else FIT_FROM

    # ---- build
    build: dict[tuple[int, int, int], Stat] = {}
    jobs = [(sc, n, mp) for n in b_ns for sc in (1, 2, 3) for mp in BUILD_MAX_PRIMS]
    for sc, n, mp in ctx.bar(jobs, desc="scaling: build"):
        s = scenario(sc, n, seed=0, radius=1.0)
        build[(sc, n, mp)], _ = time_it(
            lambda s=s, mp=mp: build_for_spheres(s.sphere_centers, s.sphere_radii, mp),
            ctx.runs,
            warmup=1 if n <= 65536 else 0,
            budget_s=None if ctx.quick else BUILD_BUDGET_S,
        )
    build_fit = {}
    for sc in (1, 2, 3):
        for mp in BUILD_MAX_PRIMS:
            pts = [(n, build[(sc, n, mp)].median) for n in b_ns if n >= fit_from]
            build_fit[(sc, mp)] = fit_power(*zip(*pts, strict=True))

    # ---- trace
    base = default_settings().with_(width=w, height=h, mode="color")
    methods = method_names()
    trace: dict[tuple[str, int, int, int], dict] = {}
    jobs = [
        (m, d, sc, n) for m in methods for d in depths for sc in (1, 2, 3) for n in t_ns if d == 1 or m in DEEP_METHODS
    ]
    last_frame: dict[tuple[str, int, int], tuple[int, float]] = {}
    too_slow: set[tuple[str, int, int]] = set()
    for m, d, sc, n in ctx.bar(jobs, desc="scaling: trace"):
        what = f"{m}, depth {d}, scenario {sc}, n = {n:,}"
        prev = last_frame.get((m, d, sc))
        if (m, d, sc) in too_slow:
            ctx.skipped.append(f"{what}: over the budget at a smaller n")
            continue
        if budget is not None and prev is not None and prev[1] / 1e3 * n / prev[0] > budget:
            ctx.skipped.append(
                f"{what}: predicted {prev[1] / 1e3 * n / prev[0]:,.1f} s per frame (linear in n from n = {prev[0]:,})"
            )
            too_slow.add((m, d, sc))
            continue
        s = scenario(sc, n, seed=0, radius=1.0)
        st = base.with_(method=m, max_recursion_depth=d)
        if not ctx.within_budget(s, st, what):
            too_slow.add((m, d, sc))
            continue
        t = ctx.time_render(s, st)
        trace[(m, d, sc, n)] = {"total": t.total, "trace": t.stages["trace"], "build": t.stages["build"]}
        last_frame[(m, d, sc)] = (n, t.total.median)

    trace_fit = {}
    for m in methods:
        for d in depths:
            for sc in (1, 2, 3):
                pts = [
                    (n, trace[(m, d, sc, n)]["trace"].median)
                    for n in t_ns
                    if (m, d, sc, n) in trace and n >= (256 if not ctx.quick else 0)
                ]
                trace_fit[(m, d, sc)] = fit_power(*zip(*pts, strict=True)) if len(pts) >= 2 else (math.nan, math.nan)
    return {
        "build": {f"{sc}/{n}/{mp}": v for (sc, n, mp), v in build.items()},
        "build_fit": {f"{sc}/{mp}": v for (sc, mp), v in build_fit.items()},
        "trace": {f"{m}/{d}/{sc}/{n}": v for (m, d, sc, n), v in trace.items()},
        "trace_fit": {f"{m}/{d}/{sc}": v for (m, d, sc), v in trace_fit.items()},
        "skipped": list(ctx.skipped),
        "size": [w, h],
        "fit_from": fit_from,
        "depths": list(depths),
        "build_ns": list(b_ns),
        "trace_ns": list(t_ns),
        "methods": methods,
        "max_prims": base.max_prims,
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    w, h = data["size"]
    # Older data did not keep its sizes, depths and methods: those of the run's mode, the methods measured.
    b_ns = data.get("build_ns") or (BUILD_NS_QUICK if run.quick else BUILD_NS)
    fit_from = data.get("fit_from") or (min(b_ns) if run.quick else FIT_FROM)
    depths = data.get("depths") or (TRACE_DEPTHS_QUICK if run.quick else TRACE_DEPTHS)
    t_ns = data.get("trace_ns") or (TRACE_NS_QUICK if run.quick else TRACE_NS)
    methods = data.get("methods") or list(dict.fromkeys(k.split("/")[0] for k in data["trace"]))
    max_prims = data.get("max_prims", default_settings().max_prims)
    build = {tuple(int(x) for x in k.split("/")): Stat.from_json(v) for k, v in data["build"].items()}
    build_fit = {tuple(int(x) for x in k.split("/")): v for k, v in data["build_fit"].items()}
    trace = {}
    for k, v in data["trace"].items():
        m, d, sc, n = k.split("/")
        trace[(m, int(d), int(sc), int(n))] = {stage: Stat.from_json(x) for stage, x in v.items()}
    trace_fit = {}
    for k, v in data["trace_fit"].items():
        m, d, sc = k.split("/")
        trace_fit[(m, int(d), int(sc))] = tuple(math.nan if x is None else x for x in v)

    rows = []
    for n in b_ns:
        cells = [f"{n:,}"]
        for sc in (1, 2, 3):
            for mp in BUILD_MAX_PRIMS:
                cells.append(build[(sc, n, mp)].fmt(2))
        cells.append(str(min(build[(sc, n, mp)].runs for sc in (1, 2, 3) for mp in BUILD_MAX_PRIMS)))
        rows.append(cells)
    rows.append(
        ["fitted exponent k (ms ∝ n^k)"]
        + [f"{build_fit[(sc, mp)][0]:.3f}" for sc in (1, 2, 3) for mp in BUILD_MAX_PRIMS]
        + [""]
    )
    build_table = md_table(["n"] + [f"S{sc} MP{mp}" for sc in (1, 2, 3) for mp in BUILD_MAX_PRIMS] + ["runs"], rows)

    t_rows = []
    for m in methods:
        for d in depths:
            if d != 1 and m not in DEEP_METHODS:
                continue
            for sc in (1, 2, 3):
                cells = [m, str(d), str(sc)]
                for n in t_ns:
                    v = trace.get((m, d, sc, n))
                    cells.append(f"{v['trace'].median:,.1f} / {v['total'].median:,.1f}" if v else "—")
                k = trace_fit[(m, d, sc)][0]
                cells.append("—" if math.isnan(k) else f"{k:.3f}")
                t_rows.append(cells)
    trace_table = md_table(
        ["method", "depth", "scenario"] + [f"n = {n:,}" for n in t_ns] + ["k (trace ∝ n^k)"],
        t_rows,
        "lrr" + "r" * (len(t_ns) + 1),
    )

    path = f"figures/{NAME}.json"
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    skipped_txt = run.skipped_md()
    return f"""## {TITLE}

{img}

### BIH build time against n

CPU build (`build_for_spheres`), radius 1, median of the runs given in the last column (points
above 65,536 have no warm-up run; a point stops after {BUILD_BUDGET_S:g} s of timing). Exponent
`k` from a least-squares fit of log(ms) against log(n) over n ≥ {fit_from:,}: `k = 1` is linear,
an n log n build shows as slightly above 1.

{build_table}

{run.caption("see the last column")}

### Trace time against n

Trace stage / whole frame (ms) at {w} × {h}, colour, spheres of radius 1, every method of
`METHODS` at its default `MAX_PRIMS` ({max_prims}) at recursion depth 1, and
{" and ".join(DEEP_METHODS)} at depth {max(depths)} too; `k` fitted on the trace stage over the measured n ≥ 256.

{trace_table}

{run.caption(capped=True)}

{skipped_txt}

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``scaling_loglog.png`` from ``scaling.json``: the BIH build against n (one colour, the BIH's;
    line style = scenario, lighter = MAX_PRIMS 1), and the trace per depth (colour = method, line
    style = scenario); the legends outside the panels."""
    pyplot = plt()
    w, h = data["size"]
    fit_from = data.get("fit_from", FIT_FROM)
    build = {tuple(int(x) for x in k.split("/")): v for k, v in data["build"].items()}
    b_ns = sorted({n for _, n, _ in build})
    mps = sorted({mp for _, _, mp in build})
    trace = {(k.split("/")[0], *map(int, k.split("/")[1:])): v for k, v in data["trace"].items()}
    methods = list(dict.fromkeys(m for m, _, _, _ in trace))
    depths = data.get("depths") or sorted({d for _, d, _, _ in trace})
    t_ns = sorted({n for _, _, _, n in trace})
    fig, axes = pyplot.subplots(1, 1 + len(depths), figsize=(6 + 5.5 * len(depths), 4.8), layout="constrained")
    ax = axes[0]
    for sc in (1, 2, 3):
        for mp in mps:
            k = data["build_fit"][f"{sc}/{mp}"][0]
            ys = [build[(sc, n, mp)]["median"] for n in b_ns if (sc, n, mp) in build]
            ax.plot(
                b_ns[: len(ys)],
                ys,
                **series(
                    f"BIH build, S{sc} MAX_PRIMS {mp}: k = {k:.2f}",
                    method="bih",
                    variant=sc - 1,
                    alpha=1.0 if mp == mps[-1] else 0.55,
                    mfc="none" if mp != mps[-1] else None,
                ),
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("spheres n")
    ax.set_ylabel("BIH build time (ms, CPU)")
    ax.set_title(f"build (fit over n ≥ {fit_from:,}; hollow: MAX_PRIMS {mps[0]})")
    ax.grid(True, which="both", alpha=0.3)
    for j, d in enumerate(depths):
        ax = axes[1 + j]
        for m in methods:
            for sc in (1, 2, 3):
                xs = [n for n in t_ns if (m, d, sc, n) in trace]
                if not xs:
                    continue
                k = data["trace_fit"].get(f"{m}/{d}/{sc}", [math.nan])[0]
                k = math.nan if k is None else k
                ax.plot(
                    xs,
                    [trace[(m, d, sc, n)]["trace"]["median"] for n in xs],
                    **series(
                        f"{m} S{sc}, depth {d}" + ("" if math.isnan(k) else f": k = {k:.2f}"), method=m, variant=sc - 1
                    ),
                )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("spheres n")
        ax.set_ylabel("trace stage (ms)")
        ax.set_title(f"trace {w} × {h}, recursion depth {d}")
        ax.grid(True, which="both", alpha=0.3)
    legend_outside(fig, axes, title="line style: scenario S1 — S2 - - S3 ···", ncol=2)
    save(fig, figures, "scaling_loglog", quick)
    return {"scaling_loglog": "Build and trace cost against n, log–log, with fitted exponents"}
