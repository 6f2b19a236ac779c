"""pocketray's experiments, all of them, with one command.

    ./dev bench experiments                          # everything → docs/RESULTS.md, docs/figures/
    ./dev bench experiments --quick                  # smoke run (tiny sizes, 1 run) → a temp dir
    ./dev bench experiments --only fig_4_4,pareto    # re-run some; their sections are replaced
    ./dev bench experiments --list
    ./dev bench experiments --replot [--only peers]  # text and charts again from figures/*.json

(``./dev bench experiments`` is ``python -m bench.experiments``.) Each experiment is a module
of ``bench/experiments/`` (see ``EXPERIMENTS`` there) in three steps: ``measure(ctx)`` returns
the raw data, saved as ``figures/NAME.json`` with what the section says of the run
(``RunInfo``: machine, GL renderer, runs, budget); ``plot(data, figures)`` draws the charts
from that data; ``report(data, run, charts)`` returns the Markdown section. This script puts
the sections into ``RESULTS.md`` between ``<!-- BEGIN name -->`` / ``<!-- END name -->``
markers under a header naming the machine, the GL renderer and the number of runs.
``--quick`` never writes over ``docs/``: without ``--out`` it writes to a fresh temporary
directory and prints where. ``--replot`` measures nothing: it draws the charts and writes the
sections again from the saved data (the header of RESULTS.md stays as it is).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import traceback
from pathlib import Path

from . import EXPERIMENTS
from .context import Context, RunInfo
from .machine import ROOT
from .results import assemble, head_of, header, run_info_from_section, sections_of
from .steps import load, module, run_one, write_up

DEFAULT_OUT = ROOT / "docs"


def replot(out: Path, names: list[str]) -> int:
    """Charts and sections of ``names`` again from ``out/figures/NAME.json``, into ``out/RESULTS.md``;
    1 when one fails. A section without saved data, or whose report fails, is kept as it was."""
    status = 0
    path = out / "RESULTS.md"
    old = sections_of(path)
    fragments: dict[str, str] = {}
    titles: dict[str, str] = {}
    notes: list[str] = []
    for name in names:
        mod = module(name)
        titles[name] = mod.TITLE
        try:
            saved = load(mod, out / "figures")
        except FileNotFoundError as e:  # never measured since its data was kept: nothing to write from
            print(
                f"  {name:12s} no {e.filename}: section kept as it is (run the experiment to save its data)",
                file=sys.stderr,
            )
            continue
        try:
            if isinstance(saved, dict) and "run" in saved:
                run = RunInfo.from_json(saved["run"])
            else:  # saved before the data carried its run: read it back from the section
                run = run_info_from_section(old.get(name, ""))
            fragments[name] = write_up(mod, saved, run, out / "figures")
            notes += run.notes
        except Exception:
            print(f"  {name:12s} FAILED:\n{traceback.format_exc()}", file=sys.stderr)
            status = 1
            continue
        print(f"  {name:12s} {path} and {out / 'figures'}/")
    if fragments:
        head = head_of(path) or "# pocketray — experiments\n\n"
        assemble(path, head, fragments, titles)
    for line in notes:
        print(f"  {line}")
    return status


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(
        prog="python -m bench.experiments", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="tiny sizes and one run: a smoke test (never writes docs/)")
    ap.add_argument("--only", default="", help="comma-separated experiment names (see --list)")
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="directory for RESULTS.md and figures/ (default: docs/, or a temp dir with --quick)",
    )
    ap.add_argument("--runs", type=int, default=None, help="runs per measured point (default 5; 1 with --quick)")
    ap.add_argument(
        "--frame-budget",
        type=float,
        default=None,
        help="seconds one frame may be predicted to take before a measurement is left out "
        "(default 10; 0.5 with --quick; 0 = no limit)",
    )
    ap.add_argument("--no-progress", action="store_true", help="no progress bars")
    ap.add_argument("--list", action="store_true", help="list the experiments and exit")
    ap.add_argument(
        "--replot",
        action="store_true",
        help="measure nothing: charts and sections again from figures/*.json (in --out, default docs/)",
    )
    a = ap.parse_args(argv)

    if a.list:
        for name in EXPERIMENTS:
            print(f"{name:12s} {module(name).TITLE}")
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
        titles[name], fragments[name], broke = run_one(ctx, name)
        if broke:
            failed.append(name)
        elapsed[name] = time.perf_counter() - t0
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
