"""The charts' shared style (bench/experiments/style.py) and ``--replot``: a method has one colour
and marker in every chart whatever the label says, legends sit outside the axes, and every chart
of docs/figures/ is redrawn from its saved JSON."""

from __future__ import annotations

import json
import shutil

import pytest

from bench.experiments import EXPERIMENTS
from bench.experiments.style import METHOD_STYLE, legend_outside, method_of, plt, series
from renderer.config.methods import METHODS
from tests.helpers import ROOT

pytestmark = pytest.mark.long  # every chart of docs/figures/ redrawn, ray_engines' by rendering


def test_labels_name_their_method_and_get_its_color_and_marker():
    cases = {
        "ours: bih": "bih",
        "BIH 8": "bih",
        "BIH rebuild (thesis)": "bih",
        "bih, MAX_PRIMS 4": "bih",
        "BF": "bruteforce",
        "ours: bruteforce": "bruteforce",
        "bruteforce, depth 5": "bruteforce",
        "BVH refit": "bvh",
        "BVH selective +30 %": "bvh",
        "ours: twolevel": "twolevel",
        "kdtree S2": "kdtree",
        "hre S1, depth 5": "hre",
        "rayengine": "rayengine",
        "auto, depth 1": "auto",
        "Mitsuba 3: sphere shapes": "mitsuba",
        "Mitsuba 3: ellipsoids": "mitsuba-ellipsoids",
        "Embree: icospheres": "embree",
        "thesis BF (iPhone 5s)": "thesis",
    }
    for label, method in cases.items():
        assert method_of(label) == method, label
        assert series(label)["color"] == METHOD_STYLE[method][0]
        assert series(label)["marker"] == METHOD_STYLE[method][1]
    assert set(METHODS) <= set(METHOD_STYLE)  # every registered method has its own entry
    colors = [c for c, _ in METHOD_STYLE.values()]
    assert len(colors) == len(set(colors)) + (1 if "thesis" in METHOD_STYLE else 0)  # thesis shares auto's grey
    assert series("BIH 4", variant=2)["color"] != series("BIH 1")["color"]
    assert series("new-method")["color"] == series("new-method S2")["color"]  # a stable spare colour


def test_the_legend_is_outside_every_axes():
    pyplot = plt()
    fig, axes = pyplot.subplots(1, 2, figsize=(6, 3))
    for ax in axes:
        ax.plot([1, 2], [1, 2], **series("bih"))
        ax.plot([1, 2], [2, 1], **series("BF"))
        ax.legend()
    legend_outside(fig, axes)
    fig.canvas.draw()
    (legend,) = fig.legends
    box = legend.get_window_extent()
    assert all(ax.get_legend() is None for ax in axes)
    assert [t.get_text() for t in legend.get_texts()] == ["bih", "BF"]
    for ax in axes:
        assert not box.overlaps(ax.get_window_extent())
    pyplot.close(fig)


@pytest.mark.gl  # ray_engines' data from before the cones were saved renders them again
def test_every_chart_of_docs_figures_is_redrawn_from_its_saved_data(tmp_path):
    import importlib

    figures = tmp_path / "figures"
    figures.mkdir()
    drawn = set()
    for name in EXPERIMENTS:
        mod = importlib.import_module(f"bench.experiments.{name}")
        src = ROOT / "docs" / "figures" / f"{name}.json"
        if not hasattr(mod, "plot"):
            continue
        shutil.copy(src, figures / src.name)
        charts = mod.plot(json.loads(src.read_text()), figures, quick=True)
        for chart in charts:
            assert (figures / f"{chart}.png").stat().st_size > 1000
        drawn |= set(charts)
    committed = {p.stem for p in (ROOT / "docs" / "figures").glob("*.png") if not p.stem.startswith("readme_")}
    assert committed == drawn, committed ^ drawn
