"""Render settings (the render-settings JSON of ``docs/FORMATS.md``), validated on construction."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from . import limits
from .limits import MAX_IMAGE_SIDE, MAX_TIME, SAMPLES_PER_PIXEL
from .methods import AUTO_METHOD, METHODS as _METHOD_REGISTRY, capabilities
from .modes import MODES
from .scene import SceneError
from .tree_update import DEFAULT_THRESHOLD, UPDATE_SCHEMES

# "auto" picks brute force below the measured crossover n, BIH above it.
METHODS = (*_METHOD_REGISTRY, AUTO_METHOD)
FORMATS = ("png", "jpeg", "npy", "exr")   # exr: float channels (server/exr.py)


@dataclass(frozen=True)
class RenderSettings:
    """How to render a scene.

    width, height: pixels (1 … 4096). method: acceleration method name.
    mode: what the image shows. max_prims / max_tree_depth: BIH build limits
    (depth counts the root as 1, as Table 4.2). max_recursion_depth: 1 = primary
    rays only (the thesis's Fig. 4.4), each reflected or transmitted ray is one
    more level. format: encoding of the HTTP response.
    samples_per_pixel: 1, 4, 9 or 16 — the frame is traced at √s times the
    resolution and box-filtered (stratified supersampling); depth, primid and
    normal come from the sub-pixel nearest the pixel centre.
    min_weight: ε ≥ 0; a reflected or transmitted ray whose path weight (the
    product of kr/kt along its path) is below ε is not traced.
    tile_size: tile edge in pixels of the hierarchical ray engine (hre), ``limits.MIN_TILE_SIZE`` …
    ``limits.MAX_TILE_SIZE`` (images it does not divide are padded).
    specialize: compile the shader with only the features the scene uses and
    clamp the recursion depth to what its materials can use (exact: the image
    does not change); False renders with the generic variant.
    time: seconds (0 … 1e6) at which an animated scene is posed (ignored by a static one).
    update: how a method that keeps its tree between frames of an animation follows the
    motion — ``rebuild`` (every frame, the thesis's way), ``refit`` or ``selective``
    (rebuild the subtrees whose SAH cost grew by more than ``update_threshold``, a
    fraction: 0.3 = +30 %); see :mod:`renderer.tree_update`.
    """
    width: int = 640
    height: int = 1088
    method: str = "bih"
    mode: str = "color"
    max_prims: int = 8
    max_tree_depth: int = limits.MAX_TREE_DEPTH
    max_recursion_depth: int = 5
    format: str = "png"
    samples_per_pixel: int = 1
    min_weight: float = 0.0
    specialize: bool = True
    tile_size: int = limits.DEFAULT_TILE_SIZE
    time: float = 0.0
    update: str = "rebuild"
    update_threshold: float = DEFAULT_THRESHOLD

    def __post_init__(self) -> None:
        def integer(name: str, lo: int, hi: int) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int):
                raise SceneError(name, f"expected an integer, got {v!r}")
            if not lo <= v <= hi:
                raise SceneError(name, f"must be in {lo} … {hi}, got {v}")

        def number(name: str, lo: float, hi: float) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= float(v) <= hi):
                raise SceneError(name, f"must be a number in [{lo:g}, {hi:g}], got {v!r}")

        integer("width", 1, MAX_IMAGE_SIDE)
        integer("height", 1, MAX_IMAGE_SIDE)
        integer("max_prims", 1, limits.MAX_PRIMS)
        integer("max_tree_depth", 1, limits.MAX_TREE_DEPTH)
        integer("max_recursion_depth", 1, limits.MAX_RECURSION_DEPTH)
        integer("tile_size", limits.MIN_TILE_SIZE, limits.MAX_TILE_SIZE)
        if self.samples_per_pixel not in SAMPLES_PER_PIXEL or isinstance(self.samples_per_pixel, bool):
            raise SceneError("samples_per_pixel", f"must be one of {SAMPLES_PER_PIXEL}, got {self.samples_per_pixel!r}")
        k = self.supersampling
        if max(self.width, self.height) * k > MAX_IMAGE_SIDE:
            raise SceneError("samples_per_pixel", f"{self.width}×{self.height} at {self.samples_per_pixel} samples "
                             f"needs {self.width * k}×{self.height * k}, over the {MAX_IMAGE_SIDE} limit")
        number("min_weight", *limits.MIN_WEIGHT_RANGE)
        number("time", 0.0, MAX_TIME)
        number("update_threshold", *limits.UPDATE_THRESHOLD_RANGE)
        if not isinstance(self.specialize, bool):
            raise SceneError("specialize", f"expected true or false, got {self.specialize!r}")
        for name, allowed in (("method", METHODS), ("mode", MODES), ("format", FORMATS), ("update", UPDATE_SCHEMES)):
            if getattr(self, name) not in allowed:
                raise SceneError(name, f"unknown {name} {getattr(self, name)!r}; one of {', '.join(allowed)}")
        self.check_method()

    def check_method(self, n_spheres: int = 0) -> None:
        """The method can draw the mode (``auto`` resolved for ``n_spheres``): no frame of
        these settings is refused later for a combination known now."""
        able = capabilities(self.method, n_spheres).modes
        if self.mode not in able:
            hint = " (it shows the hierarchical ray engine's cones: use method 'hre')" if self.mode == "cones" else \
                f"; its modes: {', '.join(able)}"
            raise SceneError("mode", f"mode {self.mode!r} is not available with method {self.method!r}{hint}")

    @property
    def supersampling(self) -> int:
        """Sub-pixels per side: √samples_per_pixel."""
        return {1: 1, 4: 2, 9: 3, 16: 4}.get(self.samples_per_pixel, 1)

    def with_(self, **kw: Any) -> RenderSettings:
        return replace(self, **kw)

    def to_json(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_json(d: Any) -> RenderSettings:
        if not isinstance(d, dict):
            raise SceneError("settings", "expected an object")
        names = {f.name for f in fields(RenderSettings)}
        unknown = set(d) - names
        if unknown:
            raise SceneError(sorted(unknown)[0], f"unknown setting (allowed: {', '.join(sorted(names))})")
        return RenderSettings(**d)
