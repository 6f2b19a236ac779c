"""What every experiment shares: the run context, timing, Markdown, settings helpers.

Numbers in ``RESULTS.md`` come only from here and the experiment modules: a module
measures, then formats what it measured. Raw measurements go to ``figures/NAME.json``
beside the charts, so every number on the page can be traced to a run.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import json
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.engine import machine as engine_machine  # noqa: E402
from renderer.methods import METHODS  # noqa: E402
from renderer.scene import Scene  # noqa: E402
from renderer.settings import RenderSettings  # noqa: E402

# --------------------------------------------------------------------------- settings

SETTING_FIELDS = frozenset(f.name for f in dataclasses.fields(RenderSettings))


def has_setting(name: str) -> bool:
    """Whether this build's RenderSettings knows ``name`` (knobs added later are optional)."""
    return name in SETTING_FIELDS


def method_names(dispatchers: bool = False) -> list[str]:
    """Every acceleration method of ``renderer.methods.METHODS``, in registry order (new ones
    join by themselves). ``dispatchers``: also the names that only pick one of them per scene
    (``auto``), i.e. every ``method`` RenderSettings accepts."""
    from renderer.settings import METHOD_NAMES
    names = list(METHODS)
    if dispatchers:
        names += [m for m in METHOD_NAMES if m not in names]
    return names


def default_settings() -> RenderSettings:
    return RenderSettings()


def diffuse_only(scene: Scene) -> Scene:
    """The same scene with nothing reflecting or transmitting (kr = kt = 0)."""
    mats = tuple(dataclasses.replace(m, reflective=0.0, transmissive=0.0) for m in scene.materials)
    return dataclasses.replace(scene, materials=mats)


# --------------------------------------------------------------------------- statistics

@dataclasses.dataclass
class Stat:
    """Samples of one measurement (ms unless said otherwise): median and min–max spread."""
    samples: list[float]

    @property
    def median(self) -> float:
        return float(statistics.median(self.samples)) if self.samples else math.nan

    @property
    def lo(self) -> float:
        return float(min(self.samples)) if self.samples else math.nan

    @property
    def hi(self) -> float:
        return float(max(self.samples)) if self.samples else math.nan

    @property
    def runs(self) -> int:
        return len(self.samples)

    def fmt(self, digits: int = 1) -> str:
        """``median (min–max)``, or just the value for one run."""
        if not self.samples:
            return "—"
        m = f"{self.median:,.{digits}f}"
        if self.runs == 1:
            return m
        return f"{m} ({self.lo:,.{digits}f}–{self.hi:,.{digits}f})"

    def to_json(self) -> dict:
        return {"median": self.median, "min": self.lo, "max": self.hi, "samples": self.samples}


def measure(fn: Callable[[], Any], runs: int, warmup: int = 1, budget_s: float | None = None,
            on_result: Callable[[Any], None] | None = None) -> tuple[Stat, Any]:
    """Wall time of ``fn`` in ms over ``runs`` calls after ``warmup`` untimed ones.

    With ``budget_s`` the runs stop early once that much time was spent timing
    (at least one run is always kept): the number of runs is ``Stat.runs``.
    ``on_result`` sees the result of every timed call, outside the timed interval.
    """
    last = None
    for _ in range(warmup):
        last = fn()
    samples: list[float] = []
    spent = 0.0
    for _ in range(max(1, runs)):
        t0 = time.perf_counter()
        last = fn()
        dt = time.perf_counter() - t0
        samples.append(dt * 1e3)
        if on_result is not None:
            on_result(last)
        spent += dt
        if budget_s is not None and spent > budget_s:
            break
    return Stat(samples), last


def crossover_n(ns: Sequence[int], ours: Sequence[float], theirs: Sequence[float]) -> tuple[float, int]:
    """The n from which ``ours`` < ``theirs`` at every larger measured n: ``(n, i)``.

    ``i`` is the first index of the final run where ours is smaller; n interpolates
    log(ours / theirs) = 0 between ``ns[i-1]`` and ``ns[i]`` in log n. ``i = 0``: ours is
    smaller everywhere (n = ns[0]); ``i = len(ns)``: not at the largest n (n = inf).
    """
    faster = [a < b for a, b in zip(ours, theirs)]
    if all(faster):
        return float(ns[0]), 0
    if not faster[-1]:
        return math.inf, len(ns)
    i = max(k for k, ok in enumerate(faster) if not ok) + 1
    r0, r1 = math.log(ours[i - 1] / theirs[i - 1]), math.log(ours[i] / theirs[i])
    x0, x1 = math.log(ns[i - 1]), math.log(ns[i])
    x = x0 + (x1 - x0) * r0 / (r0 - r1) if r0 != r1 else x1
    return math.exp(x), i


@dataclasses.dataclass
class RenderTiming:
    """One render configuration measured: wall time per frame and every stage of ``timings``."""
    total: Stat
    stages: dict[str, Stat]
    result: Any  # the last RenderResult
    first_ms: float  # the warm-up frame (shader compile included when the variant was new)

    def to_json(self) -> dict:
        return {"total": self.total.to_json(), "first_ms": self.first_ms,
                "stages": {k: v.to_json() for k, v in self.stages.items()}}


def fit_power(ns: Sequence[float], ys: Sequence[float]) -> tuple[float, float]:
    """Least-squares fit of ``y = a · n^k`` in log–log space: returns ``(k, a)``."""
    x = np.log(np.asarray(ns, dtype=float))
    y = np.log(np.asarray(ys, dtype=float))
    if len(x) < 2:
        return math.nan, math.nan
    k, log_a = np.polyfit(x, y, 1)
    return float(k), float(math.exp(log_a))


# --------------------------------------------------------------------------- machine

def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _mem_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / (1 << 20)
    except OSError:
        pass
    return None


def machine_info() -> dict[str, str]:
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    mem = _mem_gib()
    return {
        "cpu": _cpu_model(),
        "cores": f"{os.cpu_count()} logical CPUs ({usable} usable by this process)",
        "memory": f"{mem:.1f} GiB" if mem else "unknown",
        "os": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "engine.machine": engine_machine(),
    }


def revision() -> str:
    """The checked-out commit, read from .git without running git (a worktree's .git is a
    file naming its git directory; branches may live in the common directory's refs)."""
    try:
        git = ROOT / ".git"
        if git.is_file():                                   # a linked worktree
            git = (ROOT / git.read_text().split("gitdir:", 1)[1].strip()).resolve()
        common = (git / (git / "commondir").read_text().strip()).resolve() if (git / "commondir").exists() else git
        head = (git / "HEAD").read_text().strip()
        if head.startswith("ref: "):
            for base in (git, common):
                ref = base / head[5:]
                if ref.exists():
                    return ref.read_text().strip()[:12]
            packed = common / "packed-refs"
            for line in packed.read_text().splitlines() if packed.exists() else []:
                if line.endswith(head[5:]):
                    return line.split()[0][:12]
            return "unknown"
        return head[:12]
    except (OSError, IndexError):
        return "unknown"


# --------------------------------------------------------------------------- context

class Context:
    """One run of the experiments: sizes (quick or full), output place, GL renderer, progress."""

    def __init__(self, quick: bool, out: Path, runs: int, progress: bool = True,
                 frame_budget_s: float | None = None):
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

    def skipped_md(self) -> str:
        s = self.take_skipped()
        if not s:
            return ""
        budget = "none" if self.frame_budget_s is None else f"{self.frame_budget_s:g} s"
        return (f"**Not measured** (a frame predicted to take longer than the frame budget, {budget}; "
                "`--frame-budget` changes it):\n\n" + "\n".join(f"- {x}" for x in s) + "\n")

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

    # ---- wording
    @property
    def point_budget_s(self) -> float | None:
        """Seconds of timing after which a measured point stops taking runs (≥ 1 run kept)."""
        return None if self.frame_budget_s is None else 4 * self.frame_budget_s

    def caption(self, runs: int | str | None = None, what: str = "median, spread min–max",
                capped: bool = False) -> str:
        """The line under every table: machine, GL renderer, number of runs.

        ``capped``: the table's points were timed with ``point_budget_s`` (slow points may
        have fewer runs; the raw data has each point's samples)."""
        r = self.runs if runs is None else runs
        runs_txt = f"{r} run{'s' if r != 1 else ''} per point" if isinstance(r, int) else str(r)
        if isinstance(r, int) and r > 1 and what:
            runs_txt += f" ({what})"
        if capped and isinstance(r, int) and r > 1 and self.point_budget_s is not None:
            runs_txt += (f", after one untimed warm-up frame; a point stops after {self.point_budget_s:g} s of timing "
                         "(≥ 1 run; each point's samples are in the raw data)")
        return f"*Machine: {self.machine_short}. GL: {self.gl}. Runs: {runs_txt}.*"

    def caption_cpu(self, runs: int | str | None = None, what: str = "median, spread min–max") -> str:
        """Caption for CPU-only tables (the GL renderer is named anyway: it is the same run)."""
        return self.caption(runs, what)

    # ---- progress and logging
    def bar(self, iterable: Iterable | None = None, desc: str = "", total: int | None = None):
        from tqdm import tqdm
        return tqdm(iterable, desc=desc, total=total, leave=False, position=1, dynamic_ncols=True,
                    disable=not self.progress, file=sys.stderr)

    def log(self, msg: str) -> None:
        from tqdm import tqdm
        tqdm.write(msg, file=sys.stderr)

    def note(self, msg: str) -> None:
        """A line repeated in the summary at the end of the run (values to put into code)."""
        self.notes.append(msg)
        self.log(msg)

    # ---- outputs
    def savefig(self, fig, name: str, alt: str) -> str:
        """Save a matplotlib figure as figures/NAME.png; return its Markdown image line."""
        import matplotlib.pyplot as plt
        path = self.figures / f"{name}.png"
        fig.savefig(path, dpi=110 if not self.quick else 60, bbox_inches="tight")
        plt.close(fig)
        return f"![{alt}](figures/{name}.png)"

    def save_data(self, name: str, obj: Any) -> str:
        path = self.figures / f"{name}.json"
        path.write_text(json.dumps(obj, indent=1, default=_json_default))
        return f"figures/{name}.json"

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

    def time_render(self, scene: Scene, settings: RenderSettings, runs: int | None = None,
                    warmup: int = 1, budget_s: float | None | str = "point",
                    post: Callable[[Any], Any] | None = None) -> RenderTiming:
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


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (Stat, RenderTiming)):
        return o.to_json()
    if dataclasses.is_dataclass(o):
        return dataclasses.asdict(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-able: {type(o).__name__}")


# --------------------------------------------------------------------------- Markdown

def md_table(headers: Sequence[str], rows: Iterable[Sequence[Any]], align: str | None = None) -> str:
    """A Markdown table; ``align`` is one character per column: l, r or c (default: l then r)."""
    def esc(c: Any) -> str:  # a "|" inside a cell (|Δt|) would split it
        return str(c).replace("|", "\\|")
    headers = list(headers)
    if align is None:
        align = "l" + "r" * (len(headers) - 1)
    marks = {"l": ":---", "r": "---:", "c": ":---:"}
    lines = ["| " + " | ".join(esc(h) for h in headers) + " |", "|" + "|".join(marks[a] for a in align) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(esc(c) for c in row) + " |")
    return "\n".join(lines)


def fmt_n(n: int) -> str:
    return f"{n:,}"


def fmt_db(x: float) -> str:
    return "∞" if math.isinf(x) else f"{x:.2f}"


def fmt_num(x: float, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    return f"{x:,.{digits}f}"


def details(summary: str, body: str) -> str:
    return f"<details><summary>{summary}</summary>\n\n{body}\n\n</details>"


# --------------------------------------------------------------------------- images

def psnr(ref: np.ndarray, img: np.ndarray) -> float:
    """PSNR in dB of two float images in [0, 1] (∞ when identical), scikit-image's definition."""
    from skimage.metrics import peak_signal_noise_ratio
    a = np.clip(ref, 0.0, 1.0).astype(np.float64)
    b = np.clip(img, 0.0, 1.0).astype(np.float64)
    if np.array_equal(a, b):
        return math.inf
    return float(peak_signal_noise_ratio(a, b, data_range=1.0))


def ssim(ref: np.ndarray, img: np.ndarray) -> float:
    """Structural similarity (scikit-image), colour images in [0, 1]."""
    from skimage.metrics import structural_similarity
    a = np.clip(ref, 0.0, 1.0).astype(np.float64)
    b = np.clip(img, 0.0, 1.0).astype(np.float64)
    win = min(7, a.shape[0], a.shape[1])
    win -= (win + 1) % 2  # odd
    return float(structural_similarity(a, b, channel_axis=2, data_range=1.0, win_size=max(3, win)))


def max_abs(ref: np.ndarray, img: np.ndarray) -> float:
    return float(np.max(np.abs(np.clip(ref, 0, 1).astype(np.float64) - np.clip(img, 0, 1).astype(np.float64))))


def upscale(img: np.ndarray, width: int, height: int) -> np.ndarray:
    """Bilinear upscaling of a float H×W×3 image (Pillow, per channel, pixel centres aligned)."""
    from PIL import Image
    chans = [np.asarray(Image.fromarray(np.ascontiguousarray(img[..., c], dtype=np.float32), mode="F")
                        .resize((width, height), Image.BILINEAR)) for c in range(img.shape[2])]
    return np.stack(chans, axis=2)


def box_down(img: np.ndarray, k: int) -> np.ndarray:
    """Mean over k×k blocks (the box filter of supersampling); input clamped to [0, 1] first."""
    h, w = img.shape[0] // k, img.shape[1] // k
    a = np.clip(img.astype(np.float64), 0.0, 1.0)[: h * k, : w * k]
    return a.reshape(h, k, w, k, -1).mean(axis=(1, 3))


# --------------------------------------------------------------------------- caching of slow references

CACHE_DIR = Path(os.environ.get("POCKETRAY_BENCH_CACHE", Path.home() / ".cache" / "pocketray-bench"))


def cached_array(key: dict, compute: Callable[[], dict[str, np.ndarray]], sources: Sequence[Path] = ()) -> dict:
    """``compute()`` (a dict of arrays), cached on disk under a hash of ``key`` and of ``sources``' text.

    The float64 reference renders of the accuracy experiment take minutes; they only
    change when the scene, the size or the reference tracer's code change.
    """
    h = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode())
    for s in sources:
        h.update(Path(s).read_bytes())
    path = CACHE_DIR / f"{h.hexdigest()[:24]}.npz"
    if path.exists():
        try:
            with np.load(path) as z:
                return {k: z[k] for k in z.files}
        except Exception:
            path.unlink(missing_ok=True)
    out = compute()
    try:
        CACHE_DIR.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, **out)
        tmp.replace(path)
    except OSError:
        pass
    return out


def scenario_label(number: int) -> str:
    return f"scenario {number}"


def log_axis(ax, which: str = "xy", minor_labels: bool = True) -> None:
    """Log scale with plain-number tick labels (1, 20, 300, 4000 rather than 4×10³)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    fmt = FuncFormatter(lambda v, _: f"{v:g}")
    for w in which:
        axis = ax.xaxis if w == "x" else ax.yaxis
        (ax.set_xscale if w == "x" else ax.set_yscale)("log")
        axis.set_major_formatter(fmt)
        axis.set_minor_locator(LogLocator(subs=(2, 5)))
        axis.set_minor_formatter(fmt if minor_labels else NullFormatter())


def plt():
    """matplotlib.pyplot with the non-interactive backend."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    return pyplot
