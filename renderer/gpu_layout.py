"""What the GPU reads: every texture and uniform of the tracer, defined once.

Each texture or uniform is a :class:`Binding` — its GLSL name, type and purpose —
declared beside what fills it: the scene's and the camera's here, each method's in its
layout module (``renderer/accel/<method>_layout.py``). The packers fill them *by those
constants*, and the shader header declares them *from those constants*
(:mod:`renderer.shader_source`), so a name exists once: a packer cannot fill a
sampler the shader spells differently. What a compiled variant reads (a
:class:`Variant`: method, mode, recursion depth, feature defines) decides which bindings
its header declares; the GL renderer uploads exactly those, and a test checks that each
of them is an active uniform of its program.

Arrays longer than one texture row wrap into a 2-D texture: element ``i`` is
texel ``(i % width, i / width)`` where ``width = textureSize(tex, 0).x`` — the
shader reads the width from the texture, so a device with a smaller
``MAX_TEXTURE_SIZE`` only needs a narrower packing.

==============  ========  ==========  ==========================================
texture         format    element     contents
==============  ========  ==========  ==========================================
u_spheres       RGBA32F   sphere id   centre x, y, z, radius
u_sphere_mat    R32UI     sphere id   material index
u_materials     RGBA32F   3 per mat.  (r, g, b, ambient), (diffuse, specular,
                                      shininess, reflective), (transmissive,
                                      ior, 0, 0)
==============  ========  ==========  ==========================================

Planes and lights are few and go in uniform arrays (``MAX_PLANES``,
``MAX_LIGHTS``); the camera's uniforms are :func:`camera_uniforms`. Each method
packs its own structure with the layout beside its build through :func:`wrap_rows`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .limits import DEFAULT_TEXTURE_WIDTH, MAX_LIGHTS, MAX_PLANES
from .modes import RAY_TREE_MODES
from .scene import Camera, Scene

MATERIAL_TEXELS = 3


# ---- bindings and variants -----------------------------------------------------------------
@dataclass(frozen=True)
class Binding:
    """One texture or uniform of the tracer: GLSL name and type (with its precision, so the
    declaration is valid before any default-precision statement), array length, purpose,
    and the group of what a variant reads it for (see :meth:`Variant.reads`)."""
    name: str
    glsl_type: str
    doc: str = ""
    length: str | None = None   # GLSL constant of a uniform array's length
    group: str = "always"

    def declaration(self) -> str:
        arr = f"[{self.length}]" if self.length else ""
        return f"uniform {self.glsl_type} {self.name}{arr};" + (f"  // {self.doc}" if self.doc else "")


# Groups of bindings a variant may not read; each has a READS_<GROUP> define in the shader.
GROUPS = ("materials", "lights", "min_weight", "target_distance")


@dataclass(frozen=True)
class Variant:
    """One compiled tracer: method × mode × recursion depth × feature defines (``NO_*``)."""
    method: str
    mode: str
    depth: int
    features: tuple[str, ...] = ()

    @property
    def traced_depth(self) -> int:
        """Levels the variant traces: modes other than colour and recursion trace the primary ray."""
        return self.depth if self.mode in RAY_TREE_MODES else 1

    @property
    def spawns(self) -> bool:
        """Whether a hit can spawn a reflected or transmitted ray."""
        return self.traced_depth > 1 and not {"NO_REFLECTION", "NO_TRANSMISSION"} <= set(self.features)

    def reads(self, group: str) -> bool:
        """Whether the variant's shader reads the bindings of ``group``."""
        if group == "always":
            return True
        if group == "materials":    # the ambient colour, or kr / kt of the rays a hit spawns
            return self.mode == "color" or (self.mode == "recursion" and self.spawns)
        if group == "lights":       # shadow rays and the diffuse and specular terms
            return self.mode == "color" and "NO_LIGHTS" not in self.features
        if group == "min_weight":   # the ε cut-off of spawned rays
            return self.spawns
        if group == "target_distance":
            return self.mode == "depth"
        raise ValueError(f"unknown binding group {group!r}")

    def defines(self) -> list[str]:
        """``READS_<GROUP>`` for each group read: the shader guards its uses with them."""
        return [f"READS_{g.upper()}" for g in GROUPS if self.reads(g)]


SPHERES = Binding("u_spheres", "highp sampler2D", "(centre.xyz, radius) per sphere id")
SPHERE_MAT = Binding("u_sphere_mat", "highp usampler2D", "material index per sphere id", group="materials")
MATERIALS = Binding("u_materials", "highp sampler2D", "MATERIAL_TEXELS texels per material", group="materials")
NUM_SPHERES = Binding("u_num_spheres", "highp int")
NUM_PLANES = Binding("u_num_planes", "highp int")
PLANE_POINT = Binding("u_plane_point", "highp vec3", length="MAX_PLANES")
PLANE_NORMAL = Binding("u_plane_normal", "highp vec3", length="MAX_PLANES")
PLANE_MAT = Binding("u_plane_mat", "highp int", length="MAX_PLANES", group="materials")
NUM_LIGHTS = Binding("u_num_lights", "highp int", group="lights")
LIGHT_POS = Binding("u_light_pos", "highp vec3", length="MAX_LIGHTS", group="lights")
LIGHT_COLOR = Binding("u_light_color", "highp vec3", length="MAX_LIGHTS", group="lights")
SCENE_BINDINGS = (SPHERES, SPHERE_MAT, MATERIALS, NUM_SPHERES, NUM_PLANES, PLANE_POINT, PLANE_NORMAL, PLANE_MAT,
                  NUM_LIGHTS, LIGHT_POS, LIGHT_COLOR)

CAM_POS = Binding("u_cam_pos", "highp vec3")
CAM_RIGHT = Binding("u_cam_right", "highp vec3")
CAM_UP = Binding("u_cam_up", "highp vec3")
CAM_FORWARD = Binding("u_cam_forward", "highp vec3")
HALF_EXTENT = Binding("u_half_extent", "highp vec2", "(tan(fov_y/2)·W/H, tan(fov_y/2))")
RESOLUTION = Binding("u_resolution", "highp vec2", "(W, H) of the render target")
TARGET_DISTANCE = Binding("u_target_distance", "highp float", "|target − position|, for the depth image",
                          group="target_distance")
CAMERA_BINDINGS = (CAM_POS, CAM_RIGHT, CAM_UP, CAM_FORWARD, HALF_EXTENT, RESOLUTION, TARGET_DISTANCE)
MIN_WEIGHT = Binding("u_min_weight", "highp float", "ε: secondary rays of smaller path weight are not traced",
                     group="min_weight")
# A frame is traced in passes: the pixel centres (scale 1, offset 0.5), then for supersampled
# images one pass per sub-pixel (sx, sy) of the √s-times finer grid (scale √s, offset s + 0.5).
PASS_SCALE = Binding("u_pass_scale", "highp float", "sub-pixels per pixel side of this pass's grid")
PASS_OFFSET = Binding("u_pass_offset", "highp vec2", "(sx, sy) + 0.5: the sub-pixel this pass traces")
PASS_BINDINGS = (PASS_SCALE, PASS_OFFSET)
TRACER_BINDINGS = (*SCENE_BINDINGS, *CAMERA_BINDINGS, *PASS_BINDINGS, MIN_WEIGHT)
# The ray engines draw planes as instances after the spheres (the instance count carries the
# number of primitives), so they never read u_num_planes; their depth image is made on the CPU.
RAY_ENGINE_SCENE_BINDINGS = tuple(b for b in SCENE_BINDINGS if b is not NUM_PLANES)
RAY_ENGINE_BINDINGS = (*RAY_ENGINE_SCENE_BINDINGS, *(b for b in CAMERA_BINDINGS if b is not TARGET_DISTANCE),
                       MIN_WEIGHT)


def declarations(bindings: tuple[Binding, ...] | list[Binding]) -> str:
    """GLSL declarations of ``bindings``, one per line."""
    return "".join(b.declaration() + "\n" for b in bindings)


@dataclass
class PackedTexture:
    """A 1-D array wrapped into rows: ``data`` is (height, width, components)."""
    data: np.ndarray
    dtype: str  # moderngl / numpy dtype code: 'f4' or 'u4'

    @property
    def size(self) -> tuple[int, int]:
        return int(self.data.shape[1]), int(self.data.shape[0])

    @property
    def components(self) -> int:
        return int(self.data.shape[2])


def wrap_rows(elements: np.ndarray, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedTexture:
    """Wrap ``elements`` (count, components) into rows of at most ``max_width``.

    The width is a power of two (the shader addresses texel ``(i & (w-1), i >> log2 w)``),
    ``max_width`` is rounded down to one. An empty array becomes a single zero
    texel (textures cannot be empty). Arrays that share an index (spheres and
    their materials) get the same width because the width depends on the count only.
    """
    elements = np.asarray(elements)
    if elements.ndim == 1:
        elements = elements[:, None]
    count, comps = elements.shape
    max_width = 1 << (int(max_width).bit_length() - 1)
    width = min(1 << max(0, count - 1).bit_length(), max_width)   # count 0 → one texel
    height = max(1, -(-count // width))
    if height > max_width:
        raise ValueError(f"{count} elements do not fit a {max_width}×{max_width} texture")
    data = np.zeros((height * width, comps), dtype=elements.dtype)
    data[:count] = elements
    dtype = "f4" if elements.dtype == np.float32 else "u4"
    return PackedTexture(data.reshape(height, width, comps), dtype)


@dataclass
class PackedScene:
    """Textures and uniforms for one frame, independent of any GL context."""
    textures: dict[str, PackedTexture]
    uniforms: dict[str, object] = field(default_factory=dict)

    @property
    def nbytes(self) -> int:
        return sum(t.data.nbytes for t in self.textures.values())


def pack_primitives(scene: Scene, max_width: int = DEFAULT_TEXTURE_WIDTH) -> PackedScene:
    """Spheres, materials, planes and lights (what every method reads)."""
    spheres = np.concatenate([scene.sphere_centers, scene.sphere_radii[:, None]], axis=1).astype(np.float32)
    mats = np.zeros((len(scene.materials) * MATERIAL_TEXELS, 4), dtype=np.float32)
    for i, m in enumerate(scene.materials):
        mats[3 * i] = (*m.color, m.ambient)
        mats[3 * i + 1] = (m.diffuse, m.specular, m.shininess, m.reflective)
        mats[3 * i + 2] = (m.transmissive, m.ior, 0.0, 0.0)
    textures = {
        SPHERES.name: wrap_rows(spheres, max_width),
        SPHERE_MAT.name: wrap_rows(scene.sphere_materials.astype(np.uint32), max_width),
        MATERIALS.name: wrap_rows(mats, max_width),
    }
    planes = scene.planes
    lights = scene.lights
    uniforms: dict[str, object] = {
        NUM_SPHERES.name: scene.n_spheres,
        NUM_PLANES.name: len(planes),
        PLANE_POINT.name: _fixed([p.point for p in planes], MAX_PLANES, (0.0, 0.0, 0.0)),
        PLANE_NORMAL.name: _fixed([p.normal for p in planes], MAX_PLANES, (0.0, 1.0, 0.0)),
        PLANE_MAT.name: _fixed([p.material for p in planes], MAX_PLANES, 0),
        NUM_LIGHTS.name: len(lights),
        LIGHT_POS.name: _fixed([l.position for l in lights], MAX_LIGHTS, (0.0, 0.0, 0.0)),
        LIGHT_COLOR.name: _fixed([l.color for l in lights], MAX_LIGHTS, (0.0, 0.0, 0.0)),
    }
    return PackedScene(textures, uniforms)


def _fixed(items: list, length: int, filler) -> list:
    """Pad a uniform array's values to the fixed length the shader declares."""
    return [tuple(x) if isinstance(x, tuple) else x for x in items] + [filler] * (length - len(items))


def camera_uniforms(camera: Camera, width: int, height: int) -> dict[str, object]:
    """The camera's uniforms for a ``width × height`` render target (pixels).

    The ray through pixel centre (x, y), row 0 at the top, is
    ``normalize(forward + u·right + v·up)`` with ``u = (2x/W − 1)·half_extent.x`` and
    ``v = (1 − 2y/H)·half_extent.y`` (``docs/SHADING.md``); the shader, the ray engines
    and the device client all take these numbers from here.
    """
    right, up, forward = camera.basis()
    s = math.tan(math.radians(camera.fov_y) / 2.0)
    return {
        CAM_POS.name: tuple(camera.position), CAM_RIGHT.name: tuple(right), CAM_UP.name: tuple(up),
        CAM_FORWARD.name: tuple(forward),
        HALF_EXTENT.name: (s * width / height, s),
        RESOLUTION.name: (float(width), float(height)),
        TARGET_DISTANCE.name: float(np.linalg.norm(np.subtract(camera.target, camera.position))),
    }


def pass_uniforms(scale: int = 1, sub: tuple[int, int] = (0, 0)) -> dict[str, object]:
    """The pass uniforms: the pixel centres (scale 1), or sub-pixel ``sub`` = (sx, sy) of a
    ``scale × scale`` grid per pixel (sy counts from the bottom, as GL's rows do)."""
    if scale == 1:
        return {PASS_SCALE.name: 1.0, PASS_OFFSET.name: (0.5, 0.5)}
    return {PASS_SCALE.name: float(scale), PASS_OFFSET.name: (sub[0] + 0.5, sub[1] + 0.5)}


def glsl_header() -> str:
    """The tracer's own layout constants (inserted after ``#version``, before each method's)."""
    return (f"#define MAX_PLANES {MAX_PLANES}\n"
            f"#define MAX_LIGHTS {MAX_LIGHTS}\n"
            f"#define MATERIAL_TEXELS {MATERIAL_TEXELS}\n")
