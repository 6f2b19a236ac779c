"""The stability catalogue as tests: every case of ``cases.py`` × every method, each
against its thresholds (see ``catalogue.py`` for what one case checks).

The tests only assert. ``docs/STABILITY.md`` is written by ``./dev stability``
(``python -m tests.stability.write``), which runs the same evaluation.
"""

from __future__ import annotations

import pytest

from tests.stability.cases import CASES, Case
from tests.stability.catalogue import evaluate, methods_of

pytestmark = pytest.mark.long  # hundreds of cases, each method


def _params():
    for c in CASES:
        known = dict(c.known_failures)
        for m in methods_of(c):
            marks = [pytest.mark.xfail(strict=True, reason=known[m])] if m in known else []
            yield pytest.param(c, m, id=f"{c.name}-{m}", marks=marks)


@pytest.mark.parametrize("case,method", list(_params()))
def test_case(gl_renderer, case: Case, method: str):
    _, failures = evaluate(gl_renderer, case, method)
    assert not failures, f"{case.name} / {method}:\n  " + "\n  ".join(failures)
