"""Comments explain the code as it is: every repository path, module and name a comment or
docstring of the production code (renderer/, server/, the browser client, the shaders)
points at exists, and none cites the issue tracker, which is not in the repository
(history belongs to git)."""

from __future__ import annotations

import ast
import io
import re
import subprocess
import tokenize
import tomllib
from collections.abc import Iterator
from functools import cache, lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PRODUCTION = ("renderer", "server", "client_web", "shaders")
C_LIKE = (".js", ".glsl", ".frag", ".vert", ".css")


def tracked(*paths: str) -> list[str]:
    out = subprocess.run(["git", "ls-files", "--", *paths], cwd=ROOT, capture_output=True, text=True, check=True)
    return out.stdout.split()


FILES = [f for f in tracked(*PRODUCTION) if f.endswith((".py", ".html", *C_LIKE))]
TOP = sorted({p.split("/")[0] for p in tracked() if "/" in p})
# A path from the repository's root: a top-level folder, then names (``<name>`` and ``*`` stand for any).
TOPS = "|".join(map(re.escape, TOP))
PATH = re.compile(rf"(?<![\w./<>*-])((?:{TOPS})/[\w*<>.{{}},/-]*[\w*>/])")
# A source file named without its folder (``bih_layout.py``, ``method_bvh.glsl``).
BARE = re.compile(r"(?<![\w./<>*-])([\w*<>-]+\.(?:py|js|glsl|frag|vert))\b")
# A Python name in a Sphinx role or a plain dotted reference (``renderer.accel.bih``).
ROLE = re.compile(r":(?:mod|func|class|meth|data|attr|exc):`~?((?:renderer|server)(?:\.\w+)+)`")
# The tracker's numbers: the word issue or issues before a number (with or without #), or a
# number after # closed by a parenthesis.
ISSUE = re.compile(r"\bissues? +#?\d+|\(#\d+\)|#\d+\)", re.I)
# Beyond the production code, every other text of the repository that people read: the tests,
# the documentation, the scripts and the project's files, and the benchmarks' comments and
# docstrings. The result files that scripts write (docs/RESULTS.md, docs/STABILITY.md) and the
# benchmarks' strings that go into them say what docs/RESULTS.md says.
OTHER_TEXT = ("tests", "docs", "bench", "scripts", "deploy", "README.md", "pyproject.toml", "Dockerfile", "dev")
RESULT_WRITERS = ("bench",)
GENERATED = ("docs/RESULTS.md", "docs/STABILITY.md")


def comments(path: str) -> Iterator[tuple[int, str]]:
    """(line, text) of every comment and docstring of a file."""
    src = (ROOT / path).read_text()
    if path.endswith(".py"):
        for tok in tokenize.generate_tokens(io.StringIO(src).readline):
            if tok.type == tokenize.COMMENT:
                yield tok.start[0], tok.string
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
                doc = node.body[0]
                if isinstance(doc, ast.Expr) and isinstance(doc.value, ast.Constant):
                    if isinstance(doc.value.value, str):
                        yield doc.lineno, doc.value.value
        return
    pattern = r"<!--.*?-->" if path.endswith(".html") else r"//[^\n]*|/\*.*?\*/"
    for m in re.finditer(pattern, src, re.S):
        yield src.count("\n", 0, m.start()) + 1, m.group()


def wheel_aliases() -> dict[str, str]:
    """Folders of the installed package that the source tree keeps elsewhere (pyproject's
    package-dir: ``renderer/shaders/`` is the top-level ``shaders/``)."""
    dirs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    return {pkg.replace(".", "/") + "/": src.rstrip("/") + "/" for pkg, src in dirs.items() if pkg}


ALIASES = wheel_aliases()
ALL = tracked()


def exists(path: str) -> bool:
    path = path.rstrip("/")
    for pkg, src in ALIASES.items():
        if (path + "/").startswith(pkg):
            path = src + path[len(pkg) :]
    pattern = re.sub(r"<[^>]*>", "*", path)
    if "*" in pattern or "{" in pattern:
        glob = re.escape(pattern).replace(r"\*", "[^/]*")
        glob = re.sub(r"\\\{(.*?)\\\}", lambda m: "(?:" + "|".join(m[1].split(",")) + ")", glob)
        return any(re.fullmatch(glob + "(?:/.*)?", f) for f in ALL)
    return (ROOT / path).exists()


@cache
def parsed(file: Path) -> ast.Module:
    return ast.parse(file.read_text())


@cache
def module_has(dotted: str) -> bool:
    """``a.b.c``: a module, or a name defined at the top of the longest module prefix (and a
    class's member after it)."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:i])
        file = base.with_suffix(".py") if base.with_suffix(".py").is_file() else base / "__init__.py"
        if file.is_file():
            break
    else:
        return False
    rest = parts[i:]
    if not rest:
        return True
    tree = parsed(file)

    def names(body) -> dict[str, ast.AST]:
        out: dict[str, ast.AST] = {}
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                out[node.name] = node
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                for t in node.targets if isinstance(node, ast.Assign) else [node.target]:
                    for n in ast.walk(t):
                        if isinstance(n, ast.Name):
                            out[n.id] = node
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                for a in node.names:
                    out[(a.asname or a.name).split(".")[0]] = node
            elif isinstance(node, (ast.If, ast.Try)):
                out.update(names(node.body))
        return out

    found = names(tree.body).get(rest[0])
    if found is None:
        return False
    if len(rest) > 1 and isinstance(found, ast.ClassDef):
        members = names(found.body)
        for n in ast.walk(found):  # attributes set in methods (self.x = …)
            if isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store):
                members[n.attr] = n
        return rest[1] in members
    return True


@lru_cache(maxsize=1)
def pointers() -> list[tuple[str, int, str, str]]:
    """(file, line, kind, what) of every path, file name and Python name in comments and docstrings."""
    out = []
    for f in FILES:
        for line, text in comments(f):
            out += [(f, line, "path", m[1].rstrip(".,;:")) for m in PATH.finditer(text)]
            out += [(f, line, "file", m[1]) for m in BARE.finditer(text)]
            out += [(f, line, "name", m[1]) for m in ROLE.finditer(text)]
    return out


def test_the_scan_sees_the_comments_it_should():
    found = pointers()
    kinds = {k for _, _, k, _ in found}
    assert kinds == {"path", "file", "name"} and len(found) > 100
    files = {f for f, *_ in found}
    assert {"renderer/modes.py", "shaders/raytrace.frag", "client_web/js/device/device.js"} <= files
    assert not exists("renderer/hre_cones.py") and exists("renderer/accel/hre_cones.py")
    assert exists("shaders/method_<name>.glsl") and exists("renderer/shaders/raytrace.frag")
    assert module_has("renderer.accel.bih.build_bih") and not module_has("renderer.twolevel")


def test_every_path_named_in_a_comment_exists():
    missing = [f"{f}:{line}: {p}" for f, line, kind, p in pointers() if kind == "path" and not exists(p)]
    assert not missing, "comments point at paths that do not exist:\n" + "\n".join(missing)


def test_every_file_named_in_a_comment_exists():
    names = {p.rsplit("/", 1)[-1] for p in ALL}

    def known(name: str) -> bool:
        pattern = re.escape(re.sub(r"<[^>]*>", "*", name)).replace(r"\*", ".*")
        return any(re.fullmatch(pattern, n) for n in names)

    missing = [f"{f}:{line}: {p}" for f, line, kind, p in pointers() if kind == "file" and not known(p)]
    assert not missing, "comments name files that do not exist:\n" + "\n".join(missing)


def test_every_python_name_in_a_docstring_exists():
    missing = [f"{f}:{line}: {p}" for f, line, kind, p in pointers() if kind == "name" and not module_has(p)]
    assert not missing, "docstrings name modules or objects that do not exist:\n" + "\n".join(missing)


@pytest.mark.parametrize("folder", PRODUCTION)
def test_no_issue_numbers(folder):
    """Code says why; which issue brought a line is in git's history, and the tracker is not
    in the repository. (Every line, strings too: a message must not cite it either.)"""
    found = [
        f"{f}:{i}: {line.strip()}"
        for f in FILES
        if f.startswith(folder + "/")
        for i, line in enumerate((ROOT / f).read_text().splitlines(), 1)
        if ISSUE.search(line)
    ]
    assert not found, "issue numbers in production code:\n" + "\n".join(found)


def issue_numbers(files: list[str], comments_only: bool = False) -> list[str]:
    """``file:line: text`` of every line (of every comment and docstring) citing an issue."""
    found = []
    for f in files:
        if comments_only and f.endswith(".py"):
            texts = [(i, line) for start, text in comments(f) for i, line in enumerate(text.splitlines(), start)]
        else:
            texts = list(enumerate((ROOT / f).read_text(errors="replace").splitlines(), 1))
        found += [f"{f}:{i}: {line.strip()}" for i, line in texts if ISSUE.search(line)]
    return found


@pytest.mark.parametrize("where", OTHER_TEXT)
def test_no_issue_numbers_in_tests_docs_or_benchmarks(where):
    """Tests, docs and benchmarks describe what is, as the code does: a test's docstring says what
    it proves, not which issue asked for it."""
    files = [f for f in tracked(where) if f not in GENERATED and not f.endswith((".png", ".json", ".npy", ".npz"))]
    assert files
    found = issue_numbers(files, comments_only=where in RESULT_WRITERS)
    assert not found, "issue numbers outside the production code:\n" + "\n".join(found)


def test_the_issue_pattern_catches_the_ways_an_issue_is_cited():
    n = 17  # a number of the tracker's, apart, so that this file cites none
    cited = [f"(issue #{n})", f"issue {n}'s defines", f"Issues #{n}, #{n + 1}", f"see (#{n})", f"#{n})"]
    clean = ["no issues found", "issue a request", "item 9", "#define NO_LIGHTS 1", "colour #ff0000"]
    assert all(ISSUE.search(t) for t in cited) and not any(ISSUE.search(t) for t in clean)
