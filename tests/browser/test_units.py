"""The client's unit tests: ``tests/browser/units/test_<module>.mjs``, one file per module of
``client_web/js`` with logic, run by Node's built-in test runner (``node --test``): no browser,
no server — the modules are imported as they are served, and fed with fake pointers, a fake
transport, fake timers and a fake ``fetch``.

One pytest case per file; a failing case names each failing JavaScript test and shows Node's
report of it (``node --test tests/browser/units/test_gestures.mjs`` runs one file by hand).
``scripts/bootstrap.sh`` installs Node; without it these tests fail, never skip.
"""

from __future__ import annotations

import atexit
import json
import os
import re
import shutil
import subprocess
import tempfile
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
UNITS = Path(__file__).parent / "units"
CLIENT = ROOT / "client_web" / "js"
FILES = sorted(UNITS.glob("test_*.mjs"))

# The modules that are DOM or WebGL wiring, checked in Chromium by the other browser tests;
# every other module of client_web/js has its units/test_<name>.mjs.
WIRING = {
    "app.js",
    "device/device.js",
    "device/device_gl.js",
    "device/mode.js",
    "ui/connection.js",
    "ui/errors.js",
    "ui/hint.js",
    "ui/legend.js",
    "ui/notices.js",
    "ui/overlay.js",
    "ui/panel.js",
    "ui/player.js",
}
# The JavaScript tests there are: the 67 assertions made when they ran inside Chromium, one test each, and
# the tests of the modules split out of app.js since. The count only grows.
AT_LEAST = 84


@cache
def declared_settings() -> Path:
    """The render settings' declarations as GET /api/info gives them (units/declared.mjs reads them), in a file."""
    from renderer.config.settings import SETTINGS

    path = Path(tempfile.mkdtemp(prefix="pocketray-units-")) / "settings.json"
    path.write_text(json.dumps([s.metadata() for s in SETTINGS]))
    atexit.register(shutil.rmtree, path.parent, True)
    return path


class NodeRun:
    """One ``node --test`` run of a file, its TAP report split into the top-level tests."""

    def __init__(self, path: Path):
        node = shutil.which("node")
        if node is None:
            pytest.fail(
                "node (Node.js >= 18) is required for the client's unit tests: scripts/bootstrap.sh installs it"
            )
        env = {**os.environ, "POCKETRAY_SETTINGS_JSON": str(declared_settings())}
        r = subprocess.run(
            [node, "--test", "--test-reporter=tap", str(path)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=120,
            env=env,
        )
        self.returncode, self.output = r.returncode, r.stdout + r.stderr
        # A top-level result is "ok N - name" / "not ok N - name" at the start of a line (subtests are indented),
        # followed by its YAML block (the error, expected and actual, the location) up to the next "# Subtest".
        self.results: dict[str, bool] = {}
        self.reports: dict[str, str] = {}
        for m in re.finditer(
            r"^(not ok|ok) \d+ - (.*?)(?: # .*)?$(.*?)(?=^# Subtest|^1\.\.|\Z)", r.stdout, re.M | re.S
        ):
            name = m.group(2)
            self.results[name] = m.group(1) == "ok"
            self.reports[name] = m.group(0).rstrip()

    @property
    def failed(self) -> list[str]:
        return [name for name, ok in self.results.items() if not ok]


@cache
def node_run(path: Path) -> NodeRun:
    return NodeRun(path)


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_client_module(path: Path):
    run = node_run(path)
    failed = run.failed
    if failed or run.returncode != 0 or not run.results:
        names = "\n".join(f"  - {name}" for name in failed) or "  (no test reported a failure; node's output follows)"
        details = "\n\n".join(run.reports[name] for name in failed) or run.output[-6000:]
        pytest.fail(
            f"{path.relative_to(ROOT)}: {len(failed)} of {len(run.results)} JavaScript tests failed "
            f"(node exited {run.returncode}):\n{names}\n\n{details}",
            pytrace=False,
        )


def test_every_client_module_with_logic_has_its_unit_tests():
    modules = {p.relative_to(CLIENT).as_posix() for p in CLIENT.rglob("*.js")}
    tested = {f.stem[len("test_") :] for f in FILES}
    by_name = {Path(m).stem: m for m in modules}
    assert tested - set(by_name) == set(), "unit files of no client module"
    assert WIRING - modules == set(), "WIRING names modules that no longer exist"
    assert {m for m in modules if Path(m).stem not in tested} == WIRING


def test_the_unit_tests_keep_every_assertion():
    total = sum(len(node_run(p).results) for p in FILES)
    assert total >= AT_LEAST, total


def imported_modules(entry: Path) -> list[str]:
    """The modules ``entry`` imports, directly or not, as paths relative to client_web/ (``js/…``)."""
    seen: list[str] = []
    todo = [entry.resolve()]
    while todo:
        path = todo.pop()
        rel = path.relative_to(CLIENT.parent).as_posix()
        if rel in seen:
            continue
        seen.append(rel)
        for m in re.finditer(
            r"^\s*(?:import|export)\b[^;]*?\bfrom\s+'(\.[^']+)'|^\s*import\s+'(\.[^']+)'", path.read_text(), re.M
        ):
            todo.append((path.parent / (m.group(1) or m.group(2))).resolve())
    return seen


def test_the_page_preloads_every_module_it_imports():
    # index.html asks for the whole import graph at once (<link rel="modulepreload">): a module
    # missing there is found level by level again, a round trip later each (the first image later).
    html = (CLIENT.parent / "index.html").read_text()
    preloaded = set(re.findall(r'<link rel="modulepreload" href="([^"]+)">', html))
    graph = set(imported_modules(CLIENT / "app.js")) - {"js/app.js"}
    assert graph - preloaded == set(), "add to index.html: " + " ".join(
        f'<link rel="modulepreload" href="{m}">' for m in sorted(graph - preloaded)
    )
    assert preloaded - graph == set(), "index.html preloads modules the page does not import"
