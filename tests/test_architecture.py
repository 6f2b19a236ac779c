"""The import rules of the layers, read from the source with ``ast``.

- no import cycle among the modules of ``renderer/`` and ``server/``;
- only ``renderer/gl/`` and the server's GL worker import ``moderngl`` / ``glcontext``;
- with ``moderngl`` and ``glcontext`` made unimportable, every ``renderer`` module
  outside ``renderer/gl/`` still imports (run in a fresh interpreter);
- the core does not import ``renderer.accel``, and ``renderer.accel`` never imports
  ``renderer.config.methods``, ``renderer.config.settings`` or ``renderer.gl`` — directly or through
  another module (a core module that imported ``renderer.config.settings`` would depend on every
  method through the registry), the chain is printed.

Every import counts, wherever it is written: at module level, inside a function (a lazy
import still runs, and still ties the layers together) and under ``if TYPE_CHECKING:``
(a type-only dependency is still a dependency of the layer). Relative imports are resolved
against the importing module's package; ``from pkg import name`` depends on the submodule
``pkg.name`` when there is one and on ``pkg`` (its ``__init__``) otherwise. The implicit
import of the parent packages (``import a.b.c`` runs ``a/__init__.py`` and
``a/b/__init__.py`` first) is not an edge: a package that imports its own submodules
would otherwise always close a cycle, and Python resolves that order by itself.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from fnmatch import fnmatchcase
from functools import cache
from pathlib import Path

from tests.helpers import ROOT

PACKAGES = ("renderer", "server")
GL_LIBRARIES = ("moderngl", "glcontext")
# Who may import the GL libraries: the GL package, and the server's GL worker (the one
# thread that owns the context, server/frames/trace.py).
GL_ALLOWED = ("renderer.gl", "renderer.gl.*", "server.frames.trace")
# The service's parts, top down: the commands (server.tools), the application (server.app), the API
# (routes, deps, errors, bodies, its own schemas), and below it the parts the API calls: sessions (the
# Model), frames (the View) and the HTTP guards. Those never reach up. Below them all lies the contract
# (server.contract: the models both the API and the sessions read), which reaches none of them.
SERVER_PARTS = ("server.sessions", "server.frames", "server.http")
SERVER_ABOVE_PARTS = ("server.tools", "server.app", "server.api")
SERVER_CONTRACT = "server.contract"
# The core modules that may name the methods (the registry, the shader assembly, the
# settings' method validation, the reference tracer's BIH heat mode, a frame's plan — the method
# resolved and checked — and its preparation — pose, build, cost — through the registry).
CORE_MAY_IMPORT_ACCEL = {
    "renderer.config.methods",
    "renderer.frame.shader_source",
    "renderer.config.settings",
    "renderer.oracle.reference",
    "renderer.frame.plan",
    "renderer.frame.prepare",
}
ACCEL_MUST_NOT_IMPORT = ("renderer.config.methods", "renderer.config.settings", "renderer.gl")
# renderer/ in folders by role (README, "What is where"): the core's folders, below accel/ and gl/,
# and the few modules at its top that every folder shares (leaves: they import nothing of renderer).
CORE_FOLDERS = ("geometry", "materials", "scenes", "io", "gpu", "image", "config", "frame", "oracle")
CORE_TOP = ("limits", "errors", "resources", "modes", "integrators")


@dataclass(frozen=True)
class Import:
    target: str  # the module depended on (internal: a module of the graph; external: as written)
    line: int


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def modules() -> dict[str, Path]:
    found = {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}
    assert found, "no module found: the test reads the wrong directory"
    return found


def _package_of(name: str) -> str:
    """The package a module's relative imports start from."""
    return name if modules()[name].name == "__init__.py" else name.rpartition(".")[0]


def _resolve(package: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = package.split(".")
    if node.level > 1:
        base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _literal_import(node: ast.Call) -> str | None:
    """``importlib.import_module("x")`` / ``__import__("x")`` with a literal name."""
    f = node.func
    called = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
    if (
        called in ("import_module", "__import__")
        and node.args
        and isinstance(node.args[0], ast.Constant)
        and isinstance(node.args[0].value, str)
    ):
        return node.args[0].value
    return None


def read_imports(source: str, package: str, known) -> list[Import]:
    """Every import of a module's source, anywhere in its body (``ast.walk`` enters
    functions, classes and ``if TYPE_CHECKING:`` blocks alike); ``package`` is the one its
    relative imports start from, ``known`` the modules that exist."""
    out: list[Import] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [Import(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(package, node)
            for a in node.names:
                sub = f"{base}.{a.name}"
                out.append(Import(sub if sub in known else base, node.lineno))
        elif isinstance(node, ast.Call) and (target := _literal_import(node)):
            out.append(Import(target, node.lineno))
    return out


@cache
def imports_of(name: str) -> tuple[Import, ...]:
    return tuple(read_imports(modules()[name].read_text(), _package_of(name), modules()))


def internal_edges() -> dict[str, set[str]]:
    """module → the modules of renderer/ and server/ it imports (itself excluded)."""
    known = modules()
    graph: dict[str, set[str]] = {}
    for name in known:
        deps = set()
        for imp in imports_of(name):
            target = imp.target
            # ``import a.b.c`` names a.b.c; a name beyond the last module (a.b.c.attr) cannot
            # be written with ``import``, but strip to the longest known module to be safe
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                deps.add(target)
        graph[name] = deps
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as [a, b, …, a], or None (iterative DFS, white/grey/black)."""
    color = dict.fromkeys(graph, 0)
    for start in sorted(graph):
        if color[start]:
            continue
        path, stack = [start], [iter(sorted(graph[start]))]
        color[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                color[path.pop()] = 2
                stack.pop()
            elif color[nxt] == 1:
                return path[path.index(nxt) :] + [nxt]
            elif color[nxt] == 0:
                color[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph[nxt])))
    return None


def _where(name: str, imp: Import) -> str:
    return f"{modules()[name].relative_to(ROOT)}:{imp.line} imports {imp.target}"


def _in(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


# --------------------------------------------------------------------------- the graph itself


def test_the_graph_sees_relative_lazy_and_type_checking_imports():
    """The reader finds what the rules depend on (else every rule below passes vacuously)."""
    g = internal_edges()
    assert "renderer.gl.context" in g["renderer.gl"], "from .context import … in renderer/gl/__init__.py"
    assert "renderer.accel.bvh_layout" in g["renderer.accel.bvh"], "from . import bvh_layout"
    assert "renderer.gpu.gpu_layout" in g["renderer.accel.base"], "from .. import gpu_layout"
    assert "renderer.gl.renderer" in g["server.frames.trace"], "the GL worker's import inside a function"
    gl_engine = {imp.target for imp in imports_of("renderer.gl.ray_engine")}
    assert "moderngl" in gl_engine
    assert sum(len(v) for v in g.values()) > 50


def test_reader_resolves_relative_lazy_and_type_checking_imports():
    source = textwrap.dedent("""
        from typing import TYPE_CHECKING
        from . import sub
        from .pkg import name, mod
        from .. import top
        import a.b as c
        if TYPE_CHECKING:
            from x.y import Z
        def f():
            import moderngl
            importlib.import_module("glcontext")
    """)
    known = {"p", "p.q", "p.q.sub", "p.q.pkg", "p.q.pkg.mod", "p.top"}
    got = {i.target for i in read_imports(source, "p.q", known)}
    assert got == {"typing", "p.q.sub", "p.q.pkg", "p.q.pkg.mod", "p.top", "a.b", "x.y", "moderngl", "glcontext"}


def test_find_cycle_reports_the_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


# ------------------------------------------------------------------------------------- rules


def test_no_import_cycle():
    cycle = find_cycle(internal_edges())
    assert cycle is None, "import cycle: " + " → ".join(cycle)


def test_only_the_gl_layer_imports_moderngl():
    offenders, importers = [], set()
    for name in modules():
        for imp in imports_of(name):
            if imp.target.split(".")[0] in GL_LIBRARIES:
                importers.add(name)
                if not any(fnmatchcase(name, pat) for pat in GL_ALLOWED):
                    offenders.append(_where(name, imp))
    assert "renderer.gl.context" in importers, "the rule must see the GL layer's own imports"
    assert not offenders, "GL imported outside renderer/gl/ and the GL worker:\n" + "\n".join(offenders)


def chain_to(graph: dict[str, set[str]], start: str, forbidden) -> list[str] | None:
    """The shortest import chain [start, …, m] to a module m with forbidden(m), or None."""
    parent, queue = {start: None}, [start]
    for here in queue:
        for dep in sorted(graph[here]):
            if dep in parent:
                continue
            parent[dep] = here
            if forbidden(dep):
                chain = [dep]
                while chain[-1] != start:
                    chain.append(parent[chain[-1]])
                return chain[::-1]
            queue.append(dep)
    return None


def _offending_chains(sources, forbidden) -> list[str]:
    g = internal_edges()
    chains = (chain_to(g, name, forbidden) for name in sorted(sources))
    return [" → ".join(c) for c in chains if c]


def test_core_does_not_import_accel():
    core = [
        n
        for n in modules()
        if _in(n, "renderer")
        and not _in(n, "renderer.accel")
        and not _in(n, "renderer.gl")
        and n not in CORE_MAY_IMPORT_ACCEL
    ]
    assert "renderer.geometry.scene" in core and "renderer.gpu.gpu_layout" in core
    chains = _offending_chains(core, lambda m: _in(m, "renderer.accel"))
    assert not chains, "the core imports renderer.accel:\n" + "\n".join(chains)


def test_accel_does_not_import_registry_settings_or_gl():
    accel = [n for n in modules() if _in(n, "renderer.accel")]
    assert "renderer.accel.bih" in accel
    chains = _offending_chains(accel, lambda m: any(_in(m, up) for up in ACCEL_MUST_NOT_IMPORT))
    assert not chains, "renderer.accel reaches up a layer:\n" + "\n".join(chains)


def test_server_parts_do_not_reach_up_to_the_api():
    parts = [n for n in modules() if any(_in(n, p) for p in SERVER_PARTS)]
    assert "server.sessions.service" in parts and "server.frames.trace" in parts and "server.http.wire" in parts

    def above(m: str) -> bool:
        return m != "server.api" and any(_in(m, up) for up in SERVER_ABOVE_PARTS)

    chains = _offending_chains(parts, above)
    assert not chains, "a part of the service imports the API, the app or the commands:\n" + "\n".join(chains)


def test_sessions_do_not_import_the_api():
    """The sessions read the models they share with the API from the contract, never from the API's
    schemas (whose package also holds the routes that call the sessions)."""
    sessions = [n for n in modules() if _in(n, "server.sessions")]
    assert "server.sessions.service" in sessions and "server.sessions.scenes" in sessions
    chains = _offending_chains(sessions, lambda m: _in(m, "server.api"))
    assert not chains, "server.sessions imports server.api:\n" + "\n".join(chains)


def test_the_contract_imports_no_part_of_the_service():
    """The contract lies below every part of the service: it reads the engine's declarations only."""
    contract = [n for n in modules() if _in(n, SERVER_CONTRACT)]
    assert "server.contract.scene" in contract and "server.contract.settings" in contract
    chains = _offending_chains(contract, lambda m: _in(m, "server") and not _in(m, SERVER_CONTRACT))
    assert not chains, "the contract imports the service:\n" + "\n".join(chains)


def server_part(name: str) -> str:
    """The part of the service a module belongs to: its sub-package (``server.frames``), or itself for
    a module at the package's top (``server.config``)."""
    parts = name.split(".")
    return (
        ".".join(parts[:2]) if len(parts) > 2 or name in modules() and modules()[name].name == "__init__.py" else name
    )


def part_edges() -> dict[str, set[str]]:
    """The service's parts → the parts they import (themselves excluded)."""
    out: dict[str, set[str]] = {}
    for name, deps in internal_edges().items():
        if not _in(name, "server"):
            continue
        here = server_part(name)
        out.setdefault(here, set()).update(server_part(d) for d in deps if _in(d, "server") and server_part(d) != here)
    return out


def test_server_parts_have_no_import_cycle():
    """No two parts of the service import each other, directly or around a loop (``http`` and
    ``frames``, say): each part can be read, tested and replaced from what lies below it."""
    g = part_edges()
    assert "server.frames" in g["server.sessions"], "the part graph must see sessions → frames"
    cycle = find_cycle(g)
    assert cycle is None, "import cycle between the service's parts: " + " → ".join(cycle)


def test_frames_do_not_import_sessions():
    """A frame is made from what it is given (scene, camera, settings), never by reading a session."""
    frames = [n for n in modules() if _in(n, "server.frames")]
    assert "server.frames.encode" in frames
    chains = _offending_chains(frames, lambda m: _in(m, "server.sessions"))
    assert not chains, "server.frames imports server.sessions:\n" + "\n".join(chains)


def test_server_packages_import_nothing_of_the_server_on_import():
    """A sub-package's ``__init__`` imports none of the service's modules (the routes' package excepted,
    which assembles the router): importing ``server.contract.scene`` from a session, or
    ``server.api.schemas`` from a tool, then never runs the routes that import the sessions back."""
    inits = [n for n in modules() if modules()[n].name == "__init__.py" and _in(n, "server")]
    assert "server.sessions" in inits and "server.api" in inits
    g = internal_edges()
    offenders = [f"{n} imports {sorted(g[n])}" for n in inits if n != "server.api.routes" and g[n]]
    assert not offenders, "\n".join(offenders)


def test_chain_to_finds_the_shortest_chain():
    g = {"a": {"b", "c"}, "b": {"x"}, "c": {"d"}, "d": {"x"}, "x": set()}
    assert chain_to(g, "a", lambda m: m == "x") == ["a", "b", "x"]
    assert chain_to(g, "c", lambda m: m == "b") is None


BLOCK_GL = textwrap.dedent("""
    import importlib, importlib.abc, json, sys, traceback
    sys.path.insert(0, sys.argv[1])
    BLOCKED = {blocked!r}

    class NoGL(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ImportError(f"{{name}} is blocked: this module must not need OpenGL")
            return None

    sys.meta_path.insert(0, NoGL())
    try:
        import moderngl  # noqa: F401 - the blocker must work, or the test proves nothing
        blocked = False
    except ImportError:
        blocked = True
    failures = {{}}
    for name in json.loads(sys.argv[2]):
        try:
            importlib.import_module(name)
        except Exception:
            failures[name] = traceback.format_exc(limit=-3)
    print(json.dumps({{"blocked": blocked, "failures": failures,
                      "gl_loaded": sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)}}))
""").format(blocked=GL_LIBRARIES)


def test_gl_free_modules_import_without_moderngl():
    gl_free = sorted(n for n in modules() if _in(n, "renderer") and not _in(n, "renderer.gl"))
    assert "renderer.accel.bih" in gl_free and "renderer.oracle.reference" in gl_free
    proc = subprocess.run(
        [sys.executable, "-c", BLOCK_GL, str(ROOT), json.dumps(gl_free)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["blocked"], "the meta-path blocker did not stop `import moderngl`"
    assert not out["failures"], "need OpenGL although outside renderer/gl/:\n" + "\n".join(
        f"{k}:\n{v}" for k, v in out["failures"].items()
    )
    assert out["gl_loaded"] == []


def test_test_modules_outside_packages_have_unique_names():
    """pytest imports a test file outside a package by its base name: two such files of one name are
    one module, and which one a run collects depends on the order its worker meets them."""
    tests = Path(__file__).resolve().parent
    seen: dict[str, list[str]] = {}
    for path in tests.rglob("test_*.py"):
        if (path.parent / "__init__.py").exists():
            continue
        seen.setdefault(path.name, []).append(str(path.relative_to(tests)))
    assert {name: where for name, where in seen.items() if len(where) > 1} == {}


def test_every_renderer_module_lies_in_a_known_folder():
    """Each module of renderer/ is in a folder of the core (CORE_FOLDERS), in accel/ or gl/, or one of
    the shared modules at the top (CORE_TOP), which import nothing of renderer: a new module goes into
    the folder of its role, and a new folder into the table."""
    stray, top_imports = [], []
    for name in modules():
        parts = name.split(".")
        if parts[0] != "renderer" or len(parts) == 1:
            continue
        if len(parts) == 2 and modules()[name].name != "__init__.py":
            if parts[1] not in CORE_TOP:
                stray.append(name)
            top_imports += [_where(name, i) for i in imports_of(name) if _in(i.target, "renderer")]
        elif parts[1] not in (*CORE_FOLDERS, "accel", "gl"):
            stray.append(name)
    assert "renderer.limits" in modules() and any(n.startswith("renderer.geometry.") for n in modules())
    assert not stray, "renderer modules outside the folders of the table: " + ", ".join(stray)
    assert not top_imports, "a shared module at the top imports renderer:\n" + "\n".join(top_imports)


def _core_folder(name: str) -> str | None:
    """The folder of renderer/ a module lies in (a package's __init__ is its own folder), or None."""
    parts = name.split(".")
    if parts[0] != "renderer" or len(parts) < 2:
        return None
    if len(parts) == 2 and modules()[name].name != "__init__.py":
        return None  # the shared modules at the top
    return parts[1]


def test_the_folders_of_renderer_have_no_import_cycle():
    """The folders import each other one way (geometry below gpu below frame, config below frame and
    the oracles, accel below config, gl on top): each can be read and tested from what lies below it."""
    g: dict[str, set[str]] = {}
    for name, deps in internal_edges().items():
        here = _core_folder(name)
        if here is None:
            continue
        g.setdefault(here, set())
        for d in deps:
            there = _core_folder(d)
            if there is not None and there != here:
                g[here].add(there)
                g.setdefault(there, set())
    assert "geometry" in g["gpu"], "the folder graph must see gpu → geometry"
    cycle = find_cycle(g)
    assert cycle is None, "import cycle between the folders of renderer/: " + " → ".join(cycle)
