"""Fig. 4.5: BIH memory (bytes) against n = 1,024 / 2,048 / 4,096, radius 0.001, MAX_PRIMS 1…16.

Memory as the thesis counts it: nodes (12 bytes each) + the sorted index array (4 bytes
per primitive) + the global AABB (24 bytes) — ``BIHStats.bytes``. Deterministic: one
build per point, no timing.
"""

from __future__ import annotations

from pathlib import Path

from renderer.accel.bih import build_for_spheres
from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .style import image_line, legend_outside, plt, save, series

NAME = "fig_4_5"
TITLE = "Fig. 4.5 — BIH memory against n (radius 0.001)"

NS = (1024, 2048, 4096)
MAX_PRIMS = (1, 2, 4, 8, 16)
RADIUS = 0.001

THESIS = {
    "highest": ("BIH 1, scenario 2, 4,096 spheres", "little over 150 kB"),
    "lowest": ("BIH 16, scenario 3, 1,024 spheres", "slightly less than 6.2 kB"),
    "max_reduction": (82.5, "scenario 2, 1,024 spheres"),
    "min_reduction": (73.99, "scenario 1, 2,048 spheres"),
    "largest_scenario": 2,
    "smallest_scenario": 1,
}


def measure(ctx: Context) -> dict:
    jobs = [(sc, n, mp) for sc in (1, 2, 3) for n in NS for mp in MAX_PRIMS]
    mem: dict[str, int] = {}
    scenes = {}
    for sc, n, mp in ctx.bar(jobs, desc="Fig 4.5"):
        s = scenes.setdefault((sc, n), scenario(sc, n, seed=0, radius=RADIUS))
        mem[f"{sc}/{n}/{mp}"] = int(build_for_spheres(s.sphere_centers, s.sphere_radii, mp).stats.bytes)
    return {"radius": RADIUS, "bytes": mem}


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    mem = {tuple(int(x) for x in k.split("/")): v for k, v in data["bytes"].items()}

    red = {(sc, n): 100.0 * (1 - mem[(sc, n, MAX_PRIMS[-1])] / mem[(sc, n, 1)]) for sc in (1, 2, 3) for n in NS}
    rows = []
    for sc in (1, 2, 3):
        for n in NS:
            rows.append([str(sc), f"{n:,}"] + [f"{mem[(sc, n, mp)]:,}" for mp in MAX_PRIMS] + [f"{red[(sc, n)]:.2f} %"])
    table = md_table(["scenario", "n"] + [f"BIH {mp}" for mp in MAX_PRIMS] + ["BIH 16 saves vs BIH 1"], rows)

    hi = max(mem, key=mem.get)
    lo = min(mem, key=mem.get)
    rmax = max(red, key=red.get)
    rmin = min(red, key=red.get)
    per_sc = {sc: sum(v for k, v in mem.items() if k[0] == sc) for sc in (1, 2, 3)}
    comp = md_table(
        ["", "thesis (Fig. 4.5)", "ours"],
        [
            [
                "highest memory",
                f"{THESIS['highest'][1]} ({THESIS['highest'][0]})",
                f"{mem[hi]:,} B = {mem[hi] / 1000:.1f} kB (BIH {hi[2]}, scenario {hi[0]}, {hi[1]:,} spheres)",
            ],
            [
                "lowest memory",
                f"{THESIS['lowest'][1]} ({THESIS['lowest'][0]})",
                f"{mem[lo]:,} B = {mem[lo] / 1000:.2f} kB (BIH {lo[2]}, scenario {lo[0]}, {lo[1]:,} spheres)",
            ],
            [
                "largest saving of BIH 16 vs BIH 1",
                f"{THESIS['max_reduction'][0]} % ({THESIS['max_reduction'][1]})",
                f"{red[rmax]:.2f} % (scenario {rmax[0]}, {rmax[1]:,} spheres)",
            ],
            [
                "smallest saving of BIH 16 vs BIH 1",
                f"{THESIS['min_reduction'][0]} % ({THESIS['min_reduction'][1]})",
                f"{red[rmin]:.2f} % (scenario {rmin[0]}, {rmin[1]:,} spheres)",
            ],
            [
                "scenario using most / least memory overall",
                f"{THESIS['largest_scenario']} / {THESIS['smallest_scenario']}",
                f"{max(per_sc, key=per_sc.get)} / {min(per_sc, key=per_sc.get)}",
            ],
        ],
        "lll",
    )

    img = "\n".join(image_line(k, v) for k, v in charts.items())
    path = f"figures/{NAME}.json"

    return f"""## {TITLE}

Bytes of the BIH as the thesis counts them: nodes × 12 + primitives × 4 (index array) + 24
(global AABB), spheres of radius {RADIUS:g}. A build is deterministic, so each point is one build.

{img}

{table}

{run.caption(1, "")} (Memory does not depend on the machine.)

**Thesis against ours:**

{comp}

{run.caption(1, "")} (Thesis column: as quoted.)

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``fig_4_5_memory.png`` from ``fig_4_5.json``: BIH memory against n, one bar per MAX_PRIMS in
    the BIH's colour (lighter for larger MAX_PRIMS); the legend outside."""
    import numpy as np

    pyplot = plt()
    mem = {tuple(int(x) for x in k.split("/")): v for k, v in data["bytes"].items()}
    ns = sorted({n for _, n, _ in mem})
    mps = sorted({mp for _, _, mp in mem})
    fig, axes = pyplot.subplots(1, 3, figsize=(16, 4.4), sharey=True, layout="constrained")
    x = np.arange(len(ns))
    wbar = 0.8 / len(mps)
    for j, sc in enumerate((1, 2, 3)):
        ax = axes[j]
        for i, mp in enumerate(mps):
            ax.bar(
                x + (i - (len(mps) - 1) / 2) * wbar,
                [mem[(sc, n, mp)] / 1000 for n in ns],
                wbar,
                color=series("bih", variant=i)["color"],
                edgecolor="black",
                linewidth=0.3,
                label=f"BIH, MAX_PRIMS {mp}",
            )
        ax.set_xticks(x, [f"{n:,}" for n in ns])
        ax.set_title(f"scenario {sc}")
        ax.set_xlabel("spheres n")
        ax.grid(True, axis="y", alpha=0.3)
    axes[0].set_ylabel("kB (nodes + indices + global AABB)")
    legend_outside(fig, axes)
    fig.suptitle(f"Fig. 4.5 reproduced: BIH memory, radius {data['radius']:g}")
    save(fig, figures, "fig_4_5_memory", quick)
    return {"fig_4_5_memory": "BIH memory against n per MAX_PRIMS"}
