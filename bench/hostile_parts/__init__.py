"""Attacks of ``python -m bench.hostile`` kept in modules of their own, one surface each.

Every module here defines ``PARTS`` (name -> ``part(root: Path, args) -> dict``, as the parts of
``bench/hostile.py``) and may define ``add_arguments(ap: argparse.ArgumentParser)`` for its flags;
``bench/hostile.py`` finds them all, so adding an attack touches only its own module.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

Part = Callable[[Path, argparse.Namespace], dict]


def modules() -> list[ModuleType]:
    """Every attack module of this package, in name order."""
    return [
        importlib.import_module(f"{__name__}.{m.name}")
        for m in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name)
    ]


def parts() -> dict[str, Part]:
    """The parts of every module (a name defined twice is an error, not a silent override)."""
    out: dict[str, Part] = {}
    for mod in modules():
        for name, fn in mod.PARTS.items():
            if name in out:
                raise ValueError(f"hostile part {name!r} defined twice ({mod.__name__})")
            out[name] = fn
    return out


def add_arguments(ap: argparse.ArgumentParser) -> None:
    for mod in modules():
        if hasattr(mod, "add_arguments"):
            mod.add_arguments(ap)
