"""Render settings (SPEC's render-settings JSON), validated on construction."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from .scene import SceneError

from .methods import METHODS as _METHOD_REGISTRY

METHODS = tuple(_METHOD_REGISTRY)
MODES = ("color", "depth", "primid", "normal", "recursion", "heat")
FORMATS = ("png", "jpeg", "npy")

# The GPU traversal stack holds one entry per tree level; a tree deeper than
# this cannot be built, so a traversal can never overflow (see bih_layout).
MAX_TREE_DEPTH_LIMIT = 64
MAX_RECURSION_DEPTH_LIMIT = 8
MAX_IMAGE_SIDE = 4096


@dataclass(frozen=True)
class RenderSettings:
    """How to render a scene.

    width, height: pixels (1 … 4096). method: acceleration method name.
    mode: what the image shows. max_prims / max_tree_depth: BIH build limits
    (depth counts the root as 1, as Table 4.2). max_recursion_depth: 1 = primary
    rays only (the thesis's Fig. 4.4), each reflected or transmitted ray is one
    more level. format: encoding of the HTTP response.
    """
    width: int = 640
    height: int = 1088
    method: str = "bih"
    mode: str = "color"
    max_prims: int = 8
    max_tree_depth: int = MAX_TREE_DEPTH_LIMIT
    max_recursion_depth: int = 5
    format: str = "png"

    def __post_init__(self) -> None:
        def integer(name: str, lo: int, hi: int) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int):
                raise SceneError(name, f"expected an integer, got {v!r}")
            if not lo <= v <= hi:
                raise SceneError(name, f"must be in {lo} … {hi}, got {v}")
        integer("width", 1, MAX_IMAGE_SIDE)
        integer("height", 1, MAX_IMAGE_SIDE)
        integer("max_prims", 1, 1 << 24)
        integer("max_tree_depth", 1, MAX_TREE_DEPTH_LIMIT)
        integer("max_recursion_depth", 1, MAX_RECURSION_DEPTH_LIMIT)
        for name, allowed in (("method", METHODS), ("mode", MODES), ("format", FORMATS)):
            if getattr(self, name) not in allowed:
                raise SceneError(name, f"unknown {name} {getattr(self, name)!r}; one of {', '.join(allowed)}")

    def with_(self, **kw: Any) -> "RenderSettings":
        return replace(self, **kw)

    def to_json(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_json(d: Any) -> "RenderSettings":
        if not isinstance(d, dict):
            raise SceneError("settings", "expected an object")
        names = {f.name for f in fields(RenderSettings)}
        unknown = set(d) - names
        if unknown:
            raise SceneError(sorted(unknown)[0], f"unknown setting (allowed: {', '.join(sorted(names))})")
        return RenderSettings(**d)
