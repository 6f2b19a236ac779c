"""The API contract: typed request and response bodies (pydantic).

Field constraints here are what one field can say on its own (ranges, finite
numbers, enums); they become the OpenAPI schema. What needs several fields
(``camera.target`` ≠ ``camera.position``, ``up`` not parallel to the view,
material indices in range, the work caps of :mod:`server.config`) is checked by
the renderer's own validation and answered with the same 422 shape.

Units: coordinates and radii in world units; ``fov_y`` in degrees; image sizes
and ``dx``/``dy`` in pixels.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field

from renderer.animation import MAX_TIME, MUSEUM_KINDS
from renderer.scene import MAX_COORDINATE, Scene
from renderer.settings import (FORMATS, MAX_IMAGE_SIDE, MAX_RECURSION_DEPTH_LIMIT, MAX_TREE_DEPTH_LIMIT,
                               METHODS, MODES)
from renderer.tree_update import DEFAULT_THRESHOLD, UPDATE_SCHEMES

MethodName = Literal[METHODS]  # type: ignore[valid-type]
ModeName = Literal[MODES]  # type: ignore[valid-type]
FormatName = Literal[FORMATS]  # type: ignore[valid-type]
UpdateScheme = Literal[UPDATE_SCHEMES]  # type: ignore[valid-type]
MuseumKind = Literal[MUSEUM_KINDS]  # type: ignore[valid-type]


class Strict(BaseModel):
    """Unknown fields are errors; NaN and ±inf are rejected everywhere."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Vec3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3, description="[x, y, z], world units")]
Unit = Annotated[float, Field(ge=0.0, le=1.0)]
Rgb = Annotated[list[Unit], Field(min_length=3, max_length=3, description="RGB, each 0 … 1")]
Intensity = Annotated[list[Annotated[float, Field(ge=0.0, le=1e3)]],
                      Field(min_length=3, max_length=3, description="RGB intensity, each 0 … 1000")]
MaterialIndex = Annotated[int, Field(ge=0, lt=Scene.MAX_MATERIALS, description="index into materials")]


# ---- scene (SPEC's JSON) ----------------------------------------------------------
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
    shininess: float = Field(40.0, ge=0.0, le=1e4, description="Phong exponent")
    reflective: Unit = 0.3
    transmissive: Unit = 0.0
    ior: float = Field(1.0, gt=0.0, le=10.0, description="refraction index inside / outside")


class SphereModel(Strict):
    center: Vec3
    radius: float = Field(gt=0.0, le=MAX_COORDINATE, description="world units, > 0")
    material: MaterialIndex = 0


class PlaneModel(Strict):
    point: Vec3 = Field(default_factory=lambda: [0.0, -20.0, 0.0])
    normal: Vec3 = Field(default_factory=lambda: [0.0, 1.0, 0.0], description="non-zero; normalised by the server")
    material: MaterialIndex = 0


# ---- motion (issue #9; renderer.animation) ------------------------------------------
SphereIndex = Annotated[int, Field(ge=0, lt=Scene.MAX_SPHERES, description="id of the first sphere moved")]
SphereCount = Annotated[int, Field(ge=0, le=Scene.MAX_SPHERES, description="number of spheres moved")]


class RigidMotion(Strict):
    """Spheres ``first … first+count−1`` move as one rigid body: centre(t) = pivot +
    R(axis, angular_velocity·t)(c₀ − pivot) + amplitude·sin(2πt / period)."""
    kind: Literal["rigid"]
    first: SphereIndex
    count: SphereCount
    pivot: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    axis: Vec3 = Field(default_factory=lambda: [0.0, 1.0, 0.0], description="non-zero")
    angular_velocity: float = Field(0.5, ge=-1e3, le=1e3, description="radians per second")
    amplitude: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="oscillation, world units")
    period: float = Field(4.0, gt=0.0, le=1e6, description="seconds")


class DeformableMotion(Strict):
    """Coherent local motion: a travelling wave moves each sphere by at most ``amplitude`` per axis."""
    kind: Literal["deformable"]
    first: SphereIndex
    count: SphereCount
    amplitude: float = Field(1.0, ge=0.0, le=MAX_COORDINATE, description="world units")
    wavelength: float = Field(10.0, gt=0.0, le=1e9, description="world units")
    speed: float = Field(4.0, ge=-1e6, le=1e6, description="world units per second")


class IncoherentMotion(Strict):
    """Every sphere flies alone inside [box_min, box_max] and respawns every ``lifetime`` seconds;
    for the last ``absent`` fraction of each lifetime it is gone (spheres appear and disappear)."""
    kind: Literal["incoherent"]
    first: SphereIndex
    count: SphereCount
    box_min: Vec3 = Field(default_factory=lambda: [-15.0, -15.0, -15.0])
    box_max: Vec3 = Field(default_factory=lambda: [15.0, 15.0, 15.0], description="> box_min on every axis")
    speed: float = Field(5.0, ge=0.0, le=1e6, description="world units per second")
    lifetime: float = Field(2.0, gt=0.0, le=1e6, description="seconds")
    absent: float = Field(0.0, ge=0.0, le=0.95, description="fraction of each lifetime a sphere is gone")
    seed: int = Field(0, ge=0, le=2 ** 63 - 1)


Motion = Annotated[Union[RigidMotion, DeformableMotion, IncoherentMotion], Field(discriminator="kind")]


class SceneModel(Strict):
    """A whole scene (SPEC). Material indices must be < len(materials). ``motions`` (optional)
    animate sphere ranges that must not overlap; the render setting ``time`` poses the scene."""
    camera: CameraModel = Field(default_factory=CameraModel)
    lights: list[LightModel] = Field(default_factory=list, max_length=Scene.MAX_LIGHTS)
    materials: list[MaterialModel] = Field(min_length=1, max_length=Scene.MAX_MATERIALS)
    spheres: list[SphereModel] = Field(default_factory=list, max_length=Scene.MAX_SPHERES)
    planes: list[PlaneModel] = Field(default_factory=list, max_length=Scene.MAX_PLANES)
    motions: list[Motion] = Field(default_factory=list, max_length=1024)


# ---- render settings ----------------------------------------------------------
Side = Annotated[int, Field(ge=1, le=MAX_IMAGE_SIDE, description="pixels, 1 … 4096")]
Quality = Annotated[int, Field(ge=1, le=100, description="JPEG quality 1 … 100 (ignored by png and npy)")]
MaxPrims = Annotated[int, Field(ge=1, le=1 << 24, description="BIH leaf size limit")]
TreeDepth = Annotated[int, Field(ge=1, le=MAX_TREE_DEPTH_LIMIT, description="BIH depth limit (root = 1)")]
RecursionDepth = Annotated[int, Field(ge=1, le=MAX_RECURSION_DEPTH_LIMIT,
                                      description="1 = primary rays only; each reflection/refraction +1")]
SamplesPerPixel = Annotated[Literal[1, 4, 9, 16], Field(description="stratified supersampling: traced at √s× "
                                                                    "the resolution and box-filtered")]
MinWeight = Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False,
                                   description="ε: reflected/refracted rays of smaller path weight are not traced")]
TileSize = Annotated[int, Field(ge=2, le=64, description="hre's tile edge in pixels")]
Time = Annotated[float, Field(ge=0.0, le=MAX_TIME, allow_inf_nan=False,
                              description="seconds: the time an animated scene is posed at")]
UpdateThreshold = Annotated[float, Field(ge=0.0, le=100.0, allow_inf_nan=False,
                                         description="selective rebuild: SAH cost growth, 0.3 = +30 %")]


class SettingsPatch(Strict):
    """Some render settings; the ones left out (or null) keep their value."""
    width: Side | None = None
    height: Side | None = None
    method: MethodName | None = None
    mode: ModeName | None = None
    max_prims: MaxPrims | None = None
    max_tree_depth: TreeDepth | None = None
    max_recursion_depth: RecursionDepth | None = None
    format: FormatName | None = None
    quality: Quality | None = None
    samples_per_pixel: SamplesPerPixel | None = None
    min_weight: MinWeight | None = None
    specialize: bool | None = Field(None, description="shader variant with only the scene's features (exact)")
    tile_size: TileSize | None = None
    time: Time | None = None
    update: UpdateScheme | None = Field(None, description="how bvh/twolevel follow the motion between frames: "
                                                          "rebuild, refit or selective")
    update_threshold: UpdateThreshold | None = None

    def given(self) -> dict[str, Any]:
        return {k: v for k, v in self.model_dump().items() if v is not None}


class FullSettings(BaseModel):
    """All render settings of a session (SPEC's render-settings JSON plus ``quality``)."""
    width: int
    height: int
    method: str
    mode: str
    max_prims: int
    max_tree_depth: int
    max_recursion_depth: int
    format: str
    quality: int
    samples_per_pixel: int = 1
    min_weight: float = 0.0
    specialize: bool = True
    tile_size: int = 16
    time: float = 0.0
    update: str = "rebuild"
    update_threshold: float = DEFAULT_THRESHOLD


class SettingsOut(FullSettings):
    version: int


# ---- sessions -------------------------------------------------------------------
class MuseumRecipe(Strict):
    """Reiter's BART-Museum analogue (renderer.animation.museum): ``n`` moving spheres in a
    static room of 576 spheres and the floor."""
    n: int = Field(ge=0, le=Scene.MAX_SPHERES - 1024, description="moving spheres")
    kind: MuseumKind = Field("deformable", description="rigid, deformable, incoherent or mixed (a third each)")
    seed: int = Field(0, ge=0, le=2 ** 32 - 1)
    absent: float = Field(0.2, ge=0.0, le=0.95, description="incoherent spheres: fraction of a lifetime gone")


class SessionCreate(Strict):
    """Either a thesis scenario (``scenario`` and ``n``; ``seed``, ``radius`` optional),
    an animated ``museum``, or a full ``scene``; optionally the session's first render settings."""
    scenario: Literal[1, 2, 3] | None = Field(None, description="thesis scenario 1, 2 or 3")
    n: int | None = Field(None, ge=0, le=Scene.MAX_SPHERES, description="number of spheres")
    seed: int | None = Field(None, ge=0, le=2 ** 32 - 1, description="random placement seed (default 0)")
    radius: float | None = Field(None, gt=0.0, le=20.0, description="sphere radius, world units (default 1)")
    museum: MuseumRecipe | None = None
    scene: SceneModel | None = None
    settings: SettingsPatch | None = None


class SceneInfo(BaseModel):
    n_spheres: int = Field(description="spheres of the scene at rest (an animation may hide some)")
    n_planes: int
    scenario: int | None = None
    n: int | None = None
    seed: int | None = None
    radius: float | None = None
    animated: bool = False
    n_moving: int = Field(0, description="spheres some motion moves")
    museum: MuseumRecipe | None = None


class SessionOut(BaseModel):
    id: str = Field(description="session token (192 random bits, URL-safe)")
    version: int = Field(description="bumped by every change")
    settings: FullSettings
    scene_info: SceneInfo
    camera: CameraModel


class VersionOut(BaseModel):
    version: int


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
        None, gt=0.0, le=1e5,
        description="height in the same pixels as dx/dy of the view showing the frame; "
                    "default: the frame's height")


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
    pitch: float = Field(0.0, ge=-MAX_ORBIT_DEG, le=MAX_ORBIT_DEG,
                         description="degrees about right, −360 … 360 (clamped short of the poles)")


class ResetGesture(Strict):
    """Back to the camera the scene was created (or last replaced) with."""
    type: Literal["reset"]


Gesture = Annotated[Union[PanGesture, PinchGesture, OrbitGesture, ResetGesture], Field(discriminator="type")]


# ---- stateless render ------------------------------------------------------------------
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
    max_bruteforce_work: int
    max_spheres: int
    max_body_bytes: int
    max_image_side: int
    queue_size: int
    session_ttl_s: float


class MethodSettingsOut(BaseModel):
    """Which settings a method reads, so that a client shows only those (server.service.method_settings)."""
    settings: list[str] = Field(description="settings its build or passes read: max_prims, max_tree_depth, "
                                            "tile_size, update")
    modes: list[str]
    update_schemes: list[str]
    device: bool = Field(description="a browser can trace it (device mode)")
    tests_every_sphere: bool = Field(False, description="no hierarchy: POCKETRAY_MAX_BRUTEFORCE_WORK applies")
    auto: bool = Field(False, description="resolved per scene: brute force below the crossover, else bih")


class InfoOut(BaseModel):
    methods: list[str]
    modes: list[str]
    formats: list[str]
    limits: LimitsOut
    state_backend: str
    update_schemes: list[str] = Field(default_factory=list, description="values of the setting 'update'")
    museum_kinds: list[str] = Field(default_factory=list, description="motions of POST /api/sessions {museum}")
    profiles: dict[str, dict[str, Any]] = Field(
        default_factory=dict, description="render profiles measured by the Pareto experiment: 'still' (the "
                                          "session default) and 'interactive' (frames during a gesture)")
    samples_per_pixel: list[int] = Field(default_factory=list, description="values of samples_per_pixel; "
                                         "a frame's longest side × √samples must stay ≤ limits.max_image_side")
    render_timeout_s: float | None = Field(None, description="longest a frame may take; a frame that alone "
                                           "takes longer is answered with 422 (scene.n)")
    museum_room_spheres: int | None = Field(None, description="static spheres of the museum's room; they count "
                                            "against limits.max_spheres with its n moving ones")
    method_settings: dict[str, MethodSettingsOut] = Field(default_factory=dict,
                                                          description="per method: the settings that apply")


class StatsOut(BaseModel):
    """Statistics of the last build; the fields beyond ``method`` depend on the method
    (bih: renderer.accel.bih.BIHStats — primitives, inner_nodes, leaves, depth_max, …)."""
    model_config = ConfigDict(extra="allow")
    method: str
