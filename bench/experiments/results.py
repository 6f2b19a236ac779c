"""RESULTS.md: its header, its sections between markers, and what a section says of its run.

Every experiment's section sits between ``<!-- BEGIN name -->`` and ``<!-- END name -->``;
a run (or ``--replot``) replaces the sections it wrote and keeps the others.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

from . import EXPERIMENTS
from .context import Context, RunInfo
from .machine import revision

BEGIN = "<!-- BEGIN {} -->"
END = "<!-- END {} -->"
COMMAND = "./dev bench experiments"


def header(ctx: Context, argv: list[str]) -> str:
    m = ctx.machine
    quick = (
        "\n> **Quick smoke run** (`--quick`): tiny images, few sizes, one run per point. "
        "The numbers show that the scripts work, nothing else.\n"
        if ctx.quick
        else ""
    )
    cmd = " ".join([COMMAND, *argv]).strip()
    budget = (
        "none"
        if ctx.frame_budget_s is None
        else f"{ctx.frame_budget_s:g} s: a configuration whose frame is predicted to take longer is not measured "
        f"(listed where it applies); a point stops taking runs after {ctx.point_budget_s:g} s of timing"
    )
    lines = [
        "# pocketray — experiments",
        "",
        "<!-- Written by `python -m bench.experiments`. Do not edit by hand: every number below was "
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


def stamp(elapsed_s: float, quick: bool) -> str:
    """The last line of a section: when it was measured and how long that took."""
    return (
        f"<sub>Section produced {time.strftime('%Y-%m-%d %H:%M %Z')} in "
        f"{elapsed_s:.0f} s{' (quick mode)' if quick else ''}.</sub>"
    )


def with_stamp(fragment: str, stamp_line: str) -> str:
    return fragment.rstrip() + ("\n\n" + stamp_line + "\n" if stamp_line else "\n")


def head_of(path: Path) -> str | None:
    """The header of an existing RESULTS.md (everything before the contents), or None."""
    if not path.exists():
        return None
    text = path.read_text()
    i = text.find("## Contents")
    return text[:i] if i >= 0 else None


def sections_of(path: Path) -> dict[str, str]:
    """The sections of an existing RESULTS.md by experiment name, without their markers."""
    old = path.read_text() if path.exists() else ""
    out = {}
    for name in EXPERIMENTS:
        m = re.search(re.escape(BEGIN.format(name)) + r"\n(.*?)\n" + re.escape(END.format(name)), old, re.S)
        if m:
            out[name] = m.group(1).strip()
    return out


def assemble(path: Path, head: str, fragments: dict[str, str], titles: dict[str, str]) -> None:
    """Write RESULTS.md: the header, then every experiment's section in EXPERIMENTS order.

    Sections not written this time are kept from the existing file (``--only``).
    """
    sections = sections_of(path)
    for name, frag in fragments.items():
        sections[name] = frag.strip()
    toc = ["## Contents", ""]
    for name in EXPERIMENTS:
        if name in sections:
            title = titles.get(name) or _title_of(sections[name]) or name
            toc.append(f"- [{title}](#{_anchor(title)})")
    body = [head.rstrip("\n") + "\n", "\n".join(toc), ""]
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


_CAPTION = re.compile(r"^\*Machine: (.+?)\. GL: (.+?)\. Runs: (.+?)\.\*", re.M)
_STAMP = re.compile(r"^<sub>Section produced .*</sub>$", re.M)


def run_info_from_section(section: str, data_runs: int | None = None) -> RunInfo:
    """The RunInfo of data saved before the data carried its own (``"run"``), read back from
    the section that run wrote: its captions (machine, GL, runs, point budget), its list of
    what the budget left out, its stamp."""
    m = _CAPTION.search(section)
    machine, gl = m.groups()[:2] if m else ("unknown machine", "unknown GL")
    runs = data_runs
    if runs is None:  # the run's count is the largest a caption gives (some tables take fewer runs)
        counts = [re.match(r"(\d+) runs? per point", c.group(3)) for c in _CAPTION.finditer(section)]
        runs = max((int(r.group(1)) for r in counts if r), default=1)
    b = re.search(r"a point stops after ([\d.]+) s of timing", section)
    fb = re.search(r"longer than the frame budget, ([\d.]+) s", section)
    frame_budget = float(fb.group(1)) if fb else (float(b.group(1)) / 4 if b else None)
    skipped = []
    nm = re.search(r"\*\*Not measured\*\*.*?:\n\n((?:- .*\n?)+)", section)
    if nm:
        skipped = [line[2:] for line in nm.group(1).splitlines() if line.startswith("- ")]
    st = _STAMP.search(section)
    return RunInfo(
        machine_short=machine,
        gl=gl,
        runs=runs,
        quick="(quick mode)" in (st.group(0) if st else ""),
        frame_budget_s=frame_budget,
        skipped=skipped,
        stamp=st.group(0) if st else "",
    )
