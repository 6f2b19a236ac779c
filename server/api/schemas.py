"""The API contract: typed request bodies, query parameters and responses (pydantic).

Field constraints here are what one field can say on its own (ranges, finite
numbers, enums); they become the OpenAPI schema, and every bound is the engine's
(:mod:`renderer.limits`). A query takes the same fields as the body it stands for:
the frame query *is* the settings patch (:class:`RenderParams`), and the stats and
device-data queries are made of the same field types. What needs several fields
(``camera.target`` ≠ ``camera.position``, ``up`` not parallel to the view,
material indices in range, the work caps of :mod:`server.config`) is checked by
the renderer's own validation and answered with the same 422 shape.

Units: coordinates and radii in world units; ``fov_y`` in degrees; image sizes
and ``dx``/``dy`` in pixels.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, get_args

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    TypeAdapter,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import InitErrorDetails, PydanticCustomError, PydanticKnownError

from renderer import settings as declared
from renderer.animation import MUSEUM_KINDS
from renderer.limits import (
    ASPECT_RANGE,
    MAX_ABSENT,
    MAX_ANGULAR_VELOCITY,
    MAX_COORDINATE,
    MAX_DEVICE_TEXTURE_SIZE,
    MAX_EMISSION,
    MAX_ENV_ROTATION_DEG,
    MAX_ENV_SCALE,
    MAX_IOR,
    MAX_LIFETIME,
    MAX_LIGHT_INTENSITY,
    MAX_LIGHTS,
    MAX_MATERIALS,
    MAX_MESH_VERTICES,
    MAX_MESHES,
    MAX_MOTION_SEED,
    MAX_MOTIONS,
    MAX_MUSEUM_MOVING,
    MAX_PERIOD,
    MAX_PLANES,
    MAX_SHAPES,
    MAX_SHININESS,
    MAX_SPEED,
    MAX_SPHERES,
    MAX_TRIANGLES,
    MAX_WAVELENGTH,
    REFINE_MS_RANGE,
    REFINE_NOISE_RANGE,
    REFINE_SAMPLES_RANGE,
)
from renderer.mesh_io import MODEL_FORMATS
from renderer.scenarios import CUBE_HALF, MAX_MESH_DETAIL, MESH_SCENES
from renderer.settings import SettingSpec, setting

from ..frames.device_data import DEFAULT_MAX_TEXTURE_SIZE, FEATURE_DEFINES

MuseumKind = Literal[MUSEUM_KINDS]
ModelFormat = Literal[MODEL_FORMATS]

# The API's own bound: a 32-bit placement seed (the renderer takes any non-negative one).
MAX_SEED = 2**32 - 1
# The incoherent motion's seed as JSON carries it: integers beyond 2^53 are not exact in JavaScript nor
# in JSON Schema validators that compare as doubles (2^63 − 1 + 192 passed as ≤ 2^63 − 1).
MAX_JSON_MOTION_SEED = min(MAX_MOTION_SEED, 2**53)
# A 422 lists at most this many errors, then one entry counting the rest: a body of 150,000 bad
# spheres is answered in a few kB, not 72 MB.
MAX_LISTED_ERRORS = 20
# The spheres of a scene are validated this many at a time, keeping only the first
# MAX_LISTED_ERRORS errors (the others are counted): the memory of a refusal stays that of one
# chunk's errors, and the GIL is given up between chunks (the event loop keeps answering).
SPHERE_CHUNK = 2048


def optional(tp: Any) -> Any:
    """``tp | None`` (left out: keep the current value) with ``tp``'s description on the
    field itself, where OpenAPI looks for a query parameter's description."""
    info = next((m for m in get_args(tp)[1:] if isinstance(m, FieldInfo)), None)
    return Annotated[tp | None, Field(description=info.description if info else None)]


class Strict(BaseModel):
    """A JSON body's model: unknown fields are errors; NaN and ±inf are rejected everywhere; types are
    strict — a number is a JSON number (``"1"`` and ``true`` are not), an integer an integral JSON number
    (an int field refuses ``1.5`` and ``true``), a boolean ``true``/``false``."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


def _integral(value: Any) -> Any:
    """An integer as JSON Schema has it (draft 6 on, what the OpenAPI schema says): any number without a
    fraction, so ``4.0`` is 4 — a strict int would refuse it — but ``true`` is none (in Python it equals 1,
    and an int Literal such as 1 | 4 | 9 | 16 would take it). Text is left to the field: a body's strict
    int refuses ``"4"``, a query's reads it."""
    if isinstance(value, bool):
        raise PydanticKnownError("int_type")
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


Integral = BeforeValidator(_integral)


Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Vec3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3, description="[x, y, z], world units")]
Unit = Annotated[float, Field(ge=0.0, le=1.0)]
Rgb = Annotated[list[Unit], Field(min_length=3, max_length=3, description="RGB, each 0 … 1")]
Intensity = Annotated[
    list[Annotated[float, Field(ge=0.0, le=MAX_LIGHT_INTENSITY)]],
    Field(min_length=3, max_length=3, description=f"RGB intensity, each 0 … {MAX_LIGHT_INTENSITY:g}"),
]
Radiance = Annotated[
    list[Annotated[float, Field(ge=0.0, le=MAX_EMISSION)]],
    Field(min_length=3, max_length=3, description=f"linear RGB radiance, each 0 … {MAX_EMISSION:g}"),
]
MaterialIndex = Annotated[int, Field(ge=0, lt=MAX_MATERIALS, description="index into materials"), Integral]


# ---- scene (the scene JSON of docs/FORMATS.md) --------------------------------------------
class CameraModel(Strict):
    """Pinhole camera. ``target`` must differ from ``position``; ``up`` must be non-zero
    and not parallel to the viewing direction."""

    position: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 100.0])
    target: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    up: Vec3 = Field(default_factory=lambda: [0.0, 1.0, 0.0])
    fov_y: float = Field(60.0, gt=0.0, lt=180.0, description="vertical field of view, degrees, in (0, 180)")


class LightModel(Strict):
    """Point light."""

    position: Vec3 = Field(default_factory=lambda: [0.0, 40.0, 0.0])
    color: Intensity = Field(default_factory=lambda: [1.0, 1.0, 1.0])


class MaterialModel(Strict):
    """Whitted/Phong material (thesis Table 4.1)."""

    color: Rgb = Field(default_factory=lambda: [0.9, 0.3, 0.3])
    ambient: Unit = 0.3
    diffuse: Unit = 0.3
    specular: Unit = 0.1
    shininess: float = Field(40.0, ge=0.0, le=MAX_SHININESS, description="Phong exponent")
    reflective: Unit = 0.3
    transmissive: Unit = 0.0
    ior: float = Field(1.0, gt=0.0, le=MAX_IOR, description="refraction index inside / outside")
    emission: Radiance = Field(
        default_factory=lambda: [0.0, 0.0, 0.0],
        description="radiance emitted on the side the normal faces (an area light)",
    )
    roughness: Unit = Field(
        0.0, description="GGX α of the path integrator's reflective and transmissive lobes (0: a mirror, smooth glass)"
    )


class EnvironmentModel(Strict):
    """What a ray that meets nothing sees: a constant radiance (black: none), or an equirectangular
    image (docs/FORMATS.md, "Environment"): ``"sky"``, or the reference of the image uploaded to
    the session (PUT /api/sessions/{id}/environment), times ``scale``, turned by ``rotation_deg``."""

    color: Radiance = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    image: str | None = Field(None, max_length=64, description="'sky', or an uploaded image's reference")
    scale: float | None = Field(None, ge=0.0, le=MAX_ENV_SCALE, description="the image's radiance factor (1)")
    rotation_deg: float | None = Field(
        None,
        ge=-MAX_ENV_ROTATION_DEG,
        le=MAX_ENV_ROTATION_DEG,
        description="the image turned about +y, degrees, right-handed (0)",
    )


class SphereModel(Strict):
    center: Vec3
    radius: float = Field(gt=0.0, le=MAX_COORDINATE, description="world units, > 0")
    material: MaterialIndex = 0


class PlaneModel(Strict):
    point: Vec3 = Field(default_factory=lambda: [0.0, -20.0, 0.0])
    normal: Vec3 = Field(default_factory=lambda: [0.0, 1.0, 0.0], description="non-zero; normalised by the server")
    material: MaterialIndex = 0


# A mesh's numbers are bounded after its transform is applied (by the renderer, which names
# the vertex); here they only have to be finite.
Row3 = Annotated[list[float], Field(min_length=3, max_length=3, description="[x, y, z]")]
VertexIndex = Annotated[int, Field(ge=0, lt=MAX_MESH_VERTICES, description="index into the mesh's vertices"), Integral]
Triangle = Annotated[
    list[VertexIndex], Field(min_length=3, max_length=3, description="[i, j, k], counter-clockwise seen from outside")
]
Row4 = Annotated[list[float], Field(min_length=4, max_length=4)]


class MeshModel(Strict):
    """A triangle mesh (docs/FORMATS.md, "Meshes"). Every vertex within ±MAX_COORDINATE after
    ``transform``; triangle indices < len(vertices); ``normals`` one per vertex, non-zero
    (smooth shading); zero-area triangles are kept and counted (never hit)."""

    vertices: list[Row3] = Field(max_length=MAX_MESH_VERTICES, description="world units (before the transform)")
    triangles: list[Triangle] = Field(max_length=MAX_TRIANGLES)
    material: MaterialIndex = 0
    normals: list[Row3] | None = Field(
        None, max_length=MAX_MESH_VERTICES, description="per-vertex shading normals (smooth); none: flat shading"
    )
    transform: Annotated[list[Row4], Field(min_length=4, max_length=4)] | None = Field(
        None, description="4 × 4 row-major affine (last row [0, 0, 0, 1]) applied to the vertices on input"
    )


# ---- analytic shapes (renderer.shapes; docs/FORMATS.md, "Analytic shapes") --------------------
# What needs two fields (inner_radius < radius, minor_radius < major_radius, a cone with one radius
# > 0) and a non-zero axis are the renderer's checks, answered with the same 422 shape.
Axis = Annotated[list[Coordinate], Field(min_length=3, max_length=3, description="non-zero; normalised on input")]
Length = Annotated[float, Field(gt=0.0, le=MAX_COORDINATE, description="world units, > 0")]
Radius0 = Annotated[float, Field(ge=0.0, le=MAX_COORDINATE, description="world units, >= 0")]


class CylinderModel(Strict):
    """The tube of ``radius`` about the segment from ``base`` to ``base + height·axis``; ``caps``:
    closed by its two end disks."""

    base: Vec3
    axis: Axis
    radius: Length
    height: Length
    caps: bool = True
    material: MaterialIndex = 0


class ConeModel(Strict):
    """A frustum: ``base_radius`` at ``base``, ``top_radius`` at ``base + height·axis`` (one of
    them may be 0, not both); ``caps`` as the cylinder's."""

    base: Vec3
    axis: Axis
    base_radius: Radius0
    top_radius: Radius0
    height: Length
    caps: bool = True
    material: MaterialIndex = 0


class DiskModel(Strict):
    """The disk of ``radius`` about ``center`` in the plane of ``normal`` (both sides are hit); an
    annulus when ``inner_radius`` > 0 (< radius)."""

    center: Vec3
    normal: Axis
    radius: Length
    inner_radius: Radius0 = Field(0.0, description="world units, 0 <= inner_radius < radius (0: a full disk)")
    material: MaterialIndex = 0


class TorusModel(Strict):
    """The tube of ``minor_radius`` about the circle of ``major_radius`` about ``center`` in the plane
    of ``axis`` (a ring torus: 0 < minor_radius < major_radius)."""

    center: Vec3
    axis: Axis
    major_radius: Length
    minor_radius: Annotated[
        float, Field(gt=0.0, le=MAX_COORDINATE, description="world units, 0 < minor_radius < major_radius")
    ]
    material: MaterialIndex = 0


SHAPES_DOC = f"at most {MAX_SHAPES} analytic shapes in all (cylinders, cones, disks, tori together)"


# ---- motion (renderer.animation) --------------------------------------------------
SphereIndex = Annotated[int, Field(ge=0, lt=MAX_SPHERES, description="id of the first sphere moved"), Integral]
SphereCount = Annotated[int, Field(ge=0, le=MAX_SPHERES, description="number of spheres moved"), Integral]
MeshIndex = Annotated[
    int, Field(ge=0, lt=MAX_MESHES, description="index of the mesh moved (instead of first, count)"), Integral
]


class MotionTarget(Strict):
    """What a motion moves: the spheres ``first … first+count−1`` (``over: "shapes"``: those analytic
    shapes, in their id order), or the mesh ``mesh``."""

    first: SphereIndex | None = None
    count: SphereCount | None = None
    mesh: MeshIndex | None = None
    over: Literal["spheres", "shapes"] | None = Field(
        None, description="what first and count count: spheres (the default) or analytic shapes"
    )

    @model_validator(mode="after")
    def _one_target(self) -> MotionTarget:
        if self.mesh is not None:
            if self.first is not None or self.count is not None or self.over is not None:
                raise ValueError("give either mesh or first and count, not both")
        elif self.first is None or self.count is None:
            raise ValueError("first and count are required (or mesh)")
        return self


class RigidMotion(MotionTarget):
    """Spheres ``first … first+count−1`` (or mesh ``mesh``) move as one rigid body: centre(t) =
    pivot + R(axis, angular_velocity·t)(c₀ − pivot) + amplitude·sin(2πt / period)."""

    kind: Literal["rigid"]
    pivot: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    axis: Vec3 = Field(default_factory=lambda: [0.0, 1.0, 0.0], description="non-zero")
    angular_velocity: float = Field(
        0.5, ge=-MAX_ANGULAR_VELOCITY, le=MAX_ANGULAR_VELOCITY, description="radians per second"
    )
    amplitude: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="oscillation, world units")
    period: float = Field(4.0, gt=0.0, le=MAX_PERIOD, description="seconds")


class DeformableMotion(MotionTarget):
    """Coherent local motion: a travelling wave moves each sphere (or each vertex of mesh
    ``mesh``) by at most ``amplitude`` per axis."""

    kind: Literal["deformable"]
    amplitude: float = Field(1.0, ge=0.0, le=MAX_COORDINATE, description="world units")
    wavelength: float = Field(10.0, gt=0.0, le=MAX_WAVELENGTH, description="world units")
    speed: float = Field(4.0, ge=-MAX_SPEED, le=MAX_SPEED, description="world units per second")


class IncoherentMotion(MotionTarget):
    """Every sphere flies alone inside [box_min, box_max] and respawns every ``lifetime`` seconds;
    for the last ``absent`` fraction of each lifetime it is gone (spheres appear and disappear).
    Spheres only: a mesh is refused."""

    kind: Literal["incoherent"]
    box_min: Vec3 = Field(default_factory=lambda: [-15.0, -15.0, -15.0])
    box_max: Vec3 = Field(default_factory=lambda: [15.0, 15.0, 15.0], description="> box_min on every axis")
    speed: float = Field(5.0, ge=0.0, le=MAX_SPEED, description="world units per second")
    lifetime: float = Field(2.0, gt=0.0, le=MAX_LIFETIME, description="seconds")
    absent: float = Field(0.0, ge=0.0, le=MAX_ABSENT, description="fraction of each lifetime a sphere is gone")
    seed: Annotated[int, Integral] = Field(0, ge=0, le=MAX_JSON_MOTION_SEED)


Motion = Annotated[RigidMotion | DeformableMotion | IncoherentMotion, Field(discriminator="kind")]


class SceneModel(Strict):
    """A whole scene (docs/FORMATS.md). Material indices must be < len(materials). ``motions`` (optional)
    animate sphere ranges that must not overlap, or meshes; the render setting ``time`` poses the
    scene. Primitive ids: spheres, then planes, then the triangles of each mesh, then the analytic shapes
    (cylinders, cones, disks, tori)."""

    camera: CameraModel = Field(default_factory=CameraModel)
    lights: list[LightModel] = Field(default_factory=list, max_length=MAX_LIGHTS)
    materials: list[MaterialModel] = Field(min_length=1, max_length=MAX_MATERIALS)
    spheres: list[SphereModel] = Field(default_factory=list, max_length=MAX_SPHERES)
    planes: list[PlaneModel] = Field(default_factory=list, max_length=MAX_PLANES)
    meshes: list[MeshModel] = Field(
        default_factory=list,
        max_length=MAX_MESHES,
        description=f"triangle meshes; at most {MAX_TRIANGLES} triangles in all",
    )
    cylinders: list[CylinderModel] = Field(default_factory=list, max_length=MAX_SHAPES, description=SHAPES_DOC)
    cones: list[ConeModel] = Field(default_factory=list, max_length=MAX_SHAPES, description=SHAPES_DOC)
    disks: list[DiskModel] = Field(default_factory=list, max_length=MAX_SHAPES, description=SHAPES_DOC)
    tori: list[TorusModel] = Field(default_factory=list, max_length=MAX_SHAPES, description=SHAPES_DOC)
    motions: list[Motion] = Field(default_factory=list, max_length=MAX_MOTIONS)
    environment: EnvironmentModel = Field(default_factory=EnvironmentModel)

    @field_validator("spheres", mode="wrap")
    @classmethod
    def _spheres_in_chunks(cls, value: Any, handler: Any) -> Any:
        """The spheres SPHERE_CHUNK at a time (see there): the first MAX_LISTED_ERRORS errors
        with their index, then one ``too_many_errors`` entry counting the others."""
        if not isinstance(value, list) or len(value) <= SPHERE_CHUNK:
            return handler(value)
        if len(value) > MAX_SPHERES:
            raise PydanticKnownError(
                "too_long", {"field_type": "List", "max_length": MAX_SPHERES, "actual_length": len(value)}
            )
        out: list[Any] = []
        listed: list[InitErrorDetails] = []
        count = 0
        for start in range(0, len(value), SPHERE_CHUNK):
            try:
                out.extend(handler(value[start : start + SPHERE_CHUNK]))
            except ValidationError as e:
                count += e.error_count()
                if len(listed) < MAX_LISTED_ERRORS:
                    for err in e.errors(include_url=False, include_context=False)[: MAX_LISTED_ERRORS - len(listed)]:
                        index, *rest = err["loc"]
                        listed.append(
                            InitErrorDetails(
                                type=PydanticCustomError(err["type"], "{msg}", {"msg": err["msg"]}),
                                loc=(int(index) + start, *rest),
                                input=err["input"],
                            )
                        )
        if not count:
            return out
        if count > len(listed):
            listed.append(
                InitErrorDetails(
                    type=PydanticCustomError(
                        "too_many_errors",
                        "{more} more errors in these spheres not listed ({total} in all)",
                        {"more": count - len(listed), "total": count},
                    ),
                    loc=(),
                    input=None,
                )
            )
        raise ValidationError.from_exception_data("spheres", listed)


# ---- render settings ----------------------------------------------------------
# Every model of the render settings is made from their declarations (renderer.settings.SETTINGS):
# a setting's type, bounds or choices, default and description are said there once.
def setting_type(spec: SettingSpec) -> Any:
    """The field type of one setting: its bounds or choices, its doc as the description; integers as
    JSON Schema has them (:data:`Integral`)."""
    described = Field(description=spec.doc)
    if spec.choices is not None:
        values = Literal[spec.choices]  # type: ignore[name-defined]  # a Literal of the declared choices, made at run time
        return Annotated[values, Integral, described] if spec.type == "integer" else Annotated[values, described]
    if spec.type == "boolean":
        return Annotated[bool, described]
    assert spec.bounds is not None, f"setting {spec.name}: a number has bounds"
    lo, hi = spec.bounds
    if spec.type == "integer":
        return Annotated[int, Field(ge=lo, le=hi, description=spec.doc), Integral]
    return Annotated[float, Field(ge=lo, le=hi, allow_inf_nan=False, description=spec.doc)]


class RenderParamsBase(BaseModel):
    """What :func:`build_render_params` adds the settings' fields to."""

    model_config = ConfigDict(allow_inf_nan=False)
    setting_names: ClassVar[tuple[str, ...]] = ()

    def given(self) -> dict[str, Any]:
        """The settings named, as a patch of a session's settings."""
        return {k: v for k in self.setting_names if (v := getattr(self, k)) is not None}


def build_render_params(specs: Iterable[SettingSpec] | None = None) -> type[RenderParamsBase]:
    """Every setting of ``specs`` (default: renderer.settings.SETTINGS as it is now), optional: what a request
    names (body or query)."""
    specs = tuple(declared.SETTINGS if specs is None else specs)
    model = create_model(
        "RenderParams",
        __base__=RenderParamsBase,
        __module__=__name__,
        **{s.name: (optional(setting_type(s)), None) for s in specs},
    )  # type: ignore[call-overload]
    model.__doc__ = """Render settings a request names; the ones left out (or null) keep their value.

    Declared once for the body (:class:`SettingsPatch`) and the query of a frame
    (:class:`FrameQuery`)."""
    model.setting_names = tuple(s.name for s in specs)
    return model


def build_full_settings(specs: Iterable[SettingSpec] | None = None) -> type[BaseModel]:
    """Every setting of ``specs`` (default: renderer.settings.SETTINGS as it is now) as a session has it; those
    added after the first sessions were stored take their default when a stored session lacks them."""
    specs = tuple(declared.SETTINGS if specs is None else specs)
    return create_model(
        "FullSettings",
        __module__=__name__,
        __doc__=FULL_SETTINGS_DOC,  # type: ignore[call-overload]
        **{s.name: (s.python_type, ... if s.stored_since_first else s.default) for s in specs},
    )


FULL_SETTINGS_DOC = "All render settings of a session (the render-settings JSON of docs/FORMATS.md plus ``quality``)."
SETTING_TYPES: dict[str, Any] = {s.name: setting_type(s) for s in declared.SETTINGS}
MaxPrims, TreeDepth, RecursionDepth, Time, Method, Mode = (
    SETTING_TYPES[k] for k in ("max_prims", "max_tree_depth", "max_recursion_depth", "time", "method", "mode")
)
MethodName = get_args(Method)[0]
ModeName = get_args(Mode)[0]

if TYPE_CHECKING:
    RenderParams = RenderParamsBase
else:
    RenderParams = build_render_params()


class SettingsPatch(RenderParams):
    """Some render settings; the ones left out (or null) keep their value. A JSON body: strict
    types as :class:`Strict` (the query, :class:`FrameQuery`, reads the same fields from text)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


# ---- query parameters ---------------------------------------------------------------
class QueryModel(BaseModel):
    """Query parameters: unknown ones are ignored (links may carry the client's own); no NaN or ±inf.
    ``null`` for an optional parameter — what the schema allows there, and what a generic client sends
    for it — is the parameter left out."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _null_is_left_out(cls, data: Any) -> Any:
        if isinstance(data, dict) and "null" in data.values():
            optional = {k for k, f in cls.model_fields.items() if f.default is None and not f.is_required()}
            return {k: v for k, v in data.items() if not (v == "null" and k in optional)}
        return data


_INT = TypeAdapter(int)


class FrameQuery(RenderParams, QueryModel):
    """A frame's render settings in the query; missing ones come from the session's."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)
    progressive: bool = Field(
        False,
        description="answer multipart/mixed: first the preview (the pixel centres "
        "of a supersampled frame) as soon as it exists, then the final "
        "image (docs/API.md, 'Progressive frames')",
    )

    @model_validator(mode="before")
    @classmethod
    def _literal_ints_from_text(cls, data: Any) -> Any:
        """A query's values are text. pydantic reads "4" as an int field's 4 but not as an int
        Literal's, so samples_per_pixel is read as an integer first (and then checked as the set)."""
        if isinstance(data, dict) and isinstance(data.get("samples_per_pixel"), str):
            try:
                return {**data, "samples_per_pixel": _INT.validate_python(data["samples_per_pixel"])}
            except ValidationError:
                pass  # not a number: the Literal's error names the allowed values
        return data


class SessionFrameQuery(FrameQuery):
    """A session frame's query: ``accumulate`` adds the frame's samples to the session's accumulation."""

    accumulate: bool = Field(
        False,
        description="colour (the path integrator's samples, or a jittered slice of Whitted's sub-pixel grid): "
        "go on from the samples the session's accumulation holds "
        "for this same image (scene, camera, settings, time, size) and answer their mean with this "
        "frame's samples added (X-Samples: how many); yields to interactive frames (docs/API.md, "
        "'Accumulation')",
    )
    refine: bool = Field(
        False,
        description="answer the session's refinement stream as multipart/mixed: accumulation frames of the "
        "resting view until refine_samples or refine_time_ms (X-Refine: where the stream stands; docs/API.md, "
        "'Refinement')",
    )


class FrameMessage(Strict):
    """A WebSocket message that asks for a frame without a gesture (its settings are its ``frame``);
    read as a JSON body is (:class:`Strict`: an unknown field is a 422 naming it)."""

    type: Literal["frame"]
    accumulate: StrictBool = Field(False, description="as the session frame's accumulate=1")


class RefineMessage(Strict):
    """A WebSocket message that asks for the session's refinement stream (docs/API.md, "Refinement");
    its settings are its ``frame``, the targets default to the session's refine_samples, refine_time_ms and
    refine_noise. Read as a JSON body is (:class:`Strict`: an unknown field is a 422 naming it)."""

    type: Literal["refine"]
    target_samples: StrictInt | None = Field(
        None,
        ge=REFINE_SAMPLES_RANGE[0],
        le=REFINE_SAMPLES_RANGE[1],
        description="samples per pixel to refine to (default: refine_samples)",
    )
    target_ms: StrictInt | None = Field(
        None,
        ge=REFINE_MS_RANGE[0],
        le=REFINE_MS_RANGE[1],
        description="longest refinement, wall-clock ms (default: refine_time_ms; 0: none; its GL time at most "
        "POCKETRAY_MAX_REFINE_MS)",
    )
    target_noise: float | None = Field(
        None,
        ge=REFINE_NOISE_RANGE[0],
        le=REFINE_NOISE_RANGE[1],
        allow_inf_nan=False,
        description="estimated relative noise to refine to, 0: none (default: refine_noise)",
    )


class GestureQuery(FrameQuery):
    """A gesture's query: ``frame`` asks for the new frame, rendered with the other parameters."""

    frame: bool = Field(False, description="answer with the new frame (image) instead of JSON")


class StatsQuery(QueryModel):
    """The build whose statistics are asked for; missing parameters: the session's."""

    method: optional(Method) = None
    max_prims: optional(MaxPrims) = None
    max_tree_depth: optional(TreeDepth) = None
    time: optional(Time) = None

    def given(self) -> dict[str, Any]:
        return {k: v for k, v in self.model_dump().items() if v is not None}


# The render settings a device-data query may name: those that choose the data and the shader
# variant, and what the device's display of a path-traced frame reads (samples, tone map, exposure;
# denoise: on, the variant writes the guides and the device filters its mean).
DEVICE_SETTINGS = (
    "method",
    "mode",
    "max_prims",
    "max_tree_depth",
    "max_recursion_depth",
    "time",
    "integrator",
    "tone_map",
    "exposure",
    "samples_per_pixel",
    "denoise",
)


class DeviceDataQuery(QueryModel):
    """What the device-data is packed for; the settings left out are the session's."""

    method: MethodName | None = Field(None, description="default: the session's")
    mode: ModeName | None = Field(None, description="names the shader variant; default: the session's")
    max_prims: optional(MaxPrims) = None
    max_tree_depth: optional(TreeDepth) = None
    max_recursion_depth: optional(RecursionDepth) = None
    time: optional(Time) = None
    integrator: optional(SETTING_TYPES["integrator"]) = None
    tone_map: optional(SETTING_TYPES["tone_map"]) = None
    exposure: optional(SETTING_TYPES["exposure"]) = None
    samples_per_pixel: optional(SETTING_TYPES["samples_per_pixel"]) = None
    denoise: optional(SETTING_TYPES["denoise"]) = None
    max_texture_size: int = Field(
        DEFAULT_MAX_TEXTURE_SIZE, ge=1, le=MAX_DEVICE_TEXTURE_SIZE, description="the device's MAX_TEXTURE_SIZE"
    )
    float_textures: bool = Field(True, description="the device renders to RGBA32F (WebGL2: EXT_color_buffer_float)")

    def given(self) -> dict[str, Any]:
        """The render settings named (not the device's own parameters)."""
        return {k: v for k in DEVICE_SETTINGS if (v := getattr(self, k)) is not None}


# What server.api.routes.device.parse_features reads: names from FEATURE_DEFINES, commas, whitespace.
_FEATURE = "(?:" + "|".join(FEATURE_DEFINES) + ")"
_FEATURES_PATTERN = rf"^\s*(?:{_FEATURE}\s*)?(?:,\s*(?:{_FEATURE}\s*)?)*$"


class ShaderQuery(QueryModel):
    """The shader variant asked for."""

    method: Method = "bih"
    mode: Mode = "color"
    max_recursion_depth: RecursionDepth = setting("max_recursion_depth").default
    features: str | None = Field(
        None, max_length=200, pattern=_FEATURES_PATTERN, description="comma-separated: " + ", ".join(FEATURE_DEFINES)
    )
    stage: str = Field("fragment", pattern="^(fragment|vertex)$", description="fragment (the tracer) or vertex")


if TYPE_CHECKING:
    FullSettings = BaseModel
else:
    FullSettings = build_full_settings()


class SettingsOut(FullSettings):
    version: int


# ---- sessions -------------------------------------------------------------------
class MuseumRecipe(Strict):
    """Reiter's BART-Museum analogue (renderer.animation.museum): ``n`` moving spheres in a
    static room of 576 spheres and the floor."""

    n: Annotated[int, Integral] = Field(ge=0, le=MAX_MUSEUM_MOVING, description="moving spheres")
    kind: MuseumKind = Field("deformable", description="rigid, deformable, incoherent or mixed (a third each)")
    seed: Annotated[int, Integral] = Field(0, ge=0, le=MAX_SEED)
    absent: float = Field(0.2, ge=0.0, le=MAX_ABSENT, description="incoherent spheres: fraction of a lifetime gone")


class MeshSceneRecipe(Strict):
    """A demo scene (renderer.scenarios.mesh_scene): ``spheres`` (scenario 1's 512 spheres in
    colour under the sky: the default scene), ``teapot`` (the closed Utah teapot on the
    floor), ``mixed`` (27 spheres, a glass icosphere and a torus), ``room`` (a box room seen from
    inside with a teapot, an icosphere and four spheres), ``cornell`` (a Cornell box lit by an
    emitting ceiling panel, with a mirror and a glass sphere and a teapot: for ``integrator=path``),
    ``table`` (analytic shapes only: a table with a torus, a can, a glass lens and a lamp whose
    shade holds an emitting disk; Whitted or ``integrator=path``)."""

    kind: Literal[MESH_SCENES] = Field("teapot", description=", ".join(MESH_SCENES))
    detail: Annotated[int, Integral] = Field(
        2,
        ge=0,
        le=MAX_MESH_DETAIL,
        description="tessellation: teapot 2 + 2·detail segments per patch, "
        "icosphere subdivisions, torus 12 (detail + 1) segments",
    )
    smooth: bool = Field(True, description="vertex normals (smooth shading); false: flat")
    sky: bool = Field(False, description="under the procedural daylight sky (environment 'sky')")


class SessionCreate(Strict):
    """Either a thesis scenario (``scenario`` and ``n``; ``seed``, ``radius`` optional),
    an animated ``museum``, a ``mesh_scene`` or a full ``scene``; optionally the session's
    first render settings."""

    scenario: Annotated[Literal[1, 2, 3], Integral] | None = Field(None, description="thesis scenario 1, 2 or 3")
    # The bounds inside the Annotated: on an optional field pydantic would write them to the schema
    # as "ge"/"le", which JSON Schema does not know (the schema said nothing of n's range).
    n: Annotated[int, Field(ge=0, le=MAX_SPHERES), Integral] | None = Field(None, description="number of spheres")
    seed: Annotated[int, Field(ge=0, le=MAX_SEED), Integral] | None = Field(
        None, description="random placement seed (default 0)"
    )
    radius: float | None = Field(None, gt=0.0, le=CUBE_HALF, description="sphere radius, world units (default 1)")
    sky: bool | None = Field(None, description="a scenario under the procedural daylight sky (default false)")
    museum: MuseumRecipe | None = None
    mesh_scene: MeshSceneRecipe | None = None
    scene: SceneModel | None = None
    settings: SettingsPatch | None = Field(
        None, description="render settings; a demo scene's recommended ones (GET /api/info's scenes) lie under them"
    )
    aspect: float | None = Field(
        None,
        ge=ASPECT_RANGE[0],
        le=ASPECT_RANGE[1],
        description=f"the client's canvas width / height ({ASPECT_RANGE[0]:g} … {ASPECT_RANGE[1]:g}): a recipe's "
        "camera is framed for it (its content's bounds inside the frame); a reset gesture frames again for it",
    )


class SceneInfo(BaseModel):
    n_spheres: int = Field(description="spheres of the scene at rest (an animation may hide some)")
    n_planes: int
    scenario: int | None = None
    n: int | None = None
    seed: int | None = None
    radius: float | None = None
    sky: bool = Field(False, description="the scenario is under the procedural sky")
    animated: bool = False
    n_moving: int = Field(0, description="spheres some motion moves")
    museum: MuseumRecipe | None = None
    mesh_scene: MeshSceneRecipe | None = Field(
        None, description="the mesh scene recipe it was made from (until a model is added or the scene replaced)"
    )
    n_meshes: int = 0
    n_triangles: int = Field(0, description="triangles of all meshes (ids after the planes)")
    n_degenerate_triangles: int = Field(0, description="zero-area triangles: kept, never hit")
    n_moving_meshes: int = Field(0, description="meshes some motion moves")
    n_shapes: int = Field(0, description="analytic shapes: cylinders, cones, disks, tori (ids after the triangles)")
    n_moving_shapes: int = Field(0, description="analytic shapes some motion moves")


class SessionOut(BaseModel):
    id: str = Field(description="session token (192 random bits, URL-safe)")
    version: int = Field(description="bumped by every change")
    settings: FullSettings
    scene_info: SceneInfo
    camera: CameraModel


class VersionOut(BaseModel):
    version: int


class EnvironmentOut(BaseModel):
    version: int
    image: str = Field(description="the uploaded image's reference (scene JSON's environment.image)")
    width: int
    height: int


class EnvironmentUploadQuery(QueryModel):
    """How an uploaded environment image (the request body, bytes) lights the scene."""

    format: Literal["hdr", "exr"] = Field(description="the file's format: hdr (Radiance RGBE) or exr (OpenEXR)")
    scale: float = Field(1.0, ge=0.0, le=MAX_ENV_SCALE, description="radiance factor")
    rotation_deg: float = Field(
        0.0, ge=-MAX_ENV_ROTATION_DEG, le=MAX_ENV_ROTATION_DEG, description="turned about +y, degrees, right-handed"
    )


class CameraOut(BaseModel):
    version: int
    camera: CameraModel


# ---- gestures (the Controller) ------------------------------------------------------
class PanGesture(Strict):
    """One finger dragged by (dx, dy) screen pixels, right/down positive: the scene
    follows the finger at the target's distance."""

    type: Literal["pan"]
    dx: float = Field(ge=-1e6, le=1e6, description="pixels, right positive")
    dy: float = Field(ge=-1e6, le=1e6, description="pixels, down positive")
    viewport_height: float | None = Field(
        None,
        gt=0.0,
        le=1e5,
        description="height in the same pixels as dx/dy of the view showing the frame; default: the frame's height",
    )


class PinchGesture(Strict):
    """Two fingers: ``scale`` = new distance / old distance. > 1 (spread) moves the camera
    forward to distance / scale, < 1 back; it never reaches the target."""

    type: Literal["pinch"]
    scale: float = Field(ge=1e-3, le=1e3, description="finger distance ratio")


MAX_ORBIT_DEG = 360.0


class OrbitGesture(Strict):
    """Turn the camera about its target (the distance stays): ``yaw`` degrees about the
    camera's ``up`` vector, ``pitch`` degrees about its ``right`` vector (right-handed: yaw > 0
    moves the camera to its right, pitch > 0 moves it down). Pitch is clamped so that the
    view never passes over the up vector."""

    type: Literal["orbit"]
    yaw: float = Field(0.0, ge=-MAX_ORBIT_DEG, le=MAX_ORBIT_DEG, description="degrees about up, −360 … 360")
    pitch: float = Field(
        0.0,
        ge=-MAX_ORBIT_DEG,
        le=MAX_ORBIT_DEG,
        description="degrees about right, −360 … 360 (clamped short of the poles)",
    )


class ResetGesture(Strict):
    """Back to the camera the scene was created (or last replaced) with; for a session made with
    an ``aspect`` (or a reset that names one), that camera fitted to the whole scene (added models
    too) for the aspect."""

    type: Literal["reset"]
    aspect: float | None = Field(
        None,
        ge=ASPECT_RANGE[0],
        le=ASPECT_RANGE[1],
        description=f"the canvas's width / height ({ASPECT_RANGE[0]:g} … {ASPECT_RANGE[1]:g}); default: the session's",
    )


Gesture = Annotated[PanGesture | PinchGesture | OrbitGesture | ResetGesture, Field(discriminator="type")]


# ---- stateless render ------------------------------------------------------------------
class MeshUploadQuery(QueryModel):
    """How an uploaded model file (the request body, bytes) becomes a mesh."""

    format: ModelFormat = Field(description="the file's format: " + ", ".join(MODEL_FORMATS))
    material: MaterialIndex | None = Field(
        None, description="index into the scene's materials (default: a neutral clay of its own, added to them)"
    )
    smooth: bool | None = Field(
        None,
        description="shading: the file's normals (default), true: smooth (the file's "
        "or area-weighted normals), false: flat",
    )
    size: float | None = Field(
        None,
        gt=0.0,
        le=2 * CUBE_HALF,
        description="scale the model so that its longest side is this many world units, "
        "centred on the y axis, standing on the floor y = −20 (default: as is)",
    )


class MeshAdded(BaseModel):
    version: int
    scene_info: SceneInfo
    mesh: int = Field(description="index of the new mesh in the scene's meshes")
    first_id: int = Field(description="primitive id of its first triangle")
    placed: tuple[float, float, float] | None = Field(
        None, description="where the model's box's bottom centre went (world units): free floor beside the scene"
    )
    camera: CameraModel | None = Field(None, description="the session's camera, framed to show the model and the scene")
    notice: str | None = Field(None, description="a sentence for the user: where the model went")


class RenderRequest(Strict):
    scene: SceneModel
    settings: SettingsPatch = Field(default_factory=SettingsPatch)


# ---- service ----------------------------------------------------------------------------
class ErrorOut(BaseModel):
    detail: str


class HealthOut(BaseModel):
    status: Literal["ok"]


class ReadyOut(BaseModel):
    ready: bool
    gl_renderer: str | None = None
    gl_version: str | None = None
    detail: str | None = None


class LimitsOut(BaseModel):
    max_work: int
    max_frame_cost: float = Field(description="ms of estimated GL time a frame may cost (POCKETRAY_MAX_FRAME_COST)")
    slice_ms: float = Field(description="ms of estimated GL time of one slice (POCKETRAY_SLICE_MS)")
    max_spheres: int
    max_triangles: int = Field(MAX_TRIANGLES, description="triangles of one scene (POCKETRAY_MAX_TRIANGLES)")
    max_body_bytes: int
    max_image_side: int
    queue_size: int
    session_ttl_s: float


class PathInfoOut(BaseModel):
    """What a client needs to offer the path integrator's settings and count a path frame's work as the
    service does (renderer/cost.py, ``request_work``)."""

    samples_per_pixel: list[int] = Field(description="the sample counts a settings sheet offers (any 1 … max_samples)")
    max_samples: int = Field(description="most samples per pixel of one frame")
    max_depth: int = Field(description="most segments of a path (max_recursion_depth with integrator 'path')")
    segments_limit: float = Field(description="a sample's expected segments at depth D: L − (L − 1) · R^(D − 1), L")
    segments_rate: float = Field(description="… R; never more than 2·D − 1 (one bounce and one shadow ray a vertex)")


class MethodSettingsOut(BaseModel):
    """Which settings a method reads, so that a client shows only those (server.api.routes.meta.method_settings)."""

    label: str = Field("", description="the client's word for it (the method's declaration)")
    settings: list[str] = Field(
        description="settings its build or passes read: max_prims, max_tree_depth, tile_size, update"
    )
    modes: list[str]
    update_schemes: list[str]
    device: bool = Field(description="a browser can trace it (device mode)")
    tests_every_sphere: bool = Field(False, description="no hierarchy: POCKETRAY_MAX_BRUTEFORCE_WORK applies")
    primitives: list[str] = Field(
        default_factory=lambda: ["spheres", "planes", "triangles"],
        description="the kinds of primitive it traces (a scene with another is a 422)",
    )
    meshes_on_gpu: bool = Field(
        False,
        description="its GPU layout holds triangles: it traces frames of scenes "
        "with meshes (every one-pass method and auto); a method without "
        "it would answer those with 422 'meshes'",
    )
    auto: bool = Field(False, description="resolved per scene: brute force below the crossover, else bih")


class SettingInfoOut(BaseModel):
    """One render setting as it is declared (renderer.settings.SETTINGS): what a client builds its settings
    form from."""

    name: str
    type: Literal["integer", "number", "boolean", "string"]
    default: Any
    minimum: int | float | None = Field(None, description="smallest value (integer, number)")
    maximum: int | float | None = Field(None, description="largest value (integer, number)")
    choices: list[Any] | None = Field(
        None, description="the values allowed (string, and an integer such as samples_per_pixel)"
    )
    unit: str = ""
    label: str = Field(description="the client's word for it")
    doc: str = Field(description="one line: what it does")
    methods: list[str] = Field(description="the methods that read it")
    modes: list[str] = Field(description="the modes that read it")
    engine: bool = Field(True, description="the renderer reads it (false: the service's own, e.g. JPEG quality)")
    sheet: bool = Field(False, description="the client's settings sheet offers it")
    client: bool = Field(
        False, description="the client keeps it with the session's settings and carries it to a new session"
    )


class ModeColorOut(BaseModel):
    rgb: tuple[float, float, float] = Field(description="red, green, blue in [0, 1]")
    name: str


class DemoSceneOut(BaseModel):
    value: int | str = Field(description="the client's scenario value: 1, 2, 3, 'sky:2', 'museum', 'mesh:KIND'")
    label: str
    recipe: dict[str, Any] = Field(description="the body of POST /api/sessions that makes it")
    settings: dict[str, Any] = Field(
        description="recommended render settings (names of 'settings'); "
        "POST /api/sessions applies them under its body's"
    )
    default: bool = Field(False, description="the scene POST /api/sessions makes from an empty body")


class InfoOut(BaseModel):
    methods: list[str]
    modes: list[str]
    formats: list[str]
    limits: LimitsOut
    state_backend: str
    update_schemes: list[str] = Field(default_factory=list, description="values of the setting 'update'")
    museum_kinds: list[str] = Field(default_factory=list, description="motions of POST /api/sessions {museum}")
    profiles: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="render profiles measured by the Pareto experiment: 'still' (the "
        "session default) and 'interactive' (frames during a gesture)",
    )
    samples_per_pixel: list[int] = Field(
        default_factory=list,
        description="values of samples_per_pixel; a frame's longest side × √samples must stay ≤ limits.max_image_side",
    )
    max_recursion_depth: int | None = Field(None, description="most levels of the Whitted tracer's ray tree")
    path: PathInfoOut | None = Field(
        None, description="the path integrator's sample counts, depth and work per sample (limits.max_work counts it)"
    )
    render_timeout_s: float | None = Field(
        None, description="longest a frame may take; a frame that alone takes longer is answered with 422 (scene.n)"
    )
    museum_room_spheres: int | None = Field(
        None,
        description="static spheres of the museum's room; they count against limits.max_spheres with its n moving ones",
    )
    method_settings: dict[str, MethodSettingsOut] = Field(
        default_factory=dict, description="per method: the settings that apply"
    )
    settings: list[SettingInfoOut] = Field(
        default_factory=list,
        description="every render setting, declared once: type, bounds or "
        "choices, default, unit, label, doc, who reads it",
    )
    scenes: list[DemoSceneOut] = Field(
        default_factory=list, description="the demo scenes, in picker order (renderer/scenarios.py DEMO_SCENES)"
    )
    recursion_colors: list[ModeColorOut] = Field(
        default_factory=list,
        description="mode 'recursion': the colour of each ray level, index = level (0: the primary ray missed)",
    )
    heat_scale: dict[str, float] = Field(
        default_factory=dict,
        description="mode 'heat': what each event adds to its channel (red "
        "'tests', green 'gaps', blue 'nodes'), clamped at 1",
    )


class StatsOut(BaseModel):
    """Statistics of the last build; the fields beyond ``method`` depend on the method
    (bih: renderer.accel.bih.BIHStats — primitives, inner_nodes, leaves, depth_max, …)."""

    model_config = ConfigDict(extra="allow")
    method: str
