"""One experiment's steps: measure, save, draw, write up — and the same from saved data.

``run_one`` measures (``measure(ctx)``), saves the data with the run's ``RunInfo``, draws the
charts (``plot``) and writes the section (``report``) from the saved data only, so that
``write_up`` on data read back later (``--replot``) gives the same text and charts.
"""

from __future__ import annotations

import importlib
import sys
import time
import traceback
from pathlib import Path
from types import ModuleType
from typing import Any

from . import data
from .context import Context, RunInfo
from .results import stamp, with_stamp


def module(name: str) -> ModuleType:
    return importlib.import_module(f"bench.experiments.{name}")


def load(mod: ModuleType, figures: Path) -> Any:
    """The experiment's saved data (a module with more than one file has its own ``load``)."""
    return mod.load(figures) if hasattr(mod, "load") else data.load(figures, mod.NAME)


def dump(mod: ModuleType, saved: Any, figures: Path) -> None:
    if hasattr(mod, "dump"):
        mod.dump(saved, figures)
    else:
        data.save(figures, mod.NAME, saved)


def charts_of(mod: ModuleType, saved: Any, figures: Path, quick: bool) -> dict[str, str]:
    return mod.plot(saved, figures, quick) if hasattr(mod, "plot") else {}


def write_up(mod: ModuleType, saved: dict, run: RunInfo, figures: Path) -> str:
    """Charts and section text of saved data: the same whether just measured or replotted."""
    charts = charts_of(mod, saved, figures, run.quick)
    return with_stamp(mod.report(saved, run, charts), run.stamp)


def run_one(ctx: Context, name: str) -> tuple[str, str, bool]:
    """Measure, save, draw and write one experiment: (title, section, failed)."""
    t0 = time.perf_counter()
    title = name
    try:
        mod = module(name)
        title = mod.TITLE
        ctx.take_skipped()
        saved = data.roundtrip(mod.measure(ctx))
        run = ctx.run_info()
        saved["run"] = run.to_json()
        dump(mod, saved, ctx.figures)  # saved before writing it up: a failing report keeps the data
        run.stamp = stamp(time.perf_counter() - t0, ctx.quick)
        saved["run"] = run.to_json()
        dump(mod, saved, ctx.figures)
        frag = write_up(mod, saved, run, ctx.figures)
        ctx.notes += run.notes
        return title, frag, False
    except Exception:  # one broken experiment must not lose the others' results
        tb = traceback.format_exc()
        from tqdm import tqdm

        tqdm.write(f"{name} FAILED:\n{tb}", file=sys.stderr)
        frag = f"## {title}\n\n**This experiment failed:**\n\n```\n{tb.strip()}\n```\n"
        return title, with_stamp(frag, stamp(time.perf_counter() - t0, ctx.quick)), True
