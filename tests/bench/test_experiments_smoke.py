"""The experiments' plumbing on one experiment: ``python -m bench.experiments --quick --only fig_4_5``
measures, saves its data, draws its chart and writes its section, and ``--replot`` writes the same
section again from that data. Every experiment's quick run is ``test_experiments_quick.py``,
marked ``slow`` (minutes): ``./dev test -m slow`` runs it.

Fig. 4.5 because it is the cheapest experiment with a chart (BIH builds, no frame but the run's
GL probe); it still goes through the run's header, the machine and GL caption, the data file and
the section markers that every experiment shares.
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

pytestmark = pytest.mark.gl  # the run names the GL renderer it measured on, from a context of its own

NAME, HEADING, CHART = "fig_4_5", "## Fig. 4.5", "fig_4_5_memory"


@pytest.fixture(scope="module")
def one_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("experiment")
    proc = subprocess.run(
        [sys.executable, "-m", "bench.experiments", "--quick", "--only", NAME, "--out", str(out), "--no-progress"],
        cwd=ROOT,
        env=dict(os.environ, POCKETRAY_BENCH_CACHE=str(out / "cache")),
        capture_output=True,
        text=True,
        timeout=600,  # a hang guard, not a measure: ~10 s alone
    )
    assert proc.returncode == 0, f"stdout:\n{proc.stdout[-4000:]}\nstderr:\n{proc.stderr[-4000:]}"
    return out


def section(path, name: str = NAME) -> str:
    return path.read_text().split(f"<!-- BEGIN {name} -->")[1].split(f"<!-- END {name} -->")[0]


def test_one_experiment_writes_its_section_table_caption_chart_and_data(one_run):
    md = (one_run / "RESULTS.md").read_text()
    assert "Quick smoke run" in md and "| OpenGL renderer |" in md and "| machine |" in md
    text = section(one_run / "RESULTS.md")
    assert text.strip().startswith(HEADING) and "This experiment failed" not in text
    tables = len(re.findall(r"^\|[-:|]+\|$", text, re.M))
    captions = len(re.findall(r"^\*Machine: .+ GL: .+ Runs: .+\*", text, re.M))
    assert tables >= 1 and captions >= tables, text
    png = one_run / "figures" / f"{CHART}.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"(figures/{CHART}.png)" in text
    assert "run" in json.loads((one_run / "figures" / f"{NAME}.json").read_text())


def test_replot_writes_the_same_section_from_the_saved_data(one_run, tmp_path):
    from bench.experiments.__main__ import main
    from bench.experiments.results import assemble, head_of, sections_of

    shutil.copytree(one_run / "figures", tmp_path / "figures")
    path = tmp_path / "RESULTS.md"
    shutil.copy(one_run / "RESULTS.md", path)
    ran = sections_of(path)[NAME]
    assemble(path, head_of(path), {NAME: "## (stale)\n" + ran.split("\n", 1)[1]}, {})
    assert sections_of(path)[NAME] != ran  # spoilt: only a section written again can pass
    assert main(["--replot", "--only", NAME, "--out", str(tmp_path)]) == 0
    assert sections_of(path)[NAME] == ran
