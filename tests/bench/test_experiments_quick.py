"""Smoke test of the experiments: ``python -m bench.experiments --quick`` writes RESULTS.md and its charts.

Marked ``slow`` (``./dev test -m slow``): every experiment takes minutes even so; the default
run has ``test_experiments_smoke.py``, one experiment through the same plumbing.

The quick mode renders tiny images with few sizes and one run, so its numbers mean
nothing; what is tested is that every experiment runs and writes its section, tables
(with the machine, GL renderer and runs under them) and charts, and that ``--replot``
writes the same sections again from the data the run saved. Needs OpenGL (fails
without it, like every GL test).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys

import pytest

from tests.helpers import ROOT

# python -m bench.experiments renders in a subprocess (the rule of tests/conftest.py sees no door);
# minutes on a loaded machine: out of the default run, test_experiments_smoke.py runs one experiment.
pytestmark = [pytest.mark.gl, pytest.mark.slow]

SECTIONS = {  # experiment name → heading start
    "table_4_2": "## Table 4.2",
    "fig_4_4": "## Fig. 4.4",
    "fig_4_5": "## Fig. 4.5",
    "scaling": "## Scaling",
    "crossover": "## Crossover",
    "peers": "## Peers —",
    "peers_path": "## Peers, full paths",
    "first_hits": "## First hits without a traversal",
    "pareto": "## Speed against accuracy",
    "specialize": "## Model no more than the scene needs",
    "shader": "## The tracer shaped for llvmpipe",
    "meshes": "## Triangle meshes",
    "shapes": "## Analytic shapes against their tessellations",
    "client": "## The phone client",
    "refine": "## Refinement while still",
}
FIGURES = ("table_4_2_leaves", "fig_4_4_fps", "fig_4_5_memory", "scaling_loglog", "crossover", "pareto")


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("experiments")
    env = dict(os.environ, POCKETRAY_BENCH_CACHE=str(out / "cache"))
    proc = subprocess.run(
        [sys.executable, "-m", "bench.experiments", "--quick", "--out", str(out), "--no-progress"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,  # a hang guard: the quick run of every experiment takes 2–4 min on 2 loaded cores
    )
    return out, proc


def test_quick_run_succeeds(quick_run):
    out, proc = quick_run
    assert proc.returncode == 0, f"stdout:\n{proc.stdout[-4000:]}\nstderr:\n{proc.stderr[-4000:]}"
    assert "values measured for the code" in proc.stdout
    assert "AUTO_CROSSOVER_N = " in proc.stdout


def test_results_markdown_has_every_section(quick_run):
    out, _ = quick_run
    md = (out / "RESULTS.md").read_text()
    assert "Quick smoke run" in md
    for name, heading in SECTIONS.items():
        assert f"<!-- BEGIN {name} -->" in md and f"<!-- END {name} -->" in md, name
        section = md.split(f"<!-- BEGIN {name} -->")[1].split(f"<!-- END {name} -->")[0]
        assert section.strip().startswith(heading), (name, section[:200])
        assert "This experiment failed" not in section, section
    assert "| OpenGL renderer |" in md and "| machine |" in md


def test_every_table_states_machine_gl_and_runs(quick_run):
    out, _ = quick_run
    md = (out / "RESULTS.md").read_text()
    for name in SECTIONS:
        section = md.split(f"<!-- BEGIN {name} -->")[1].split(f"<!-- END {name} -->")[0]
        if name == "peers" and "peers not installed" in section:
            continue  # optional dependency group: the section says how to install it
        tables = len(re.findall(r"^\|[-:|]+\|$", section, re.M))
        captions = len(re.findall(r"^\*Machine: .+ GL: .+ Runs: .+\*", section, re.M))
        assert tables >= 1, name
        assert captions >= tables, f"{name}: {tables} tables but {captions} machine/GL/runs captions"


def test_charts_written(quick_run):
    out, _ = quick_run
    md = (out / "RESULTS.md").read_text()
    for name in FIGURES:
        png = out / "figures" / f"{name}.png"
        assert png.exists(), png
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
        assert f"(figures/{name}.png)" in md, name
    for data in ("table_4_2", "fig_4_4", "fig_4_5", "scaling", "crossover", "pareto", "specialize"):
        assert (out / "figures" / f"{data}.json").exists(), data


def test_table_4_2_scenario_1_matches_the_thesis(quick_run):
    out, _ = quick_run
    md = (out / "RESULTS.md").read_text()
    assert "MAX_PRIMS 1: identical" in md and "MAX_PRIMS 8: identical" in md


def test_replot_writes_the_runs_sections_from_its_data(quick_run, tmp_path):
    """Every section of the run, written again from the data it saved: the same text (headings spoilt
    first, so a section not written again cannot pass)."""
    from bench.experiments.__main__ import main
    from bench.experiments.results import assemble, head_of, sections_of

    out, _ = quick_run
    shutil.copytree(out / "figures", tmp_path / "figures")
    path = tmp_path / "RESULTS.md"
    shutil.copy(out / "RESULTS.md", path)
    ran = sections_of(out / "RESULTS.md")
    assemble(path, head_of(path), {name: "## (stale)\n" + text.split("\n", 1)[1] for name, text in ran.items()}, {})
    assert main(["--replot", "--out", str(tmp_path)]) == 0
    again = sections_of(path)
    for name, text in ran.items():
        if "This experiment failed" in text:
            continue  # no data to write it from (test_results_markdown_has_every_section fails then)
        assert again[name] == text, name
    for data in ("table_4_2", "pareto", "dynamic", "shader"):
        assert "run" in json.loads((out / "figures" / f"{data}.json").read_text()), data
