"""Beyond the thesis: the n below which brute force beats the BIH, per scenario.

Whole frames (build + upload + trace + read back) at 640 × 1088 with the BIH at the
default ``MAX_PRIMS`` against brute force, at recursion depth 1 (the thesis's Fig. 4.4
setting) and 5 (the service's default). The crossover is where the BIH's frame time drops
below brute force's for good, interpolated in log n between the two measured sizes around
it. The value for ``renderer.config.methods.AUTO_CROSSOVER_N`` is the threshold ``c`` ("brute
force when n < c") that loses least over every measured case.
"""

from __future__ import annotations

import math
from pathlib import Path

from renderer.config import methods as _methods
from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings, method_names
from .style import image_line, legend_outside, log_axis, plt, save, series
from .timing import crossover_n

NAME = "crossover"
TITLE = "Crossover — where brute force beats the BIH"

NS = (1, 2, 4, 8, 12, 16, 24, 32, 48, 64, 96, 128)
NS_QUICK = (1, 4, 16, 64)
DEPTHS = (1, 5)
SIZE = (640, 1088)
SIZE_QUICK = (64, 108)


def crossover(ns, bf, bih) -> tuple[float, str]:
    """(n, text): the n from which the BIH is faster than brute force for every larger measured n."""
    n, i = crossover_n(ns, bih, bf)
    if i == 0:
        return n, f"≤ {ns[0]:,} (the BIH is faster at every n measured)"
    if i == len(ns):
        return n, f"> {ns[-1]:,} (brute force is faster up to the largest n measured)"
    return n, f"≈ {n:.1f} (between {ns[i - 1]:,} and {ns[i]:,})"


def best_threshold(ns, cases: list[tuple[list[float], list[float]]]) -> tuple[int, dict[int, float]]:
    """The c minimising Σ (time of the choice "BF if n < c else BIH") / (best time) − 1 over all cases."""
    candidates = sorted(set(ns) | {ns[-1] + 1})
    regret = {}
    for c in candidates:
        loss = 0.0
        for bf, bih in cases:
            for n, f, b in zip(ns, bf, bih, strict=True):
                chosen = f if n < c else b
                loss += chosen / min(f, b) - 1.0
        regret[c] = loss
    best = min(candidates, key=lambda c: (round(regret[c], 9), c))
    return best, regret


def measure(ctx: Context) -> dict:
    ns = NS_QUICK if ctx.quick else NS
    w, h = SIZE_QUICK if ctx.quick else SIZE
    base = default_settings().with_(width=w, height=h, mode="color")
    # Brute force against the BIH, plus the names that choose between them (auto).
    extra = [m for m in method_names(dispatchers=True) if m not in method_names()]
    methods = ["bruteforce", "bih"] + extra
    raw = {}
    jobs = [(m, d, sc, n) for d in DEPTHS for sc in (1, 2, 3) for n in ns for m in methods]
    for m, d, sc, n in ctx.bar(jobs, desc="crossover"):
        s = scenario(sc, n, seed=0, radius=1.0)
        t = ctx.time_render(s, base.with_(method=m, max_recursion_depth=d))
        raw[f"{m}/{d}/{sc}/{n}"] = t.to_json()
    xs, c, regret = analyse(ns, raw)
    return {
        "size": [w, h],
        "ns": ns,
        "max_prims": base.max_prims,
        "points": raw,
        "crossover": {f"{d}/{sc}": x for (d, sc), x in xs.items()},
        "auto_crossover_n": c,
        "regret": regret,
        "auto_crossover_n_in_code": getattr(_methods, "AUTO_CROSSOVER_N", None),
    }


def _series(ns, points: dict, method: str, d: int, sc: int) -> list[float]:
    return [points[f"{method}/{d}/{sc}/{n}"]["total"]["median"] for n in ns]


def analyse(ns, points: dict) -> tuple[dict[tuple[int, int], float], int, dict[int, float]]:
    """Each scenario × depth series' crossover, the best threshold and every threshold's cost."""
    xs, cases = {}, []
    for d in DEPTHS:
        for sc in (1, 2, 3):
            bf, bih = _series(ns, points, "bruteforce", d, sc), _series(ns, points, "bih", d, sc)
            cases.append((bf, bih))
            xs[(d, sc)] = crossover(ns, bf, bih)[0]
    c, regret = best_threshold(ns, cases)
    return xs, c, regret


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    ns, points = data["ns"], data["points"]
    w, h = data["size"]
    mp = data["max_prims"]
    rows, cases = [], []
    for d in DEPTHS:
        for sc in (1, 2, 3):
            bf, bih = _series(ns, points, "bruteforce", d, sc), _series(ns, points, "bih", d, sc)
            cases.append((bf, bih))
            rows.append(
                [str(sc), str(d), crossover(ns, bf, bih)[1]] + [f"{f / b:.2f}" for f, b in zip(bf, bih, strict=True)]
            )
    table = md_table(
        ["scenario", "depth", "crossover n"] + [f"BF/BIH n = {n}" for n in ns], rows, "rrl" + "r" * len(ns)
    )
    c, regret = best_threshold(ns, cases)
    # The value in the code when the data was measured (older data: the value in the code now).
    current = data.get("auto_crossover_n_in_code", getattr(_methods, "AUTO_CROSSOVER_N", None))
    run.note(
        f"crossover: AUTO_CROSSOVER_N = {c}  # renderer/config/methods.py: brute force when n < {c} "
        f"(current: {current})"
    )
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    path = f"figures/{NAME}.json"

    reg = ", ".join(f"{k}: {v:.2f}" for k, v in regret.items())
    return f"""## {TITLE}

Whole-frame time (build + upload + trace + read back) at {w} × {h}, colour, spheres of radius 1,
brute force against the BIH with `MAX_PRIMS` {mp}, at recursion depth 1 and 5. The table gives the
crossover and the ratio BF time / BIH time per n (> 1: the BIH is faster).

{img}

{table}

{run.caption(capped=True)}

**`AUTO_CROSSOVER_N = {c}`** (brute force when n < {c}): of the thresholds tried, the one whose choice
costs least over all {len(cases)} scenario × depth series, the cost being Σ (time of the choice / time of
the faster method − 1) over every measured n. Cost per threshold: {reg}. Value in the code when this ran:
`{current}`.

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``crossover.png`` from ``crossover.json``: frame time of brute force, the BIH and auto
    against n (method colours; line style = depth), each series' crossover and the chosen threshold."""
    pyplot = plt()
    w, h = data["size"]
    ns = data["ns"]
    points = {tuple(k.split("/")): v for k, v in data["points"].items()}
    methods = list(dict.fromkeys(m for m, _, _, _ in points))
    depths = sorted({int(d) for _, d, _, _ in points})
    c = data["auto_crossover_n"]
    fig, axes = pyplot.subplots(1, 3, figsize=(15, 4.6), sharey=True, layout="constrained")
    for j, sc in enumerate((1, 2, 3)):
        ax = axes[j]
        for i, d in enumerate(depths):
            for m in methods:
                xs = [n for n in ns if (m, str(d), str(sc), str(n)) in points]
                ax.plot(
                    xs,
                    [points[(m, str(d), str(sc), str(n))]["total"]["median"] for n in xs],
                    **series(
                        f"{m}, depth {d}",
                        method=m,
                        variant=i,
                        marker=".",
                        ls=(":" if m == "auto" else ("-", "--", "-.")[i % 3]),
                    ),
                )
            x = data["crossover"].get(f"{d}/{sc}")
            if x is not None and math.isfinite(x):
                ax.axvline(x, color="#d62728", ls=("-", "--", "-.")[i % 3], alpha=0.45, label=f"crossover, depth {d}")
        ax.axvline(c, color="#2ca02c", lw=2, alpha=0.5, label=f"chosen AUTO_CROSSOVER_N = {c}")
        ax.set_xscale("log", base=2)
        log_axis(ax, "y")
        ax.set_title(f"scenario {sc}")
        ax.set_xlabel("spheres n")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(f"frame time (ms) at {w} × {h}")
    legend_outside(fig, axes)
    fig.suptitle(f"Brute force against BIH (MAX_PRIMS {data['max_prims']}); red lines: crossover per depth")
    save(fig, figures, "crossover", quick)
    return {"crossover": "Frame time of brute force and BIH at small n, with the crossover"}
