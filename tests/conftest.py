"""Shared fixtures and markers. GL tests fail (never skip) when no OpenGL context can be made.

Markers (registered in pyproject.toml), set here at collection so that no test has to
remember them:

- ``gl``: the test needs OpenGL — it uses a fixture that makes a context or starts the
  render service (``GL_FIXTURES``, looked up in the test's whole fixture closure), or its
  module says ``pytestmark = pytest.mark.gl`` (a subprocess that renders, say).
  ``pytest -m "not gl"`` is the CPU suite. A session that runs no ``gl`` test also makes
  OpenGL unavailable to itself and its subprocesses (``_no_gl_for_cpu_only_runs``), so a
  GL test that lacks the marker fails in every CPU-only run, not only on a machine
  without GL.
- ``browser``: the test drives Chromium (Playwright).
- ``slow``: long property-based runs, deselected unless the ``-m`` expression names
  ``slow`` (``-m slow``, ``-m "slow and not gl"``). This is done here rather than with
  ``addopts = -m 'not slow'`` because a second ``-m`` on the command line (``-m "not gl"``)
  replaces the first and would run the slow tests.
"""

from __future__ import annotations

import os

import pytest

# schemathesis.parametrize() (tests/server/test_schemathesis.py) needs its plugin; pyproject.toml's
# addopts turn off the entry point it is otherwise loaded by (see there).
pytest_plugins = ("schemathesis.pytest.plugin",)

# Fixtures that make an OpenGL context or start the service (in-process or as a process,
# whose GL worker makes one). Names of tests/server/conftest.py, tests/browser/conftest.py
# and tests/server/test_schemathesis.py: a fixture renamed there must be renamed here (a
# CPU-only run then fails loudly on the tests it stops marking, see below).
GL_FIXTURES = frozenset(
    {
        "gl_renderer",  # tests/conftest.py
        "client",
        "ready_client",
        "spawn_server",  # tests/server/conftest.py
        "api_server",  # tests/server/test_schemathesis.py
        "server",
        "open_client",  # tests/browser/conftest.py
    }
)
BROWSER_FIXTURES = frozenset({"browser", "open_client"})
# What makes libglvnd's EGL find no driver, and the GLX fallback find no display.
NO_GL_ENV = {"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent"}
NO_GL_UNSET = ("DISPLAY", "WAYLAND_DISPLAY")


@pytest.hookimpl(tryfirst=True)  # before pytest's own -m / -k deselection sees the items
def pytest_collection_modifyitems(config, items):
    for item in items:
        names = set(getattr(item, "fixturenames", ()))
        if names & GL_FIXTURES:
            item.add_marker(pytest.mark.gl)
        if names & BROWSER_FIXTURES:
            item.add_marker(pytest.mark.browser)
    if "slow" not in (config.getoption("markexpr") or ""):
        slow = [item for item in items if item.get_closest_marker("slow")]
        if slow:
            config.hook.pytest_deselected(items=slow)
            items[:] = [item for item in items if not item.get_closest_marker("slow")]


class _NoGLForCpuOnlyRuns:
    """A session that runs no ``gl`` test runs without OpenGL, so an unmarked GL test fails.

    A plugin object because this conftest already implements the hook (tryfirst, above);
    this one runs last, after ``-m`` / ``-k`` have deselected: ``items`` are what will run.
    The environment is changed before any test makes a context (libglvnd reads it then)
    and is inherited by the servers and scripts the tests start.
    """

    cpu_only = False

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, config, items):
        if items and not any(item.get_closest_marker("gl") for item in items):
            for name in NO_GL_UNSET:
                os.environ.pop(name, None)
            os.environ.update(NO_GL_ENV)
            self.cpu_only = True

    def pytest_terminal_summary(self, terminalreporter):
        if self.cpu_only:
            terminalreporter.write_line(
                "no 'gl' test selected: ran with OpenGL made unavailable "
                f"({', '.join(f'{k}={v}' for k, v in NO_GL_ENV.items())})"
            )


def pytest_configure(config):
    config.pluginmanager.register(_NoGLForCpuOnlyRuns(), "pocketray-no-gl-for-cpu-only-runs")


@pytest.fixture(scope="session")
def gl_renderer():
    """One GLRenderer for the whole run (the context is owned by the main thread)."""
    from renderer.gl.renderer import GLRenderer, GLUnavailable

    try:
        return GLRenderer()
    except GLUnavailable as e:  # a missing GL is a failure, in CI and everywhere else
        pytest.fail(f"OpenGL is required (Mesa EGL/llvmpipe; ./dev installs it): {e}")
