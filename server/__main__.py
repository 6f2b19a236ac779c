"""``python -m server [serve flags]``: the same as ``pocketray serve`` (``python -m server
render …`` and the other commands of :mod:`server.tools.cli` work too)."""

from __future__ import annotations

import sys

from .tools.cli import COMMANDS, main

if __name__ == "__main__":
    argv = sys.argv[1:]
    sys.exit(main(argv if argv and argv[0] in COMMANDS else ["serve", *argv]))
