"""The ``gl`` mark is derived from the code a test runs (tests/conftest.py, ``uses_gl``), so that
``pytest -m "not gl"`` passes where no OpenGL context can be made.

The rule on small cases (a helper that makes an app, a worker on a fake renderer, the service as
a process), then the CPU selection of the files where CPU and GL tests sit side by side, behind
fixtures of their own (a module's app, a test's app), run in a subprocess: a session that selects
no ``gl`` test makes OpenGL unavailable to itself, so a GL test the rule missed fails there.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.conftest import _reaches_gl, uses_gl
from tests.helpers import ROOT

# Files whose CPU tests share the module with tests that make an app of their own, through a
# module fixture (test_trace.py's capped service, test_cors_docs.py's CORS app) or in the test
# itself (test_store.py's corrupt and deleted store files).
MIXED = (
    "tests/server/frames/test_trace.py",
    "tests/server/http/test_cors_docs.py",
    "tests/server/sessions/test_store.py",
)


def _make_app(tmp):
    from server.app import create_app  # imported where it is used, as some fixtures do

    return create_app(tmp)


def _fixture_through_a_helper(tmp_path_factory):
    return _make_app(tmp_path_factory.mktemp("app"))


def _worker_on_a_fake_renderer():
    from server.frames.trace import GLWorker

    return GLWorker(queue_size=1, renderer_factory=object, render_timeout_s=1.0)


def _the_cli_as_a_process():
    return subprocess.run([sys.executable, "-m", "server", "scenario", "1"], check=True)


def _a_nested_function_renders():
    def later():
        from renderer.gl.renderer import GLRenderer

        return GLRenderer()

    return later


@pytest.mark.parametrize(
    ("code", "opens_gl"),
    [
        (_make_app, True),
        (_fixture_through_a_helper, True),  # followed into the helper, whose import is lazy
        (_the_cli_as_a_process, True),
        (_a_nested_function_renders, True),
        (_worker_on_a_fake_renderer, False),  # the GL worker alone opens nothing: its renderer does
    ],
    ids=lambda v: getattr(v, "__name__", str(v)).strip("_"),
)
def test_the_rule_follows_helpers_lazy_imports_nested_functions_and_the_service_as_a_process(code, opens_gl):
    assert _reaches_gl(code) is opens_gl


def test_this_module_is_cpu_only(request):
    assert not uses_gl(request.node) and request.node.get_closest_marker("gl") is None


def test_the_cpu_selection_of_the_mixed_files_runs_without_gl(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", *MIXED, "-m", "not gl", "-q", "-n", "0", "-p", "no:cacheprovider"],
        cwd=ROOT,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
        capture_output=True,
        text=True,
        timeout=900,  # a hang guard, not a measure
    )
    tail = proc.stdout[-6000:] + proc.stderr[-2000:]
    assert proc.returncode == 0, tail
    assert "no 'gl' test selected: ran with OpenGL made unavailable" in proc.stdout, tail
    assert " passed" in proc.stdout and " deselected" in proc.stdout, tail
