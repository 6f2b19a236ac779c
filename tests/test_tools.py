"""The tools that keep the code in shape, run as the suite runs: ruff's lint and its formatter's check over
the whole checkout, and mypy over renderer/ and server/ (their settings: pyproject.toml's [tool.ruff] and
[tool.mypy]). Each is this interpreter's own module (the versions of requirements-test.lock); a failure shows
the tool's findings.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.helpers import ROOT

pytestmark = pytest.mark.long  # mypy's run, cold in a fresh clone


def run_tool(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize(
    "args", [("ruff", "check", "."), ("ruff", "format", "--check", ".")], ids=["ruff-check", "ruff-format"]
)
def test_ruff(args: tuple[str, ...]) -> None:
    out = run_tool(*args, "--no-cache")
    assert out.returncode == 0, f"{' '.join(args)} found:\n{out.stdout}{out.stderr}"


def test_mypy() -> None:
    """Every file of [tool.mypy]'s files, checked with its settings (the cache, .mypy_cache/, makes a rerun quick)."""
    out = run_tool("mypy")
    assert out.returncode == 0, f"mypy found:\n{out.stdout}{out.stderr}"
    assert "Success: no issues found" in out.stdout
