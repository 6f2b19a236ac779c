"""Helpers shared by the GL tests."""

from __future__ import annotations


def active(prog) -> set[str]:
    """The active uniforms and uniform blocks of a compiled program, array names without ``[i]``."""
    return {name.split("[")[0] for name in prog}
