"""Helpers shared by the GL tests."""

from __future__ import annotations

from renderer.config.settings import RenderSettings


def active(prog) -> set[str]:
    """The active uniforms and uniform blocks of a compiled program, array names without ``[i]``."""
    return {name.split("[")[0] for name in prog}


def path(width: int = 32, height: int = 32, spp: int = 32, depth: int = 16, **kw) -> RenderSettings:
    """Settings of a path-traced linear-radiance frame (npy)."""
    return RenderSettings(
        width=width,
        height=height,
        integrator="path",
        samples_per_pixel=spp,
        max_recursion_depth=depth,
        format="npy",
        **kw,
    )
