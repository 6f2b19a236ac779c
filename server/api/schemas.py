"""The API's own models: queries, WebSocket messages and answers (pydantic), over the contract.

The models the sessions read too — the scene JSON, the render settings, the session recipes, the
gestures, the model upload's query — are the service's contract (:mod:`server.contract`), below the API
and the sessions; they are re-exported here, so the routes and the OpenAPI schema see one module.

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

from typing import Any, Literal, cast

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    TypeAdapter,
    ValidationError,
    model_validator,
)

from renderer.config import settings as declared
from renderer.config.settings import SettingValues, setting
from renderer.gpu.texture_layout import WEBGL2_MAX_ARRAY_LAYERS
from renderer.limits import (
    MAX_DEVICE_ARRAY_LAYERS,
    MAX_DEVICE_TEXTURE_SIZE,
    MAX_ENV_ROTATION_DEG,
    MAX_ENV_SCALE,
    MAX_TRIANGLES,
    REFINE_MS_RANGE,
    REFINE_NOISE_RANGE,
    REFINE_SAMPLES_RANGE,
)

from ..contract.fields import MAX_LISTED_ERRORS, QueryModel, Strict, optional  # noqa: F401 - re-exported
from ..contract.scene import (  # noqa: F401 - re-exported: the scene JSON's models
    CameraModel,
    ConeModel,
    CylinderModel,
    DiskModel,
    EnvironmentModel,
    LightModel,
    MaterialModel,
    MeshModel,
    PlaneModel,
    SceneModel,
    SphereModel,
    TorusModel,
)
from ..contract.sessions import (  # noqa: F401 - re-exported: what sessions are made and moved with
    Gesture,
    MeshSceneRecipe,
    MeshUploadQuery,
    MuseumRecipe,
    OrbitGesture,
    PanGesture,
    PinchGesture,
    ResetGesture,
    SessionCreate,
)
from ..contract.settings import (  # noqa: F401 - re-exported: the settings' models
    SETTING_TYPES,
    FullSettings,
    MaxPrims,
    Method,
    MethodName,
    Mode,
    ModeName,
    RecursionDepth,
    RenderParams,
    SettingsPatch,
    Time,
    TreeDepth,
    build_full_settings,
    build_render_params,
)
from ..frames.device_data import DEFAULT_MAX_TEXTURE_SIZE, FEATURE_DEFINES

_INT = TypeAdapter(int)


# The settings whose values are listed integers (a Literal of them in the models).
_INTEGER_CHOICES = tuple(s.name for s in declared.SETTINGS if s.type == "integer" and s.choices is not None)


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
        Literal's, so a setting of integer choices is read as an integer first (and then checked as the set)."""
        if not isinstance(data, dict):
            return data
        read = dict(data)
        for name in _INTEGER_CHOICES:
            if isinstance(data.get(name), str):
                try:
                    read[name] = _INT.validate_python(data[name])
                except ValidationError:
                    pass  # not a number: the Literal's error names the allowed values
        return read


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

    def given(self) -> SettingValues:
        return cast(SettingValues, {k: v for k, v in self.model_dump().items() if v is not None})


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
    max_array_texture_layers: int = Field(
        WEBGL2_MAX_ARRAY_LAYERS,
        ge=1,
        le=MAX_DEVICE_ARRAY_LAYERS,
        description="the device's MAX_ARRAY_TEXTURE_LAYERS (WebGL2 guarantees 256; a scene's textures are its layers)",
    )

    def given(self) -> SettingValues:
        """The render settings named (not the device's own parameters)."""
        return cast(SettingValues, {k: v for k in DEVICE_SETTINGS if (v := getattr(self, k)) is not None})


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


class SettingsOut(FullSettings):
    version: int


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
    n_triangles: int = Field(
        0, description="triangles of all meshes (ids after the planes): a model's mesh on k nodes counts k times"
    )
    n_unique_triangles: int = Field(
        0, description="triangles of all meshes, a model's mesh used by several nodes counted once (parsed once)"
    )
    n_textures: int = Field(0, description="textures the scene's materials read")
    texture_bytes: int = Field(0, description="GPU bytes of the scene's texture array, every mip level")
    attribute_bytes: int = Field(0, description="GPU bytes of the meshes' vertex attribute records")
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


# ---- stateless render ------------------------------------------------------------------


class MeshAdded(BaseModel):
    version: int
    scene_info: SceneInfo
    mesh: int = Field(description="index of the new mesh in the scene's meshes")
    first_id: int = Field(description="primitive id of its first triangle")
    placed: tuple[float, float, float] | None = Field(
        None, description="where the model's box's bottom centre went (world units): free floor beside the scene"
    )
    camera: CameraModel | None = Field(None, description="the session's camera, framed to show the model and the scene")
    notice: str | None = Field(
        None, description="a sentence for the user: where the model went, and what of the file was not read"
    )
    n_meshes: int = Field(1, description="the meshes the model became (one per glTF primitive per node)")
    n_textures: int = Field(0, description="the textures it brought")


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
    service does (renderer/frame/cost.py, ``request_work``)."""

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


class IntegratorValuesOut(BaseModel):
    """What a setting accepts, and means, under one integrator (renderer.config.settings.IntegratorValues)."""

    meaning: str = Field(description="what a value is under this integrator")
    minimum: int | float | None = Field(None, description="smallest value (when bounded)")
    maximum: int | float | None = Field(None, description="largest value (when bounded)")
    choices: list[Any] | None = Field(None, description="the values allowed (when listed)")
    offered: list[Any] | None = Field(None, description="the values a client lists: the choices, or suggestions")
    subpixel_grid: bool = Field(
        False, description="a value s is a √s × √s grid of sub-pixels: the frame is traced at √s × its size"
    )
    modes: list[str] = Field(description="the modes where these values hold (in the others: Whitted's)")


class SettingInfoOut(BaseModel):
    """One render setting as it is declared (renderer.config.settings.SETTINGS): what a client builds its settings
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
    integrators: dict[str, IntegratorValuesOut] | None = Field(
        None, description="what it accepts and means under each integrator, where that differs (null: the same)"
    )
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
    mode_labels: dict[str, str] = Field(default_factory=dict, description="what the client calls each mode")
    averaged_modes: list[str] = Field(
        default_factory=list,
        description="modes whose image is the mean of √s × √s sub-pixels (the others trace each pixel's centre)",
    )
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
        default_factory=list, description="the demo scenes, in picker order (renderer/scenes/scenarios.py DEMO_SCENES)"
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
