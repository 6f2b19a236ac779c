"""Where the service's run-time files are: the browser client, the shaders, the state.

The wheel holds the client inside the package (``server/client_web/``, mapped from the
source tree's top-level ``client_web/`` by ``pyproject.toml``) and it is found through
:mod:`importlib.resources`; a source checkout serves the top-level ``client_web/``. State
(the SQLite file) never lives next to the code: its default is ``var/`` under the working
directory, where ``./dev serve`` (the checkout's root) always kept it.
"""

from __future__ import annotations

from pathlib import Path

from renderer.resources import package_dir, shader_dir

__all__ = ["client_dir", "shader_dir", "default_sqlite_path"]


def client_dir() -> Path:
    """The browser client's directory (``index.html``, ``js/``, ``style.css``)."""
    return package_dir("server", "client_web")


def default_sqlite_path() -> Path:
    """``./var/sessions.sqlite3`` of the working directory (resolved when the config is made)."""
    return Path.cwd() / "var" / "sessions.sqlite3"
