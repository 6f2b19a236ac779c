"""One look for every chart of ``docs/figures/``: a method keeps its colour and marker in every
chart, legends sit outside the plots, and charts are drawn from their saved data.

- :func:`method_of` reads the method (or peer) a series label names — ``"ours: bih"``,
  ``"BIH 8"``, ``"BVH refit"``, ``"BF"``, ``"Mitsuba 3: ellipsoids"`` — and :func:`series` gives
  its line style: the method's colour and marker from :data:`METHOD_STYLE` (methods added to
  the registry later get a fixed colour of their own from :data:`SPARE_COLOURS`, by name),
  and a ``variant`` (a MAX_PRIMS, an update scheme, a scenario) as the line style and a
  lighter shade, never as another colour. A series is therefore never coloured by its
  position in a plot, so a panel that lacks a series (brute force builds nothing) does not
  shift the others' colours.
- :func:`legend_outside` puts one legend for the whole figure to its right, outside every
  axes, so that no data hides under it.
- :func:`save` writes the PNG; every experiment module's ``plot(data, figures)`` draws its
  charts from the dict it saved as ``figures/NAME.json``, so ``python -m bench.experiments
  --replot`` redraws them without measuring again.
- :func:`plt` is pyplot on the non-interactive backend, :func:`log_axis` a log axis with plain
  numbers.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

# Methods of renderer.config.methods and the peers of the peers experiment: colour, marker.
METHOD_STYLE: dict[str, tuple[str, str]] = {
    "bih": ("#1f77b4", "o"),  # blue: the thesis's method
    "bruteforce": ("#000000", "s"),  # black: the baseline
    "rayengine": ("#ff7f0e", "^"),
    "hre": ("#d62728", "v"),
    "bvh": ("#2ca02c", "D"),
    "kdtree": ("#9467bd", "P"),
    "twolevel": ("#8c564b", "X"),
    "auto": ("#7f7f7f", "*"),
    "mitsuba": ("#e377c2", "h"),  # Mitsuba 3, sphere shapes
    "mitsuba-ellipsoids": ("#bcbd22", "p"),
    "embree": ("#17becf", "d"),
    "thesis": ("#7f7f7f", "x"),  # numbers quoted from the thesis
}
SPARE_COLOURS = ("#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd", "#e6550d", "#31a354")
SPARE_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "h")
LINESTYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)))
DPI, DPI_QUICK = 110, 60

_ALIASES = (
    ("ellipsoid", "mitsuba-ellipsoids"),
    ("mitsuba", "mitsuba"),
    ("embree", "embree"),
    ("brute", "bruteforce"),
    ("thesis", "thesis"),
)


def method_of(label: str) -> str:
    """The method or peer a series label names (``"ours: bvh"`` → ``bvh``; ``"BF"`` → ``bruteforce``)."""
    text = label.lower()
    if text == "bf" or text.startswith("bf ") or text.startswith("bf,"):
        return "bruteforce"
    for needle, name in _ALIASES:
        if needle in text and (name != "thesis" or "(thesis)" not in text):
            return name
    words = re.findall(r"[a-z0-9_]+", text)
    for name in sorted(METHOD_STYLE, key=len, reverse=True):
        if name != "thesis" and name in words:  # "BIH rebuild (thesis)" is the BIH's
            return name
    return words[0] if words else text


def colour_marker(method: str) -> tuple[str, str]:
    """The colour and marker of ``method`` (a stable spare for a name the map does not know)."""
    if method in METHOD_STYLE:
        return METHOD_STYLE[method]
    i = int(hashlib.sha1(method.encode()).hexdigest(), 16)
    return SPARE_COLOURS[i % len(SPARE_COLOURS)], SPARE_MARKERS[(i // 7) % len(SPARE_MARKERS)]


def shade(colour: str, amount: float) -> str:
    """``colour`` mixed with white by ``amount`` (0 = itself, 1 = white)."""
    c = colour.lstrip("#")
    rgb = [int(c[i : i + 2], 16) for i in (0, 2, 4)]
    mixed = [round(v + (255 - v) * amount) for v in rgb]
    return "#" + "".join(f"{v:02x}" for v in mixed)


def series(label: str, variant: int = 0, method: str | None = None, **extra: Any) -> dict[str, Any]:
    """``plot()`` keyword arguments of a series: its method's colour and marker; ``variant`` ≥ 1
    (a second MAX_PRIMS, another scheme) changes the line style and lightens the colour."""
    colour, marker = colour_marker(method or method_of(label))
    style = {
        "color": shade(colour, min(0.7, 0.15 * variant)) if variant else colour,
        "marker": marker,
        "ls": LINESTYLES[variant % len(LINESTYLES)],
        "label": label,
        "ms": 5,
        "lw": 1.5,
    }
    style.update(extra)
    return style


def legend_outside(
    fig: Any, axes: Any = None, title: str | None = None, ncol: int = 1, extra: Sequence[tuple[Any, str]] = ()
) -> None:
    """One legend for the figure, to the right of every axes (the figure must use the
    constrained layout, which it is switched to); each label once, in first-seen order."""
    if fig.get_layout_engine() is None or type(fig.get_layout_engine()).__name__ != "ConstrainedLayoutEngine":
        fig.set_layout_engine("constrained")
    axes_list = list(_flat(axes if axes is not None else fig.axes))
    seen: dict[str, Any] = {}
    for ax in axes_list:
        old = ax.get_legend()
        if old is not None:
            old.remove()
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label and not label.startswith("_") and label not in seen:
                seen[label] = handle
    for handle, label in extra:
        seen.setdefault(label, handle)
    if seen:
        fig.legend(
            list(seen.values()),
            list(seen),
            loc="outside right upper",
            fontsize=8,
            ncol=ncol,
            title=title,
            title_fontsize=8,
            frameon=False,
        )


def _flat(axes: Any) -> Iterable[Any]:
    if hasattr(axes, "flat"):
        return list(axes.flat)
    if isinstance(axes, (list, tuple)):
        return [a for x in axes for a in _flat(x)]
    return [axes]


def save(fig: Any, figures: Path, name: str, quick: bool = False) -> Path:
    """Write ``figures/NAME.png`` and close the figure."""
    import matplotlib.pyplot as plt

    path = Path(figures) / f"{name}.png"
    fig.savefig(path, dpi=DPI_QUICK if quick else DPI, bbox_inches="tight")
    plt.close(fig)
    return path


def image_line(name: str, alt: str) -> str:
    """The Markdown image line of ``figures/NAME.png``."""
    return f"![{alt}](figures/{name}.png)"


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
