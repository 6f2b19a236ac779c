"""Shared fixtures. GL tests fail (never skip) when no OpenGL context can be made."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def gl_renderer():
    """One GLRenderer for the whole run (the context is owned by the main thread)."""
    from renderer.gl.renderer import GLRenderer, GLUnavailable

    try:
        return GLRenderer()
    except GLUnavailable as e:  # a missing GL is a failure, in CI and everywhere else
        pytest.fail(f"OpenGL is required (Mesa EGL/llvmpipe; ./dev installs it): {e}")
