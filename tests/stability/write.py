"""Run the whole stability catalogue and write ``docs/STABILITY.md`` (``./dev stability``).

The tests (``test_catalogue.py``) only assert; this is the one command that rewrites the
tracked report, on purpose, with the machine's figures. Exit status 1 when a case failed
(the report is still written: a ✗ in it is the point of the report).

    .venv/bin/python -m tests.stability.write [--out PATH]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tests.stability.catalogue import CASES, DOC, EXPECTED, evaluate, render_doc


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=DOC, help=f"where to write the report (default {DOC})")
    args = ap.parse_args(argv)

    from renderer.gl.renderer import GLRenderer, GLUnavailable

    try:
        gl = GLRenderer()
    except GLUnavailable as e:
        print(f"OpenGL is required (Mesa EGL/llvmpipe; ./dev installs it): {e}", file=sys.stderr)
        return 2
    cases = {c.name: c for c in CASES}
    rows, failed = {}, {}
    for i, (name, method) in enumerate(EXPECTED, 1):
        rows[(name, method)], failures = evaluate(gl, cases[name], method)
        print(f"[{i:3d}/{len(EXPECTED)}] {'✗' if failures else '✓'} {name} / {method}", flush=True)
        if failures:
            failed[(name, method)] = failures
    args.out.write_text(render_doc(rows, gl.info))
    print(f"wrote {args.out}: {len(EXPECTED) - len(failed)} of {len(EXPECTED)} passed")
    for (name, method), failures in failed.items():
        print(f"FAILED {name} / {method}:\n  " + "\n  ".join(failures), file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
