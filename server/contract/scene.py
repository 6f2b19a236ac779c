"""The scene JSON of docs/FORMATS.md as request models: camera, lights, materials, spheres, planes,
meshes, analytic shapes, motions and the environment (:class:`SceneModel`).

Field constraints are what one field can say on its own; what needs several fields is the renderer's
validation (:mod:`renderer.geometry.scene`), answered with the same 422 shape. Units: coordinates and radii in
world units; ``fov_y`` in degrees."""

from __future__ import annotations

from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING, Annotated, Any, Literal, get_args

from pydantic import (
    Discriminator,
    Field,
    Tag,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError, PydanticKnownError

from renderer.geometry.scene import Material
from renderer.limits import (
    MAX_ABSENT,
    MAX_ANGULAR_VELOCITY,
    MAX_COORDINATE,
    MAX_EMISSION,
    MAX_ENV_ROTATION_DEG,
    MAX_ENV_SCALE,
    MAX_LIFETIME,
    MAX_LIGHT_INTENSITY,
    MAX_LIGHTS,
    MAX_MATERIALS,
    MAX_MESH_VERTICES,
    MAX_MESHES,
    MAX_MOTIONS,
    MAX_PERIOD,
    MAX_PLANES,
    MAX_SHAPES,
    MAX_SPEED,
    MAX_SPHERES,
    MAX_TEXTURE_NAME,
    MAX_TEXTURES,
    MAX_TRIANGLES,
    MAX_WAVELENGTH,
)
from renderer.materials import material_params
from renderer.materials.pbr import PbrMaterial
from renderer.materials.texture import FILTERS, WRAPS

from .fields import MAX_JSON_MOTION_SEED, MAX_LISTED_ERRORS, SPHERE_CHUNK, Integral, Strict

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


def material_model(kind: type = Material) -> type[Strict]:
    """The API's model of material kind ``kind``, made from its declaration (renderer/materials): each
    parameter's name, default, range and doc; an RGB triple a list of three numbers bounded alike; a
    whole number (a texture index) an integer; a choice one of its values. A kind other than the Phong
    one has a required ``kind`` naming it (the Phong kind's JSON has none)."""
    fields: dict[str, Any] = {}
    tag = getattr(kind, "KIND", "phong")
    if tag != "phong":
        fields["kind"] = (Literal[tag], Field(description=f"the material kind: {tag!r}"))
    defaults: dict[str, Any] = {f.name: f.default for f in dataclass_fields(kind)}
    for name, p in material_params(kind).items():
        bound = {"gt" if p.lo_open else "ge": p.lo, "le": p.hi}
        unit = f"; in {p.unit}" if p.unit else ""
        if p.choices:
            fields[name] = (Literal[p.choices], Field(defaults[name], description=p.doc))
        elif p.integer:
            whole = Annotated[int, Field(**bound), Integral]  # 1.0 is an integer to JSON Schema, as here
            fields[name] = (whole, Field(int(defaults[name]), description=p.doc + unit))
        elif isinstance(p.default, tuple):
            item = Annotated[float, Field(**bound)]
            vector = Annotated[list[item], Field(min_length=p.size, max_length=p.size)]
            default = Field(default_factory=lambda d=p.default: list(d), description=p.doc + unit)
            fields[name] = (vector, default)
        else:
            fields[name] = (float, Field(p.default, description=p.doc + unit, **bound))  # type: ignore[call-overload]
    doc = (kind.__doc__ or "").strip().split("\n")[0]
    return create_model(f"{kind.__name__}Model", __base__=Strict, __module__=__name__, __doc__=doc, **fields)


def _material_kind(value: Any) -> str | None:
    """The tag of a material's JSON (or model): its ``"kind"``, the Phong kind's where it has none."""
    kind = value.get("kind", "phong") if isinstance(value, dict) else getattr(value, "kind", "phong")
    return kind if isinstance(kind, str) else None


if TYPE_CHECKING:
    MaterialModel = Strict
    PbrMaterialModel = Strict
    AnyMaterialModel = Strict
else:
    MaterialModel = material_model()
    PbrMaterialModel = material_model(PbrMaterial)
    # The scene's materials: a union of the kinds told apart by "kind" (absent: the Phong kind), so a
    # refused field is named within its own kind's model (materials.0.pbr.metallic).
    AnyMaterialModel = Annotated[
        Annotated[MaterialModel, Tag("phong")] | Annotated[PbrMaterialModel, Tag("pbr")],
        Discriminator(
            _material_kind,
            custom_error_type="material_kind",
            custom_error_message="'kind' must be 'phong' (or absent) or 'pbr'",
        ),
    ]


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
Row2 = Annotated[list[Coordinate], Field(min_length=2, max_length=2)]
Rgba = Annotated[list[Unit], Field(min_length=4, max_length=4, description="linear RGBA, each 0 … 1")]
Tangent = Annotated[
    list[Coordinate], Field(min_length=4, max_length=4, description="[x, y, z, w]: +U's direction, w = ±1 handedness")
]


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
    uvs: list[Row2] | None = Field(
        None, max_length=MAX_MESH_VERTICES, description="texture coordinates, set 0, per vertex (U right, V down)"
    )
    uvs1: list[Row2] | None = Field(
        None, max_length=MAX_MESH_VERTICES, description="texture coordinates, set 1, per vertex"
    )
    colors: list[Rgba] | None = Field(
        None, max_length=MAX_MESH_VERTICES, description="per-vertex colours multiplying a PBR base colour"
    )
    tangents: list[Tangent] | None = Field(
        None, max_length=MAX_MESH_VERTICES, description="per-vertex tangents for normal maps (generated where absent)"
    )


Wrap = Literal["repeat", "clamp", "mirror"]
Filter = Literal["linear", "nearest"]
# (spelled out for the type checker; the texture's own declaration is the one that counts)
assert get_args(Wrap) == WRAPS and get_args(Filter) == FILTERS


class TextureModel(Strict):
    """An image a PBR material reads (docs/FORMATS.md, "Textures"): a PNG or JPEG in base64, at most
    MAX_TEXTURE_SIDE a side (checked from its header before it is decoded)."""

    png: str = Field(description="the image, a PNG or JPEG file in base64")
    srgb: bool = Field(False, description="colour channels sRGB-encoded (base colour, emissive); else linear data")
    wrap_s: Wrap = Field("repeat", description="how U outside [0, 1] repeats")
    wrap_t: Wrap = Field("repeat", description="how V outside [0, 1] repeats")
    filter: Filter = Field("linear", description="within a mip level; between levels always linear")
    name: str = Field("", max_length=MAX_TEXTURE_NAME, description="the image's file name")


# ---- analytic shapes (renderer.geometry.shapes; docs/FORMATS.md, "Analytic shapes") --------------------
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


# ---- motion (renderer.scenes.animation) --------------------------------------------------
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
    materials: list[AnyMaterialModel] = Field(min_length=1, max_length=MAX_MATERIALS)
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
    textures: list[TextureModel] = Field(
        default_factory=list, max_length=MAX_TEXTURES, description="the images PBR materials read, by index"
    )

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
