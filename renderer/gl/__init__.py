"""The GPU side: the only package that imports moderngl.

``context`` makes headless contexts, ``textures`` uploads packed data, ``renderer`` is
the :class:`GLRenderer` (one context, its programs and targets), ``ray_engine`` runs the
multi-pass methods' passes and ``raw_gl`` holds the few GL calls moderngl lacks.
"""

from .context import GLUnavailable, create_context
from .renderer import GLRenderer

__all__ = ["GLRenderer", "GLUnavailable", "create_context"]
