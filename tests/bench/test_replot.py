"""``--replot`` writes sections of RESULTS.md from saved data alone: run on a copy of docs/, it
gives back the committed sections word for word (the run each came from is in its data, or, for
data saved before it was, read back from the section's captions, budget list and stamp).

The sections chosen cover one chart drawn from its data (table_4_2, scaling), tables only
(specialize, hardening), two data files (shader), tables from many groups of rows (shapes) and a
list of what the frame budget left out (scaling). Each copied section's heading is spoilt first,
so a section that was not written again cannot pass.
"""

from __future__ import annotations

import shutil

import pytest

from bench.experiments.__main__ import main
from bench.experiments.results import assemble, head_of, sections_of
from tests.helpers import ROOT

SECTIONS = ("table_4_2", "scaling", "specialize", "hardening", "hardening2", "shader", "shapes")
DATA = {"shader": ("shader", "shader_next")}
DOCS = ROOT / "docs"


def spoilt_copy(out, names) -> None:
    """docs/RESULTS.md and the data of ``names`` in ``out``, each section's heading replaced."""
    (out / "figures").mkdir(parents=True)
    for name in names:
        for stem in DATA.get(name, (name,)):
            shutil.copy(DOCS / "figures" / f"{stem}.json", out / "figures" / f"{stem}.json")
    path = out / "RESULTS.md"
    shutil.copy(DOCS / "RESULTS.md", path)
    spoilt = {
        name: "## (stale)\n" + text.split("\n", 1)[1] for name, text in sections_of(path).items() if name in names
    }
    assemble(path, head_of(path), spoilt, {})


@pytest.fixture(scope="module")
def replotted(tmp_path_factory):
    out = tmp_path_factory.mktemp("replot")
    spoilt_copy(out, SECTIONS)
    status = main(["--replot", "--only", ",".join(SECTIONS), "--out", str(out)])
    return out, status


def test_replot_succeeds(replotted):
    _, status = replotted
    assert status == 0


@pytest.mark.parametrize("name", SECTIONS)
def test_replot_writes_the_committed_section(replotted, name):
    out, _ = replotted
    assert sections_of(out / "RESULTS.md")[name] == sections_of(DOCS / "RESULTS.md")[name]


def test_replot_keeps_the_header_and_the_other_sections(replotted):
    out, _ = replotted
    written, committed = (out / "RESULTS.md").read_text(), (DOCS / "RESULTS.md").read_text()
    assert head_of(out / "RESULTS.md") == head_of(DOCS / "RESULTS.md")
    others = [n for n in sections_of(DOCS / "RESULTS.md") if n not in SECTIONS]
    assert others and all(sections_of(out / "RESULTS.md")[n] == sections_of(DOCS / "RESULTS.md")[n] for n in others)
    assert written == committed


def test_replot_without_data_keeps_the_section(tmp_path, capsys):
    path = tmp_path / "RESULTS.md"
    (tmp_path / "figures").mkdir()
    shutil.copy(DOCS / "RESULTS.md", path)
    assert main(["--replot", "--only", "scheduling", "--out", str(tmp_path)]) == 0
    assert "section kept" in capsys.readouterr().err
    assert path.read_text() == (DOCS / "RESULTS.md").read_text()
