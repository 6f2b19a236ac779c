"""Render settings (the render-settings JSON of ``docs/FORMATS.md``): each declared once, in
:data:`SETTINGS`; :class:`RenderSettings`, their typed frozen dataclass, validated on construction.

A setting's :class:`SettingSpec` is all that is said of it anywhere: its name, type, bounds or
choices (per integrator where they differ: :class:`IntegratorValues`), default, unit, which methods
and modes read it, the client's label and a one-line doc. The API's query, patch and response models
(:mod:`server.api.schemas`), the ``pocketray render`` flags, ``GET /api/info``'s ``settings`` (what
the client's settings sheet is built from) and the validation of :class:`RenderSettings` are made
from the table. :class:`RenderSettings`' fields and :class:`SettingValues`' keys are written out so
that a type checker sees them, and are held to the table at import (:func:`check_declaration`,
:func:`check_values_type`): adding a setting is one entry here, its field and key, and the code that
reads it.
"""

from __future__ import annotations

import builtins
import enum
import math
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, TypedDict

from .. import limits
from ..geometry.scene import SceneError
from ..integrators import Denoiser, Integrator, ToneMap, values
from ..limits import (
    MAX_IMAGE_SIDE,
    MAX_PATH_DEPTH,
    MAX_PATH_SAMPLES,
    MAX_RECURSION_DEPTH,
    MAX_TIME,
    PATH_SAMPLE_CHOICES,
    SAMPLES_PER_PIXEL,
)
from ..modes import MODES, PRIMARY_MODES, RAY_TREE_MODES
from ..scenes.tree_update import DEFAULT_THRESHOLD, UPDATE_SCHEMES
from .methods import AUTO_METHOD, METHODS, capabilities, integrator_methods

# The names a request may give as ``method``: the registry's, and "auto" (brute force below the
# measured crossover n, BIH above it).
METHOD_NAMES = (*METHODS, AUTO_METHOD)
FORMATS = ("png", "jpeg", "npy", "exr")  # exr: float channels (server/frames/exr.py)
# The JSON values of the settings whose choices are types (renderer/integrators.py).
INTEGRATORS = values(Integrator)
TONE_MAPS = values(ToneMap)
DENOISERS = values(Denoiser)

# How a primary-ray frame finds its first hits (renderer/frame/first_hits.py).
FIRST_HITS = ("auto", "trace", "raster", "tiles")

# The JSON types a setting can have (as JSON Schema names them) and their Python types.
TYPES: dict[str, type] = {"integer": int, "number": float, "boolean": bool, "string": str}


Number = int | float


@dataclass(frozen=True)
class IntegratorValues:
    """What one setting accepts, and what its numbers mean, under one integrator (``SettingSpec.by_integrator``).

    meaning: what a value is under it (the API's description, the CLI's help and ``/api/info`` say it).
    bounds or choices: the values allowed (inside the setting's own bounds, which the API's schema
    states for every integrator). offered: the values a client lists (default: the choices). hint: how
    these values read in another integrator's refusal ("any count 1 … 4096"). subpixel_grid: a value
    ``s`` is a √s × √s grid of sub-pixels, so the frame is traced at √s × its size (which
    ``limits.MAX_IMAGE_SIDE`` bounds). modes: the modes where these values hold (None: every one); in
    the others the frame is Whitted's ray tree, and Whitted's values hold.
    """

    meaning: str
    bounds: tuple[Number, Number] | None = None
    choices: tuple[Number, ...] | None = None
    offered: tuple[Number, ...] | None = None
    hint: str = ""
    subpixel_grid: bool = False
    modes: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if (self.bounds is None) == (self.choices is None):
            raise ValueError(f"values {self.meaning!r}: bounds or choices, one of them")

    def accepts(self) -> str:
        """The values, in words: ``one of 1, 4, 9, 16`` or ``1 … 4096``."""
        if self.choices is not None:
            return "one of " + ", ".join(map(str, self.choices))
        assert self.bounds is not None
        return f"{self.bounds[0]} … {self.bounds[1]}"

    def listed(self) -> tuple[Number, ...] | None:
        """The values a client lists for it."""
        return self.offered if self.offered is not None else self.choices

    def metadata(self) -> dict[str, Any]:
        """What ``GET /api/info`` says of them (a setting's ``integrators``)."""
        listed = self.listed()
        return {
            "meaning": self.meaning,
            "minimum": self.bounds[0] if self.bounds else None,
            "maximum": self.bounds[1] if self.bounds else None,
            "choices": list(self.choices) if self.choices is not None else None,
            "offered": list(listed) if listed is not None else None,
            "subpixel_grid": self.subpixel_grid,
            "modes": list(self.modes) if self.modes is not None else list(MODES),
        }


@dataclass(frozen=True)
class SettingSpec:
    """One render setting, declared once.

    type: ``integer``, ``number``, ``boolean`` or ``string``. bounds: (lo, hi), inclusive, of a
    number; choices: the values allowed (a string's, or an integer's).
    doc: the one line every description of it says (API schema, CLI help). label: the client's
    word for it. unit: what its numbers count. capability: read only by the methods whose
    ``Capabilities.settings`` name this (None: by every method). modes: read only in these
    modes (None: in every one). engine: a field of :class:`RenderSettings` (False: the service's
    alone — the JPEG quality of the encoder). stored_since_first: every session ever stored has
    it, so the response model requires it (a setting added later is filled with its default for
    older sessions). sheet: the client's settings sheet offers it. client: the client keeps it
    with its session's settings and carries it to a new session. by_integrator: what it accepts
    and means under each integrator, where that differs (its own bounds then span them all).
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
    by_integrator: Mapping[Integrator, IntegratorValues] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"setting {self.name}: type {self.type!r} is not one of {', '.join(TYPES)}")
        if self.type == "string" and not self.choices:
            raise ValueError(f"setting {self.name}: a string setting names its choices")
        if self.type in ("integer", "number") and self.choices is None and self.bounds is None:
            raise ValueError(f"setting {self.name}: a number has bounds or choices")
        if self.by_integrator is not None:
            if Integrator.WHITTED not in self.by_integrator or self.bounds is None:
                raise ValueError(f"setting {self.name}: values by integrator need Whitted's and bounds spanning all")
            lo, hi = self.bounds
            for name, v in self.by_integrator.items():
                ends = v.choices if v.choices is not None else v.bounds
                assert ends is not None  # IntegratorValues: bounds or choices
                if not all(lo <= x <= hi for x in ends):
                    raise ValueError(f"setting {self.name}: {name}'s values leave its bounds {lo} … {hi}")

    def values_under(self, integrator: str, mode: str) -> IntegratorValues | None:
        """What it accepts for a frame of ``integrator`` in ``mode`` (None: only its own bounds or choices)."""
        if self.by_integrator is None:
            return None
        v = self.by_integrator.get(Integrator(integrator)) if integrator in INTEGRATORS else None
        if v is None or (v.modes is not None and mode not in v.modes):
            return self.by_integrator[Integrator.WHITTED]
        return v

    def description(self) -> str:
        """Its doc, and what it means and accepts under each integrator: the API schema's description, the
        CLI's help and ``/api/info``'s ``doc``."""
        if self.by_integrator is None:
            return self.doc
        each = "; ".join(f"{i}: {v.meaning}, {v.accepts()}" for i, v in self.by_integrator.items())
        return f"{self.doc}. {each}"

    @property
    def python_type(self) -> builtins.type:  # `type` here is the field above
        return TYPES[self.type]

    def methods(self) -> list[str]:
        """The method names (``auto`` included, for the BIH it picks above the crossover) that read it."""
        if self.capability is None:
            return list(METHOD_NAMES)
        return [m for m in METHOD_NAMES if self.capability in capabilities(m, 1 << 30).settings]

    def check(self, v: Any, integrator: str = Integrator.WHITTED, mode: str = "color") -> None:
        """SceneError naming this setting when ``v`` is not one of its values (for a frame of
        ``integrator`` in ``mode``)."""
        self._check_own(v)
        under = self.values_under(integrator, mode)
        if under is None or self.by_integrator is None:
            return
        elsewhere = "; ".join(
            f"{x.hint} with integrator '{i}'" for i, x in self.by_integrator.items() if x is not under and x.hint
        )
        hint = f" ({elsewhere})" if elsewhere else ""
        if under.choices is not None and v not in under.choices:
            raise SceneError(self.name, f"must be one of {under.choices}, got {v!r}{hint}")
        if under.bounds is not None and not under.bounds[0] <= v <= under.bounds[1]:
            raise SceneError(self.name, f"must be in {under.bounds[0]} … {under.bounds[1]}, got {v}{hint}")

    def _check_own(self, v: Any) -> None:
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
            "doc": self.description(),
            "integrators": (
                {i.value: v.metadata() for i, v in self.by_integrator.items()} if self.by_integrator else None
            ),
            "methods": self.methods(),
            "modes": list(self.modes) if self.modes is not None else list(MODES),
            "engine": self.engine,
            "sheet": self.sheet,
            "client": self.client,
        }


# The modes whose frames are the path integrator's when it is chosen: the recursion mode draws
# Whitted's ray tree whatever the integrator, so Whitted's depth holds there.
_PATH_DEPTH_MODES = tuple(m for m in MODES if m != "recursion")

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
        "1 = primary rays only; each reflection/refraction +1",
        "Recursion depth",
        unit="levels",
        bounds=(1, MAX_PATH_DEPTH),
        modes=RAY_TREE_MODES,
        stored_since_first=True,
        sheet=True,
        client=True,
        by_integrator={
            Integrator.WHITTED: IntegratorValues("levels of the ray tree", bounds=(1, MAX_RECURSION_DEPTH)),
            Integrator.PATH: IntegratorValues(
                "segments of a path, Mitsuba's max_depth",
                bounds=(1, MAX_PATH_DEPTH),
                hint=f"up to {MAX_PATH_DEPTH}",
                modes=_PATH_DEPTH_MODES,
            ),
        },
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
        "samples of each pixel",
        "Quality (samples per pixel)",
        unit="samples",
        bounds=(1, MAX_PATH_SAMPLES),
        sheet=True,
        client=True,
        by_integrator={
            Integrator.WHITTED: IntegratorValues(
                "a k × k grid of sub-pixels (stratified supersampling: the frame is traced at k × its size, "
                f"at most {MAX_IMAGE_SIDE} a side, and box-filtered)",
                choices=SAMPLES_PER_PIXEL,
                subpixel_grid=True,
            ),
            Integrator.PATH: IntegratorValues(
                "paths per pixel",
                bounds=(1, MAX_PATH_SAMPLES),
                offered=PATH_SAMPLE_CHOICES,
                hint=f"any count 1 … {MAX_PATH_SAMPLES}",
            ),
        },
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
    integer choices (then a sub-pixel grid's traced size), numbers, booleans, strings."""
    if spec.type == "integer":
        by = spec.by_integrator.values() if spec.by_integrator else ()
        return 0 if spec.choices is None and not any(v.choices for v in by) else 1
    return {"number": 2, "boolean": 3, "string": 4}[spec.type]


@dataclass(frozen=True)
class RenderSettings:
    """How to render a scene: the engine settings of :data:`SETTINGS` (each one's doc there), each a
    field here with its type and default (:func:`check_declaration` holds the two to each other).

    Validated on construction (:class:`~renderer.geometry.scene.SceneError` names the first bad one), the
    strings whose choices are types made those types. max_prims / max_tree_depth: BIH build limits
    (depth counts the root as 1, as Table 4.2). max_recursion_depth: 1 = primary rays only (the thesis's
    Fig. 4.4), each reflected or transmitted ray is one more level (the path integrator: segments of a
    path). samples_per_pixel: Whitted's k × k sub-pixel grid (1, 4, 9 or 16) — the frame is traced at k
    times the resolution and box-filtered; depth, primid and normal come from the sub-pixel nearest the
    pixel centre, and the traced size must stay within ``limits.MAX_IMAGE_SIDE`` — or the path
    integrator's paths per pixel. min_weight: a reflected or transmitted ray whose path weight (the
    product of kr/kt along its path) is below ε is not traced. tile_size: the hierarchical ray engine's
    tile edge (images it does not divide are padded). specialize: compile the shader with only the
    features the scene uses and clamp the recursion depth to what its materials can use (exact: the
    image does not change). time: when an animated scene is posed (a static one ignores it). update:
    how a method that keeps its tree between frames follows the motion — ``rebuild``, ``refit`` or
    ``selective`` (rebuild the subtrees whose SAH cost grew by more than ``update_threshold``); see
    :mod:`renderer.scenes.tree_update`. The method must be able to draw the mode.
    """

    width: int = 640
    height: int = 1088
    method: str = "bih"
    mode: str = "color"
    first_hits: str = "auto"
    max_prims: int = 8
    max_tree_depth: int = limits.MAX_TREE_DEPTH
    max_recursion_depth: int = 5
    format: str = "png"
    samples_per_pixel: int = 1
    integrator: Integrator = Integrator.WHITTED
    tone_map: ToneMap = ToneMap.CLAMP
    exposure: float = 0.0
    denoise: Denoiser = Denoiser.OFF
    min_weight: float = 0.0
    specialize: bool = True
    tile_size: int = limits.DEFAULT_TILE_SIZE
    time: float = 0.0
    update: str = "rebuild"
    update_threshold: float = DEFAULT_THRESHOLD

    def __post_init__(self) -> None:
        plan = _validation(type(self))
        integrator = self.integrator  # a string until checked: another integrator's values name it
        for spec in plan.checks:
            v = getattr(self, spec.name)
            spec.check(v, integrator, self.mode)
            under = spec.values_under(integrator, self.mode)
            if under is not None and under.subpixel_grid:
                k = math.isqrt(v)
                if max(self.width, self.height) * k > MAX_IMAGE_SIDE:
                    raise SceneError(
                        spec.name,
                        f"{self.width}×{self.height} at {v} samples needs {self.width * k}×{self.height * k}, "
                        f"over the {MAX_IMAGE_SIDE} limit",
                    )
        for name, choices in plan.enums.items():  # checked above: one of its members
            object.__setattr__(self, name, choices(getattr(self, name)))
        self.check_method()

    def check_method(self, n_spheres: int = 0) -> None:
        """The method can draw the mode (``auto`` resolved for ``n_spheres``): no frame of
        these settings is refused later for a combination known now."""
        able = capabilities(self.method, n_spheres).modes
        if self.integrator not in capabilities(self.method, n_spheres).integrators:
            raise SceneError(
                "integrator",
                f"integrator '{self.integrator}' is not available with method "
                f"{self.method!r}; the methods that trace it: {', '.join(integrator_methods(self.integrator))}",
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
        """Sub-pixels per side: k of Whitted's k × k grid (the path integrator: 1, its samples are paths)."""
        under = setting("samples_per_pixel").values_under(self.integrator, self.mode)
        return math.isqrt(self.samples_per_pixel) if under is not None and under.subpixel_grid else 1

    @property
    def path_traced(self) -> bool:
        """Its colour is the path integrator's radiance (the other modes show the first hit or Whitted's tree)."""
        return self.integrator is Integrator.PATH and self.mode == "color"

    def with_(self, **kw: Any) -> RenderSettings:
        return replace(self, **kw)

    def to_json(self) -> dict[str, Any]:
        """Its fields as JSON values (the types' members as their strings)."""
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Its fields: the engine settings, in their order."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_json(cls, d: Any) -> RenderSettings:
        if not isinstance(d, dict):
            raise SceneError("settings", "expected an object")
        names = set(cls.names())
        unknown = set(d) - names
        if unknown:
            raise SceneError(sorted(unknown)[0], f"unknown setting (allowed: {', '.join(sorted(names))})")
        return cls(**d)


def _plain(v: Any) -> Any:
    return v.value if isinstance(v, enum.Enum) else v


@dataclass(frozen=True)
class _Validation:
    checks: tuple[SettingSpec, ...]  # the fields' declarations, in the order they are checked
    enums: dict[str, type[enum.StrEnum]]  # the fields whose type is a StrEnum: made members after the checks


_VALIDATIONS: dict[type[RenderSettings], _Validation] = {}


def _validation(cls: type[RenderSettings]) -> _Validation:
    """How ``cls`` is validated, from the table as it is when its first instance is made."""
    if cls not in _VALIDATIONS:
        _VALIDATIONS[cls] = _plan_validation(cls)
    return _VALIDATIONS[cls]


def _plan_validation(cls: type[RenderSettings]) -> _Validation:
    declared = {s.name: s for s in SETTINGS}
    own = [declared[f.name] for f in fields(cls)]
    hints = typing.get_type_hints(cls)
    enums = {f.name: t for f in fields(cls) if isinstance(t := hints[f.name], type) and issubclass(t, enum.StrEnum)}
    return _Validation(tuple(sorted(own, key=_check_order)), enums)


def check_declaration(cls: type[RenderSettings] = RenderSettings, specs: Iterable[SettingSpec] | None = None) -> None:
    """TypeError unless ``cls``'s fields are the engine settings of ``specs`` (default: :data:`SETTINGS`), in
    their order, each of the declared type (a string's StrEnum with the declared choices) and default."""
    engine = [s for s in (SETTINGS if specs is None else specs) if s.engine]
    hints = typing.get_type_hints(cls)
    got, want = [f.name for f in fields(cls)], [s.name for s in engine]
    if got != want:
        raise TypeError(f"RenderSettings' fields {got} are not the declared engine settings {want}")
    for f, spec in zip(fields(cls), engine, strict=True):
        t = hints[f.name]
        if not (isinstance(t, type) and issubclass(t, spec.python_type)) or (t is int) != (spec.python_type is int):
            raise TypeError(f"RenderSettings.{f.name} is {t}, declared {spec.type}")
        if isinstance(t, type) and issubclass(t, enum.StrEnum) and values(t) != spec.choices:
            raise TypeError(f"RenderSettings.{f.name}'s members {values(t)} are not the declared {spec.choices}")
        if f.default != spec.default or type(_plain(f.default)) is not type(spec.default):
            raise TypeError(f"RenderSettings.{f.name} defaults to {f.default!r}, declared {spec.default!r}")


check_declaration()  # at import: the class and the table cannot disagree in a running service


class SettingValues(TypedDict, total=False):
    """Settings by name, as JSON has them: a patch (some of them) or a session's settings (all of them,
    the service's own included). :func:`check_values_type` holds it to :data:`SETTINGS`."""

    width: int
    height: int
    method: str
    mode: str
    first_hits: str
    max_prims: int
    max_tree_depth: int
    max_recursion_depth: int
    format: str
    quality: int
    samples_per_pixel: int
    integrator: str
    tone_map: str
    exposure: float
    denoise: str
    refine_samples: int
    refine_time_ms: int
    refine_noise: float
    min_weight: float
    specialize: bool
    tile_size: int
    time: float
    update: str
    update_threshold: float


def check_values_type(specs: Iterable[SettingSpec] | None = None) -> None:
    """TypeError unless :class:`SettingValues` has a key of the declared type for every setting of ``specs``."""
    specs = tuple(SETTINGS if specs is None else specs)
    hints = typing.get_type_hints(SettingValues)
    want = {s.name: s.python_type for s in specs}
    if hints != want:
        raise TypeError(f"SettingValues' keys {hints} are not the declared settings {want}")


check_values_type()
