"""Shader text (transitional: the assemblers still live with their GL users)."""
from .gl_renderer import shader_source as tracer_source, vertex_source  # noqa: F401
from .ray_engine import shader_source as pass_source  # noqa: F401
