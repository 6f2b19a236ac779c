"""The two contexts of an experiment.

:class:`Context` is the measuring run: sizes (quick or full), where output goes, the GL
renderer, the frame budget, progress bars. :class:`RunInfo` is what a report says about the
run that measured (machine, GL renderer, runs, budget, what the budget left out): it is saved
with the experiment's data, so that ``--replot`` writes the same text without measuring.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene

from .machine import machine_info
from .timing import RenderTiming, Stat, measure


@dataclasses.dataclass
class RunInfo:
    """The run behind a section, as its report words it (every table's caption, the budget)."""

    machine_short: str
    gl: str
    runs: int
    quick: bool = False
    frame_budget_s: float | None = None
    skipped: list[str] = dataclasses.field(default_factory=list)
    stamp: str = ""  # the section's last line: when it was produced and in how long
    notes: list[str] = dataclasses.field(default_factory=list, compare=False)

    def to_json(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items() if k != "notes"}

    @classmethod
    def from_json(cls, d: dict) -> RunInfo:
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls) if f.name in d})

    @property
    def point_budget_s(self) -> float | None:
        """Seconds of timing after which a measured point stopped taking runs (≥ 1 run kept)."""
        return None if self.frame_budget_s is None else 4 * self.frame_budget_s

    def skipped_md(self) -> str:
        """The measurements the frame budget left out, as a list (empty when none)."""
        if not self.skipped:
            return ""
        budget = "none" if self.frame_budget_s is None else f"{self.frame_budget_s:g} s"
        return (
            f"**Not measured** (a frame predicted to take longer than the frame budget, {budget}; "
            "`--frame-budget` changes it):\n\n" + "\n".join(f"- {x}" for x in self.skipped) + "\n"
        )

    def caption(self, runs: int | str | None = None, what: str = "median, spread min–max", capped: bool = False) -> str:
        """The line under every table: machine, GL renderer, number of runs.

        ``capped``: the table's points were timed with ``point_budget_s`` (slow points may
        have fewer runs; the raw data has each point's samples)."""
        r = self.runs if runs is None else runs
        runs_txt = f"{r} run{'s' if r != 1 else ''} per point" if isinstance(r, int) else str(r)
        if isinstance(r, int) and r > 1 and what:
            runs_txt += f" ({what})"
        if capped and isinstance(r, int) and r > 1 and self.point_budget_s is not None:
            runs_txt += (
                f", after one untimed warm-up frame; a point stops after {self.point_budget_s:g} s of timing "
                "(≥ 1 run; each point's samples are in the raw data)"
            )
        return f"*Machine: {self.machine_short}. GL: {self.gl}. Runs: {runs_txt}.*"

    def caption_cpu(self, runs: int | str | None = None, what: str = "median, spread min–max") -> str:
        """Caption for CPU-only tables (the GL renderer is named anyway: it is the same run)."""
        return self.caption(runs, what)

    def note(self, msg: str) -> None:
        """A line repeated at the end of the run (values to put into code)."""
        self.notes.append(msg)


class Context:
    """One run of the experiments: sizes (quick or full), output place, GL renderer, progress."""

    def __init__(self, quick: bool, out: Path, runs: int, progress: bool = True, frame_budget_s: float | None = None):
        self.quick = quick
        self.out = Path(out)
        self.figures = self.out / "figures"
        self.figures.mkdir(parents=True, exist_ok=True)
        self.runs = runs
        self.progress = progress
        self.machine = machine_info()
        self.started = _dt.datetime.now().astimezone()
        self._renderer = None
        self.notes: list[str] = []  # lines for stdout at the end (constants to put in the code, …)
        # Longest predicted frame a measurement may have (see within_budget); None = no limit.
        self.frame_budget_s = frame_budget_s if frame_budget_s is not None else (0.5 if quick else 5.0)
        self.skipped: list[str] = []  # measurements left out by the budget, per experiment

    def take_skipped(self) -> list[str]:
        """The measurements skipped since the last call (an experiment lists them in its section)."""
        out, self.skipped = self.skipped, []
        return out

    # ---- renderer
    @property
    def renderer(self):
        if self._renderer is None:
            from renderer.gl.renderer import GLRenderer

            self._renderer = GLRenderer()
        return self._renderer

    @property
    def gl(self) -> str:
        info = self.renderer.info
        return f"{info['renderer']}, OpenGL {info['version']}"

    @property
    def machine_short(self) -> str:
        m = self.machine
        return f"{m['cpu']}, {m['cores'].split(' (')[0]}, {m['memory']} RAM"

    @property
    def point_budget_s(self) -> float | None:
        """Seconds of timing after which a measured point stops taking runs (≥ 1 run kept)."""
        return None if self.frame_budget_s is None else 4 * self.frame_budget_s

    def run_info(self) -> RunInfo:
        """What a report says about this run (machine, GL, runs, budget), with the measurements
        skipped since the last ``take_skipped``; saved with the experiment's data."""
        return RunInfo(
            machine_short=self.machine_short,
            gl=self.gl,
            runs=self.runs,
            quick=self.quick,
            frame_budget_s=self.frame_budget_s,
            skipped=self.take_skipped(),
        )

    # ---- progress and logging
    def bar(self, iterable: Iterable | None = None, desc: str = "", total: int | None = None):
        from tqdm import tqdm

        return tqdm(
            iterable,
            desc=desc,
            total=total,
            leave=False,
            position=1,
            dynamic_ncols=True,
            disable=not self.progress,
            file=sys.stderr,
        )

    def log(self, msg: str) -> None:
        from tqdm import tqdm

        tqdm.write(msg, file=sys.stderr)

    # ---- rendering
    def predict_frame_s(self, scene: Scene, settings: RenderSettings) -> float:
        """Predicted seconds for one frame: two frames at 1/8 of the width and height
        (the first compiles the variant); the second's trace stage is scaled by the pixel
        count, the rest (build, upload, …) is kept as it is. Cheap: 1/64 of the pixels."""
        w, h = settings.width, settings.height
        if w * h <= 64 * 64 * 16:
            return 0.0  # small frames: just render them
        small = settings.with_(width=max(1, w // 8), height=max(1, h // 8))
        self.renderer.render(scene, small)
        t0 = time.perf_counter()
        res = self.renderer.render(scene, small)
        wall = time.perf_counter() - t0
        ratio = (w * h) / (small.width * small.height)
        trace = getattr(res, "timings", {}).get("trace")
        if trace is None:
            return wall * ratio
        trace_s = min(trace / 1e3, wall)
        return (wall - trace_s) + trace_s * ratio

    def within_budget(self, scene: Scene, settings: RenderSettings, what: str) -> bool:
        """False (and the reason recorded in ``self.skipped``) when one frame of ``settings``
        is predicted to take longer than ``frame_budget_s``; a method this slow would make
        the whole run take hours. ``--frame-budget`` raises the limit."""
        if self.frame_budget_s is None:
            return True
        s = self.predict_frame_s(scene, settings)
        if s > self.frame_budget_s:
            self.skipped.append(f"{what}: predicted {s:,.1f} s per frame (from a frame at 1/8 × 1/8 of the size)")
            return False
        return True

    def time_render(
        self,
        scene: Scene,
        settings: RenderSettings,
        runs: int | None = None,
        warmup: int = 1,
        budget_s: float | None | str = "point",
        post: Callable[[Any], Any] | None = None,
    ) -> RenderTiming:
        """Render ``runs`` frames after ``warmup`` (compile, caches); wall time per frame.

        ``budget_s``: stop taking runs after this many seconds of timing (≥ 1 run);
        ``"point"`` = ``point_budget_s``, ``None`` = always all runs.
        ``post`` (e.g. upscaling) runs on every result and is part of the timed frame.
        """
        r = self.renderer
        runs = self.runs if runs is None else runs
        if budget_s == "point":
            budget_s = self.point_budget_s
        stages: dict[str, list[float]] = {}
        first = math.nan

        def frame():
            res = r.render(scene, settings)
            return post(res) if post else res

        if warmup > 0:  # the first warm-up frame is timed on its own: it compiles new variants
            t0 = time.perf_counter()
            frame()
            first = (time.perf_counter() - t0) * 1e3

        def record(last: Any) -> None:
            res = last[0] if isinstance(last, tuple) else last
            for k, v in getattr(res, "timings", {}).items():
                stages.setdefault(k, []).append(float(v))

        total, last = measure(frame, runs, warmup=max(0, warmup - 1), budget_s=budget_s, on_result=record)
        return RenderTiming(total, {k: Stat(v) for k, v in stages.items()}, last, first)
