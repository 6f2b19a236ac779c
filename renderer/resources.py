"""Where the engine's run-time files are: the GLSL sources.

An installed wheel holds them inside the package (``renderer/shaders/``, mapped there from
the source tree's top-level ``shaders/`` by ``pyproject.toml``) and they are found through
:mod:`importlib.resources`; a source checkout (or an editable install) reads the top-level
``shaders/`` itself. ``POCKETRAY_SHADER_DIR`` is not read here: the engine's shaders are
the package's own (the service serves that directory, see ``server.config``).
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

SOURCE_ROOT = Path(__file__).resolve().parent.parent  # the checkout's root (meaningless in a wheel)


def package_dir(package: str, name: str, source_name: str | None = None) -> Path:
    """``<package>/<name>`` inside the installed package when it is there (a wheel), else
    ``<checkout>/<source_name or name>`` (the source tree keeps it at the top level)."""
    packaged = files(package).joinpath(name)
    if packaged.is_dir():
        return Path(str(packaged))
    return SOURCE_ROOT / (source_name or name)


def shader_dir() -> Path:
    """The directory of the GLSL sources (``raytrace.frag``, ``method_*.glsl``, …)."""
    return package_dir("renderer", "shaders")
