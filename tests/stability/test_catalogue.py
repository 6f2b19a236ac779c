"""The stability catalogue as tests: every case of ``cases.py`` × every method, each
against its thresholds (see ``catalogue.py`` for what one case checks).

The tests only assert. ``docs/STABILITY.md`` is written by ``./dev stability``
(``python -m tests.stability.write``), which runs the same evaluation.
"""

from __future__ import annotations

import pytest

from renderer.methods import METHODS
from tests.stability.cases import CASES, Case
from tests.stability.catalogue import evaluate


@pytest.mark.parametrize("case,method", [(c, m) for c in CASES for m in METHODS],
                         ids=[f"{c.name}-{m}" for c in CASES for m in METHODS])
def test_case(gl_renderer, case: Case, method: str):
    _, failures = evaluate(gl_renderer, case, method)
    assert not failures, f"{case.name} / {method}:\n  " + "\n  ".join(failures)
