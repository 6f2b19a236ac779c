"""pocketray's experiments, all of them, with one command.

    ./dev bench bench/experiments.py                      # everything → docs/RESULTS.md, docs/figures/
    ./dev bench bench/experiments.py --quick              # smoke run (tiny sizes, 1 run) → a temp dir
    ./dev bench bench/experiments.py --only fig_4_4,pareto   # re-run some; their sections are replaced
    ./dev bench bench/experiments.py --list
    ./dev bench bench/experiments.py --replot [--only peers]   # redraw the charts from figures/*.json

Each experiment is a module of ``bench/experiments/`` (see ``EXPERIMENTS`` there). It
measures, writes its charts (``figures/*.png``) and raw data (``figures/*.json``) and
returns a Markdown fragment; this script puts the fragments into ``RESULTS.md`` between
``<!-- BEGIN name -->`` / ``<!-- END name -->`` markers under a header naming the machine,
the GL renderer and the number of runs. ``--quick`` never writes over ``docs/``: without
``--out`` it writes to a fresh temporary directory and prints where. ``--replot`` measures
nothing: every module's ``plot(data, figures)`` redraws its charts from the
``figures/NAME.json`` it saved (the style of ``bench/experiments/style.py``).
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import tempfile
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# This file's directory is on sys.path when run as a script; "experiments" must be the
# package bench.experiments, so import everything from the repository root instead.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]
sys.path.insert(0, str(ROOT))

from bench.experiments import EXPERIMENTS  # noqa: E402
from bench.experiments.common import Context, revision  # noqa: E402

BEGIN = "<!-- BEGIN {} -->"
END = "<!-- END {} -->"
DEFAULT_OUT = ROOT / "docs"


def header(ctx: Context, argv: list[str]) -> str:
    m = ctx.machine
    quick = ("\n> **Quick smoke run** (`--quick`): tiny images, few sizes, one run per point. "
             "The numbers show that the scripts work, nothing else.\n" if ctx.quick else "")
    cmd = " ".join(["./dev bench bench/experiments.py", *argv]).strip()
    budget = ("none" if ctx.frame_budget_s is None else
              f"{ctx.frame_budget_s:g} s: a configuration whose frame is predicted to take longer is not measured "
              f"(listed where it applies); a point stops taking runs after {ctx.point_budget_s:g} s of timing")
    lines = [
        "# pocketray — experiments",
        "",
        "<!-- Written by bench/experiments.py. Do not edit by hand: every number below was "
        "produced by that script; re-run it instead. -->",
        quick,
        f"Written by `{cmd}`. Every number on this page was produced by the scripts in "
        "`bench/experiments/`; the raw measurements are beside the charts in `figures/*.json`. "
        "Thesis numbers are quoted from de Melo Arôxa (2014), chapter IV, and marked as such; "
        "the thesis measured on an iPhone 5s (Apple A7 GPU), we measure on the machine below, so "
        "absolute times are not comparable — shapes and ratios are.",
        "",
        "| | |",
        "|---|---|",
        f"| machine | {m['cpu']}, {m['cores']}, {m['memory']} RAM |",
        f"| OS | {m['os']} |",
        f"| Python / NumPy | {m['python']} / {m['numpy']} |",
        f"| OpenGL renderer | {ctx.gl} |",
        f"| runs | {ctx.runs} per measured point after one untimed warm-up frame, unless a table says "
        f"otherwise; times are medians, spreads min–max |",
        f"| frame budget | {budget} |",
        f"| revision | `{revision()}` (sections re-run with `--only` carry their own date) |",
        "",
    ]
    return "\n".join(lines)


def assemble(path: Path, head: str, fragments: dict[str, str], titles: dict[str, str]) -> None:
    """Write RESULTS.md: the header, then every experiment's section in EXPERIMENTS order.

    Sections not run this time are kept from the existing file (``--only``).
    """
    old = path.read_text() if path.exists() else ""
    sections: dict[str, str] = {}
    for name in EXPERIMENTS:
        if name in fragments:
            sections[name] = fragments[name].strip()
            continue
        m = re.search(re.escape(BEGIN.format(name)) + r"\n(.*?)\n" + re.escape(END.format(name)), old, re.S)
        if m:
            sections[name] = m.group(1).strip()
    toc = ["## Contents", ""]
    for name in EXPERIMENTS:
        if name in sections:
            title = titles.get(name) or _title_of(sections[name]) or name
            toc.append(f"- [{title}](#{_anchor(title)})")
    body = [head, "\n".join(toc), ""]
    for name in EXPERIMENTS:
        if name in sections:
            body += [BEGIN.format(name), sections[name], END.format(name), ""]
    path.write_text("\n".join(body))


def _title_of(section: str) -> str | None:
    m = re.search(r"^## (.+)$", section, re.M)
    return m.group(1).strip() if m else None


def _anchor(title: str) -> str:
    """GitHub's heading anchor: lower case, punctuation dropped, spaces to dashes."""
    a = re.sub(r"[^\w\- ]", "", title.lower(), flags=re.U)
    return a.replace(" ", "-")


def replot(out: Path, names: list[str]) -> int:
    """Redraw the charts of ``names`` from ``out/figures/NAME.json``; 1 when one is missing or fails."""
    import json

    status = 0
    for name in names:
        mod = importlib.import_module(f"bench.experiments.{name}")
        data_path = out / "figures" / f"{getattr(mod, 'NAME', name)}.json"
        if not hasattr(mod, "plot"):
            continue   # an experiment without charts (tables only)
        if not data_path.exists():
            print(f"  {name:12s} no {data_path}: run the experiment first", file=sys.stderr)
            status = 1
            continue
        try:
            charts = mod.plot(json.loads(data_path.read_text()), out / "figures")
        except Exception:
            print(f"  {name:12s} FAILED:\n{traceback.format_exc()}", file=sys.stderr)
            status = 1
            continue
        for chart in charts:
            print(f"  {name:12s} {out / 'figures' / (chart + '.png')}")
    return status


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="tiny sizes and one run: a smoke test (never writes docs/)")
    ap.add_argument("--only", default="", help="comma-separated experiment names (see --list)")
    ap.add_argument("--out", type=Path, default=None,
                    help="directory for RESULTS.md and figures/ (default: docs/, or a temp dir with --quick)")
    ap.add_argument("--runs", type=int, default=None, help="runs per measured point (default 5; 1 with --quick)")
    ap.add_argument("--frame-budget", type=float, default=None,
                    help="seconds one frame may be predicted to take before a measurement is left out "
                         "(default 10; 0.5 with --quick; 0 = no limit)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bars")
    ap.add_argument("--list", action="store_true", help="list the experiments and exit")
    ap.add_argument("--replot", action="store_true",
                    help="measure nothing: redraw the charts of figures/*.json (in --out, default docs/)")
    a = ap.parse_args(argv)

    if a.list:
        for name in EXPERIMENTS:
            mod = importlib.import_module(f"bench.experiments.{name}")
            print(f"{name:12s} {mod.TITLE}")
        return 0
    names = [s.strip() for s in a.only.split(",") if s.strip()] or list(EXPERIMENTS)
    unknown = [n for n in names if n not in EXPERIMENTS]
    if unknown:
        ap.error(f"unknown experiment(s) {', '.join(unknown)}; one of {', '.join(EXPERIMENTS)}")
    if a.out is None:
        out = Path(tempfile.mkdtemp(prefix="pocketray-quick-")) if a.quick else DEFAULT_OUT
    else:
        out = a.out
    if a.replot:
        return replot(out, names)
    if a.quick and out.resolve() == DEFAULT_OUT.resolve():
        ap.error("--quick does not write over docs/: give another --out")
    runs = a.runs if a.runs is not None else (1 if a.quick else 5)
    if runs < 1:
        ap.error("--runs must be ≥ 1")
    out.mkdir(parents=True, exist_ok=True)
    ctx = Context(quick=a.quick, out=out, runs=runs, progress=not a.no_progress, frame_budget_s=a.frame_budget)
    if a.frame_budget == 0:
        ctx.frame_budget_s = None

    from tqdm import tqdm
    print(f"pocketray experiments ({'quick' if a.quick else 'full'}, {runs} run(s) per point) → {out}", flush=True)
    print(f"machine: {ctx.machine_short}; GL: {ctx.gl}", flush=True)
    fragments: dict[str, str] = {}
    titles: dict[str, str] = {}
    elapsed: dict[str, float] = {}
    failed: list[str] = []
    bar = tqdm(names, desc="experiments", position=0, dynamic_ncols=True, disable=a.no_progress, file=sys.stderr)
    for name in bar:
        bar.set_postfix_str(name)
        t0 = time.perf_counter()
        titles[name] = name
        ctx.take_skipped()
        try:
            mod = importlib.import_module(f"bench.experiments.{name}")
            titles[name] = mod.TITLE
            frag = mod.run(ctx)
        except Exception:  # one broken experiment must not lose the others' results
            tb = traceback.format_exc()
            failed.append(name)
            tqdm.write(f"{name} FAILED:\n{tb}", file=sys.stderr)
            frag = f"## {titles[name]}\n\n**This experiment failed:**\n\n```\n{tb.strip()}\n```\n"
        elapsed[name] = time.perf_counter() - t0
        stamp = (f"\n\n<sub>Section produced {time.strftime('%Y-%m-%d %H:%M %Z')} in "
                 f"{elapsed[name]:.0f} s{' (quick mode)' if a.quick else ''}.</sub>\n")
        fragments[name] = frag.rstrip() + stamp
        # Written after every experiment, so an interrupted run keeps what it finished.
        assemble(out / "RESULTS.md", header(ctx, argv), fragments, titles)
    bar.close()

    print(f"\nwrote {out / 'RESULTS.md'} and {out / 'figures'}/")
    for name in names:
        print(f"  {name:12s} {elapsed[name]:7.1f} s{'  FAILED' if name in failed else ''}")
    if ctx.notes:
        print("\nvalues measured for the code:")
        for line in ctx.notes:
            print(f"  {line}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
