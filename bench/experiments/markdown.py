"""Markdown pieces of the sections of RESULTS.md: tables, number formats, folded blocks."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any


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


def fmt_db(x: float) -> str:
    return "∞" if math.isinf(x) else f"{x:.2f}"


def fmt_num(x: float, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    return f"{x:,.{digits}f}"


def details(summary: str, body: str) -> str:
    return f"<details><summary>{summary}</summary>\n\n{body}\n\n</details>"
