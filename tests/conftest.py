"""Shared fixtures and markers. GL tests fail (never skip) when no OpenGL context can be made.

Markers (registered in pyproject.toml), set here at collection so that no test has to
remember them:

- ``gl``: the test needs OpenGL. Derived from the code it runs (``uses_gl``): the test
  function and every fixture in its closure, followed through the helpers they call that live
  in ``tests/``, reach one of the doors to GL (``_gl_doors``: a ``GLRenderer``,
  a context, an app whose lifespan starts the GL worker, EGL's devices) or start the
  service as a process (``python -m server``). A subprocess of another kind that renders
  says so with ``pytestmark = pytest.mark.gl`` in its module. ``pytest -m "not gl"`` is the
  CPU suite. A session that runs no ``gl`` test also makes OpenGL unavailable to itself and
  its subprocesses (``_no_gl_for_cpu_only_runs``), so a GL test that the rule misses fails in
  every CPU-only run, not only on a machine without GL (``tests/test_gl_marks.py`` runs one).
- ``browser``: the test drives Chromium (Playwright).
- ``long``: a file with tens of seconds of work says so (``pytestmark``); such files are put
  first, so that ``./dev test``'s workers take them first.
- ``slow``: long runs (property-based runs with many examples, every experiment's quick run),
  deselected unless the ``-m`` expression names ``slow`` (``-m slow``, ``-m "slow and not gl"``).
  This is done here rather than with ``addopts = -m 'not slow'`` because a second ``-m`` on
  the command line (``-m "not gl"``) replaces the first and would run the slow tests.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import os
import sys
import types
from pathlib import Path

import pytest

BROWSER_FIXTURES = frozenset({"browser", "open_client"})
# What makes libglvnd's EGL find no driver, and the GLX fallback find no display.
NO_GL_ENV = {"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent"}
NO_GL_UNSET = ("DISPLAY", "WAYLAND_DISPLAY")


# The code followed by ``uses_gl``: the tests and their helpers. The engine, the service and the
# benchmarks are not followed (by name nearly all of them reach GL, whatever the arguments
# say); the engine's and the service's doors to GL are named instead.
_FOLLOWED = Path(__file__).resolve().parent
_CHECKOUT = _FOLLOWED.parent
# What starts the service or its CLI as a process: ``python -m server ...``.
_SERVICE_MODULE = "server"


@functools.cache
def _gl_doors() -> tuple[object, ...]:
    """Each way into OpenGL: a context, the renderer that makes one, an app (its lifespan starts
    the GL worker, whose default renderer makes one), EGL's list of devices."""
    from renderer.gl.context import create_context
    from renderer.gl.gpus import list_gpus
    from renderer.gl.renderer import GLRenderer
    from server.app import create_app
    from server.frames.trace import default_renderer

    return (create_context, GLRenderer, create_app, default_renderer, list_gpus)


def _followed(obj: object) -> bool:
    try:
        path = inspect.getsourcefile(obj)  # type: ignore[arg-type]
    except TypeError:
        return False
    return path is not None and Path(path).resolve().is_relative_to(_FOLLOWED)


def _ours(module: types.ModuleType) -> bool:
    """A module of this checkout (the engine, the service, the tests), not of a library."""
    path = getattr(module, "__file__", None)
    if path is None:
        return False
    where = Path(path).resolve()
    return where.is_relative_to(_CHECKOUT) and "site-packages" not in where.parts


def _code_objects(code: types.CodeType):
    yield code
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _code_objects(const)


def _functions_of(obj: object) -> list[types.FunctionType]:
    if isinstance(obj, types.FunctionType):
        return [obj]
    if isinstance(obj, type):
        out = []
        for attr in vars(obj).values():
            if isinstance(attr, (staticmethod, classmethod)):
                attr = attr.__func__
            if isinstance(attr, property):
                out += [f for f in (attr.fget, attr.fset) if isinstance(f, types.FunctionType)]
            elif isinstance(attr, types.FunctionType):
                out.append(attr)
        return out
    return []


_verdicts: dict[int, bool] = {}


def _reaches_gl(fn: types.FunctionType) -> bool:
    """Whether ``fn`` (or a nested function, or a followed helper it names) opens GL."""
    key = id(fn)
    if key in _verdicts:
        return _verdicts[key]
    _verdicts[key] = False  # while it is looked at: a helper that calls back adds nothing new
    _verdicts[key] = verdict = _names_a_door(fn)
    return verdict


def _names_a_door(fn: types.FunctionType) -> bool:
    doors = _gl_doors()
    scope = fn.__globals__
    for code in _code_objects(fn.__code__):
        consts = {c for c in code.co_consts if isinstance(c, str)}
        if "-m" in consts and _SERVICE_MODULE in consts:
            return True
        found: list[object] = []
        for name in code.co_names:
            obj = scope.get(name)
            if obj is None and name.partition(".")[0] in ("server", "renderer", "tests"):
                obj = sys.modules.get(name)  # ``from server.app import create_app`` inside a function
                if obj is None:
                    try:
                        obj = importlib.import_module(name)
                    except ImportError:
                        obj = None
            if isinstance(obj, types.ModuleType) and _ours(obj):
                found += [getattr(obj, n) for n in code.co_names if hasattr(obj, n)]
            elif obj is not None:
                found.append(obj)
        for obj in found:
            if any(obj is door for door in doors):
                return True
            if _followed(obj) and any(_reaches_gl(f) for f in _functions_of(obj)):
                return True
    return False


def uses_gl(item: pytest.Item) -> bool:
    """Whether the test's own code or any fixture in its closure opens GL (see the module's doc)."""
    functions = [getattr(item, "function", None)]
    info = getattr(item, "_fixtureinfo", None)
    if info is not None:
        functions += [d.func for defs in info.name2fixturedefs.values() for d in defs]
    plain = (inspect.unwrap(f) for f in functions if f is not None)
    return any(_reaches_gl(f) for f in plain if isinstance(f, types.FunctionType))


@pytest.hookimpl(tryfirst=True)  # before pytest's own -m / -k deselection sees the items
def pytest_collection_modifyitems(config, items):
    for item in items:
        names = set(getattr(item, "fixturenames", ()))
        if uses_gl(item):
            item.add_marker(pytest.mark.gl)
        if names & BROWSER_FIXTURES:
            item.add_marker(pytest.mark.browser)
    if "slow" not in (config.getoption("markexpr") or ""):
        slow = [item for item in items if item.get_closest_marker("slow")]
        if slow:
            config.hook.pytest_deselected(items=slow)
            items[:] = [item for item in items if not item.get_closest_marker("slow")]
    # Files marked long first, each file's tests in their order: xdist (``--dist loadfile
    # --no-loadscope-reorder``, as ./dev test runs it) hands files out in this order, so the
    # longest are begun early and the last file left to a worker is a short one.
    long_files = {item.path for item in items if item.get_closest_marker("long")}
    if long_files:
        items.sort(key=lambda item: item.path not in long_files)  # stable: the rest keep their order


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


_session_renderers: list = []  # the session's gl_renderer, once a test has asked for it


@pytest.fixture(scope="session")
def gl_renderer():
    """One GLRenderer for the whole run (the context is owned by the main thread)."""
    from renderer.gl.renderer import GLRenderer, GLUnavailable

    try:
        renderer = GLRenderer()
    except GLUnavailable as e:  # a missing GL is a failure, in CI and everywhere else
        pytest.fail(f"OpenGL is required (Mesa EGL/llvmpipe; ./dev installs it): {e}")
    _session_renderers.append(renderer)
    return renderer


def _release_programs(renderer) -> None:
    """Release the compiled variants a GLRenderer holds (it compiles again what it is asked for)."""
    renderer.programs.clear()


@pytest.fixture(scope="module", autouse=True)
def _gl_programs_released_at_module_end():
    """The session renderer's compiled variants are released after each module: llvmpipe's
    programs take ~2 MB each, and a worker that runs many GL modules (the stability catalogue
    alone compiles hundreds) otherwise keeps every variant it ever compiled. A module's tests
    still share theirs; the next module compiles what it uses."""
    yield
    for renderer in _session_renderers:
        _release_programs(renderer)


@pytest.fixture
def gl_renderer_released_after(gl_renderer):
    """The session's GLRenderer, its compiled variants released when the test ends: for a test
    that compiles a thousand variants to look at them once (3.5 GB resident otherwise)."""
    yield gl_renderer
    _release_programs(gl_renderer)
