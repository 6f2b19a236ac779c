"""Render settings (the render-settings JSON of ``docs/FORMATS.md``): each declared once, in
:data:`SETTINGS`, and :class:`RenderSettings`, validated on construction, made from them.

A setting's :class:`SettingSpec` is all that is said of it anywhere: its name, type, bounds or
choices, default, unit, which methods and modes read it, the client's label and a one-line doc.
The API's query, patch and response models (:mod:`server.api.schemas`), the ``pocketray render``
flags, ``GET /api/info``'s ``settings`` (what the client's settings sheet is built from) and
:class:`RenderSettings` are all generated from the table; adding a setting is one entry here
(and the code that reads it).
"""

from __future__ import annotations

import builtins
import dataclasses
from collections.abc import Iterable
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

from . import limits
from .limits import MAX_IMAGE_SIDE, MAX_PATH_DEPTH, MAX_PATH_SAMPLES, MAX_TIME, SAMPLES_PER_PIXEL
from .methods import AUTO_METHOD, METHODS, capabilities, integrator_methods
from .modes import MODES, PRIMARY_MODES, RAY_TREE_MODES
from .scene import SceneError
from .tree_update import DEFAULT_THRESHOLD, UPDATE_SCHEMES

# The names a request may give as ``method``: the registry's, and "auto" (brute force below the
# measured crossover n, BIH above it).
METHOD_NAMES = (*METHODS, AUTO_METHOD)
FORMATS = ("png", "jpeg", "npy", "exr")  # exr: float channels (server/frames/exr.py)
# How a frame's colour is computed (docs/SHADING.md): the thesis's Whitted ray tree, or unidirectional
# path tracing of the same scene (one-pass methods only: Capabilities.integrators).
INTEGRATORS = ("whitted", "path")
# How the path integrator's radiance becomes a png/jpeg pixel (docs/SHADING.md, "Tone mapping").
TONE_MAPS = ("clamp", "reinhard", "aces")
# The path integrator's denoiser (renderer/denoise.py): none, Intel Open Image Denoise, or the
# edge-avoiding à-trous filter (renderer/atrous.py; the one a browser runs in device mode).
DENOISERS = ("off", "oidn", "atrous")

# How a primary-ray frame finds its first hits (renderer/first_hits.py).
FIRST_HITS = ("auto", "trace", "raster", "tiles")

# The JSON types a setting can have (as JSON Schema names them) and their Python types.
TYPES: dict[str, type] = {"integer": int, "number": float, "boolean": bool, "string": str}


@dataclass(frozen=True)
class SettingSpec:
    """One render setting, declared once.

    type: ``integer``, ``number``, ``boolean`` or ``string``. bounds: (lo, hi), inclusive, of a
    number; choices: the values allowed (a string's, or an integer's such as samples_per_pixel).
    doc: the one line every description of it says (API schema, CLI help). label: the client's
    word for it. unit: what its numbers count. capability: read only by the methods whose
    ``Capabilities.settings`` name this (None: by every method). modes: read only in these
    modes (None: in every one). engine: a field of :class:`RenderSettings` (False: the service's
    alone — the JPEG quality of the encoder). stored_since_first: every session ever stored has
    it, so the response model requires it (a setting added later is filled with its default for
    older sessions). sheet: the client's settings sheet offers it. client: the client keeps it
    with its session's settings and carries it to a new session.
    """

    name: str
    type: str
    default: Any
    doc: str
    label: str
    unit: str = ""
    bounds: tuple[Any, Any] | None = None
    choices: tuple[Any, ...] | None = None
    capability: str | None = None
    modes: tuple[str, ...] | None = None
    engine: bool = True
    stored_since_first: bool = False
    sheet: bool = False
    client: bool = False

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"setting {self.name}: type {self.type!r} is not one of {', '.join(TYPES)}")
        if self.type == "string" and not self.choices:
            raise ValueError(f"setting {self.name}: a string setting names its choices")
        if self.type in ("integer", "number") and self.choices is None and self.bounds is None:
            raise ValueError(f"setting {self.name}: a number has bounds or choices")

    @property
    def python_type(self) -> builtins.type:  # `type` here is the field above
        return TYPES[self.type]

    def methods(self) -> list[str]:
        """The method names (``auto`` included, for the BIH it picks above the crossover) that read it."""
        if self.capability is None:
            return list(METHOD_NAMES)
        return [m for m in METHOD_NAMES if self.capability in capabilities(m, 1 << 30).settings]

    def check(self, v: Any) -> None:
        """SceneError naming this setting when ``v`` is not one of its values."""
        name = self.name
        if self.type == "boolean":
            if not isinstance(v, bool):
                raise SceneError(name, f"expected true or false, got {v!r}")
        elif self.type == "string":
            assert self.choices is not None
            if v not in self.choices:
                raise SceneError(name, f"unknown {name} {v!r}; one of {', '.join(self.choices)}")
        elif self.type == "integer" and self.choices is not None:
            if v not in self.choices or isinstance(v, bool):
                raise SceneError(name, f"must be one of {self.choices}, got {v!r}")
        elif self.type == "integer":
            assert self.bounds is not None  # __post_init__: a number has bounds or choices
            lo, hi = self.bounds
            if isinstance(v, bool) or not isinstance(v, int):
                raise SceneError(name, f"expected an integer, got {v!r}")
            if not lo <= v <= hi:
                raise SceneError(name, f"must be in {lo} … {hi}, got {v}")
        else:
            assert self.bounds is not None
            lo, hi = self.bounds
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= float(v) <= hi):
                raise SceneError(name, f"must be a number in [{lo:g}, {hi:g}], got {v!r}")

    def metadata(self) -> dict[str, Any]:
        """What ``GET /api/info`` says of it (``settings``): a client builds its form from this."""
        return {
            "name": self.name,
            "type": self.type,
            "default": self.default,
            "minimum": self.bounds[0] if self.bounds else None,
            "maximum": self.bounds[1] if self.bounds else None,
            "choices": list(self.choices) if self.choices is not None else None,
            "unit": self.unit,
            "label": self.label,
            "doc": self.doc,
            "methods": self.methods(),
            "modes": list(self.modes) if self.modes is not None else list(MODES),
            "engine": self.engine,
            "sheet": self.sheet,
            "client": self.client,
        }


# Every render setting, in the order of the render-settings JSON (and of the API's models).
SETTINGS: tuple[SettingSpec, ...] = (
    SettingSpec(
        "width",
        "integer",
        640,
        f"pixels, 1 … {MAX_IMAGE_SIDE}",
        "Width",
        unit="pixels",
        bounds=(1, MAX_IMAGE_SIDE),
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "height",
        "integer",
        1088,
        f"pixels, 1 … {MAX_IMAGE_SIDE}",
        "Height",
        unit="pixels",
        bounds=(1, MAX_IMAGE_SIDE),
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "method",
        "string",
        "bih",
        "acceleration method; auto: brute force below the measured crossover, bih above it",
        "Method",
        choices=METHOD_NAMES,
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "mode",
        "string",
        "color",
        "what the image shows (docs/SHADING.md)",
        "Mode",
        choices=MODES,
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "first_hits",
        "string",
        "auto",
        "how primary-ray frames (depth, primid, normal) find first hits: trace (the method's traversal per "
        "pixel), raster (each sphere's screen rectangle drawn, its fragments testing that sphere), tiles "
        "(each screen tile's spheres tested nearest first; a scene with meshes or analytic shapes traces) or "
        "auto (the cheapest by the cost model); the same ids and distances either way",
        "First hits",
        choices=FIRST_HITS,
        modes=PRIMARY_MODES,
    ),
    SettingSpec(
        "max_prims",
        "integer",
        8,
        "BIH leaf size limit",
        "Max primitives per leaf",
        unit="primitives",
        bounds=(1, limits.MAX_PRIMS),
        capability="max_prims",
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "max_tree_depth",
        "integer",
        limits.MAX_TREE_DEPTH,
        "BIH depth limit (root = 1)",
        "Max tree depth",
        unit="levels",
        bounds=(1, limits.MAX_TREE_DEPTH),
        capability="max_tree_depth",
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "max_recursion_depth",
        "integer",
        5,
        f"1 = primary rays only; each reflection/refraction +1 (whitted: ≤ {limits.MAX_RECURSION_DEPTH}; "
        f"path: segments of a path, Mitsuba's max_depth, ≤ {MAX_PATH_DEPTH})",
        "Recursion depth",
        unit="levels",
        bounds=(1, MAX_PATH_DEPTH),
        modes=RAY_TREE_MODES,
        stored_since_first=True,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "format",
        "string",
        "png",
        "encoding of the frame: png, jpeg, npy (one array) or exr (OpenEXR, float channels)",
        "Format",
        choices=FORMATS,
        stored_since_first=True,
        client=True,
    ),
    SettingSpec(
        "quality",
        "integer",
        85,
        f"JPEG quality {limits.JPEG_QUALITY_RANGE[0]} … {limits.JPEG_QUALITY_RANGE[1]} (ignored by png and npy)",
        "JPEG quality",
        bounds=limits.JPEG_QUALITY_RANGE,
        engine=False,
        stored_since_first=True,
        client=True,
    ),
    SettingSpec(
        "samples_per_pixel",
        "integer",
        1,
        f"whitted: stratified supersampling, {', '.join(map(str, SAMPLES_PER_PIXEL))} (traced at √s× the "
        f"resolution and box-filtered); path: paths per pixel, 1 … {MAX_PATH_SAMPLES}",
        "Quality (samples per pixel)",
        unit="samples",
        bounds=(1, MAX_PATH_SAMPLES),
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "integrator",
        "string",
        "whitted",
        "whitted: the thesis's ray tree (point lights, Phong); path: unidirectional path tracing (one-pass methods)",
        "Integrator",
        choices=INTEGRATORS,
        capability="integrator",
        modes=("color",),
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "tone_map",
        "string",
        "clamp",
        "path integrator's png/jpeg: clamp, reinhard (L/(1+L)) or aces (Narkowicz's fit), then sRGB",
        "Tone mapping",
        choices=TONE_MAPS,
        modes=("color",),
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "exposure",
        "number",
        0.0,
        "path integrator's png/jpeg: stops, radiance × 2^exposure before tone mapping",
        "Exposure",
        unit="stops",
        bounds=limits.EXPOSURE_RANGE,
        modes=("color",),
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "denoise",
        "string",
        "off",
        "path integrator's radiance: off, oidn (Intel Open Image Denoise) or atrous (edge-avoiding à-trous "
        "filter, the device's), both guided by the first hit's albedo and normal; npy and exr stay undenoised "
        "unless the request itself names it",
        "Denoiser",
        choices=DENOISERS,
        modes=("color",),
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "refine_samples",
        "integer",
        256,
        "colour (path integrator, or Whitted's jittered slices): a resting camera's refinement stream "
        "goes on until its image holds this many samples per pixel",
        "Refine to (samples)",
        unit="samples",
        bounds=limits.REFINE_SAMPLES_RANGE,
        modes=("color",),
        engine=False,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "refine_time_ms",
        "integer",
        0,
        "colour: … or until it has refined this long, wall-clock (0: no time of its own — the view refines "
        "until its samples or the next change, within the service's POCKETRAY_MAX_REFINE_MS of GL time)",
        "Refine for at most",
        unit="ms",
        bounds=limits.REFINE_MS_RANGE,
        modes=("color",),
        engine=False,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "refine_noise",
        "number",
        0.0,
        "colour: … or until its estimated relative noise (RMS error over the mean) is this low (0: no noise target)",
        "Refine to noise",
        unit="fraction",
        bounds=limits.REFINE_NOISE_RANGE,
        modes=("color",),
        engine=False,
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "min_weight",
        "number",
        0.0,
        "ε: reflected/refracted rays of smaller path weight are not traced",
        "Minimum path weight",
        bounds=limits.MIN_WEIGHT_RANGE,
        modes=RAY_TREE_MODES,
        client=True,
    ),
    SettingSpec(
        "specialize", "boolean", True, "shader variant with only the scene's features (exact)", "Specialised shader"
    ),
    SettingSpec(
        "tile_size",
        "integer",
        limits.DEFAULT_TILE_SIZE,
        "hre's tile edge in pixels",
        "Tile size",
        unit="pixels",
        bounds=(limits.MIN_TILE_SIZE, limits.MAX_TILE_SIZE),
        capability="tile_size",
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "time",
        "number",
        0.0,
        "seconds: the time an animated scene is posed at",
        "Time",
        unit="seconds",
        bounds=(0.0, MAX_TIME),
    ),
    SettingSpec(
        "update",
        "string",
        "rebuild",
        "how bvh/twolevel follow the motion between frames: rebuild, refit or selective",
        "Between animation frames",
        choices=UPDATE_SCHEMES,
        capability="update",
        sheet=True,
        client=True,
    ),
    SettingSpec(
        "update_threshold",
        "number",
        DEFAULT_THRESHOLD,
        "selective rebuild: SAH cost growth, 0.3 = +30 %",
        "Selective rebuild threshold",
        unit="fraction",
        bounds=limits.UPDATE_THRESHOLD_RANGE,
        capability="update",
    ),
)


def setting(name: str, specs: Iterable[SettingSpec] | None = None) -> SettingSpec:
    """The declaration of setting ``name``."""
    return next(s for s in (SETTINGS if specs is None else specs) if s.name == name)


def _check_order(spec: SettingSpec) -> int:
    """The order settings are checked in (the first bad one is the one named): integers, the
    integer choices (then the supersampled size), numbers, booleans, strings."""
    if spec.type == "integer":
        return 0 if spec.choices is None and spec.name != "samples_per_pixel" else 1
    return {"number": 2, "boolean": 3, "string": 4}[spec.type]


class _RenderSettingsBase:
    """The behaviour of :class:`RenderSettings`; its fields are the engine settings of :data:`SETTINGS`."""

    _specs: tuple[SettingSpec, ...] = ()
    _checks: tuple[SettingSpec, ...] = ()  # _specs in the order they are checked

    if TYPE_CHECKING:  # the fields are made from SETTINGS at run time

        def __init__(self, **kw: Any) -> None: ...

        def __getattr__(self, name: str) -> Any: ...

    def __post_init__(self) -> None:
        path = getattr(self, "integrator", "whitted") == "path"
        for spec in self._checks:
            spec.check(getattr(self, spec.name))
            if (
                spec.name == "max_recursion_depth"
                and self.max_recursion_depth > limits.MAX_RECURSION_DEPTH
                and (not path or self.mode == "recursion")
            ):  # (the recursion mode draws Whitted's tree)
                raise SceneError(
                    spec.name,
                    f"must be in 1 … {limits.MAX_RECURSION_DEPTH}, got "
                    f"{self.max_recursion_depth} (up to {MAX_PATH_DEPTH} with integrator 'path')",
                )
            if spec.name == "samples_per_pixel" and not path and self.samples_per_pixel not in SAMPLES_PER_PIXEL:
                raise SceneError(
                    spec.name,
                    f"must be one of {SAMPLES_PER_PIXEL}, got {self.samples_per_pixel!r} "
                    f"(any count 1 … {MAX_PATH_SAMPLES} with integrator 'path')",
                )
            if spec.name == "samples_per_pixel":
                k = self.supersampling
                if max(self.width, self.height) * k > MAX_IMAGE_SIDE:
                    raise SceneError(
                        "samples_per_pixel",
                        f"{self.width}×{self.height} at {self.samples_per_pixel} "
                        f"samples needs {self.width * k}×{self.height * k}, over the "
                        f"{MAX_IMAGE_SIDE} limit",
                    )
        self.check_method()

    def check_method(self, n_spheres: int = 0) -> None:
        """The method can draw the mode (``auto`` resolved for ``n_spheres``): no frame of
        these settings is refused later for a combination known now."""
        able = capabilities(self.method, n_spheres).modes
        integrator = getattr(self, "integrator", "whitted")
        if integrator not in capabilities(self.method, n_spheres).integrators:
            raise SceneError(
                "integrator",
                f"integrator {integrator!r} is not available with method "
                f"{self.method!r}; the methods that trace it: {', '.join(integrator_methods(integrator))}",
            )
        if self.mode not in able:
            hint = (
                " (it shows the hierarchical ray engine's cones: use method 'hre')"
                if self.mode == "cones"
                else f"; its modes: {', '.join(able)}"
            )
            raise SceneError("mode", f"mode {self.mode!r} is not available with method {self.method!r}{hint}")

    @property
    def supersampling(self) -> int:
        """Sub-pixels per side: √samples_per_pixel (the path integrator: 1, its samples are paths)."""
        if getattr(self, "integrator", "whitted") == "path":
            return 1
        return {1: 1, 4: 2, 9: 3, 16: 4}.get(self.samples_per_pixel, 1)

    def with_(self, **kw: Any) -> RenderSettings:
        return replace(self, **kw)  # type: ignore[type-var]  # a dataclass, made by build_render_settings

    def to_json(self) -> dict:
        return asdict(self)  # type: ignore[call-overload]  # a dataclass, made by build_render_settings

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Its fields: the engine settings, in their order."""
        return tuple(s.name for s in cls._specs)

    @classmethod
    def from_json(cls, d: Any) -> RenderSettings:
        if not isinstance(d, dict):
            raise SceneError("settings", "expected an object")
        names = set(cls.names())
        unknown = set(d) - names
        if unknown:
            raise SceneError(sorted(unknown)[0], f"unknown setting (allowed: {', '.join(sorted(names))})")
        return cls(**d)


_DOC = """How to render a scene: the engine settings of :data:`SETTINGS` (each one's doc there).

    Validated on construction (:class:`~renderer.scene.SceneError` names the first bad one). max_prims /
    max_tree_depth: BIH build limits (depth counts the root as 1, as Table 4.2). max_recursion_depth: 1 =
    primary rays only (the thesis's Fig. 4.4), each reflected or transmitted ray is one more level.
    samples_per_pixel: 1, 4, 9 or 16 — the frame is traced at √s times the resolution and box-filtered
    (stratified supersampling); depth, primid and normal come from the sub-pixel nearest the pixel centre,
    and the traced size must stay within ``limits.MAX_IMAGE_SIDE``. min_weight: a reflected or transmitted
    ray whose path weight (the product of kr/kt along its path) is below ε is not traced. tile_size: the
    hierarchical ray engine's tile edge (images it does not divide are padded). specialize: compile the
    shader with only the features the scene uses and clamp the recursion depth to what its materials can
    use (exact: the image does not change). time: when an animated scene is posed (a static one ignores
    it). update: how a method that keeps its tree between frames follows the motion — ``rebuild``,
    ``refit`` or ``selective`` (rebuild the subtrees whose SAH cost grew by more than
    ``update_threshold``); see :mod:`renderer.tree_update`. The method must be able to draw the mode.
    """


def build_render_settings(specs: Iterable[SettingSpec] | None = None) -> type:
    """The frozen dataclass of the engine settings of ``specs`` (default: :data:`SETTINGS` as it is now), in
    their order, with their defaults."""
    specs = tuple(s for s in (SETTINGS if specs is None else specs) if s.engine)
    cls = dataclasses.make_dataclass(
        "RenderSettings",
        [(s.name, s.python_type, dataclasses.field(default=s.default)) for s in specs],
        bases=(_RenderSettingsBase,),
        frozen=True,
        namespace={"__doc__": _DOC, "_specs": specs, "_checks": tuple(sorted(specs, key=_check_order))},
    )
    cls.__module__ = __name__  # pickled by name, as a class written here would be
    return cls


if TYPE_CHECKING:
    RenderSettings = _RenderSettingsBase
else:
    RenderSettings = build_render_settings()
