"""What the GPU reads: every texture and uniform of the tracer, defined once.

The packer (:func:`pack_scene`) and the shader (``shaders/raytrace.frag``, via
:func:`glsl_header`) both take their layout from here; so does the browser
client, which receives the same arrays from the binary endpoint.

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
packs its own structure with the layout beside its build
(``renderer/accel/<method>_layout.py``) through :func:`wrap_rows`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import math

import numpy as np

from .limits import DEFAULT_TEXTURE_WIDTH, MAX_LIGHTS, MAX_PLANES, MAX_TREE_DEPTH
from .scene import Camera, Scene

MATERIAL_TEXELS = 3
# One traversal-stack entry per tree level: a tree is never deeper than MAX_TREE_DEPTH.
BIH_STACK_SIZE = MAX_TREE_DEPTH


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
    width = min(1 << max(0, (count - 1).bit_length()), max_width)
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
        "u_spheres": wrap_rows(spheres, max_width),
        "u_sphere_mat": wrap_rows(scene.sphere_materials.astype(np.uint32), max_width),
        "u_materials": wrap_rows(mats, max_width),
    }
    planes = scene.planes
    lights = scene.lights
    uniforms: dict[str, object] = {
        "u_num_spheres": scene.n_spheres,
        "u_num_planes": len(planes),
        "u_plane_point": _fixed([p.point for p in planes], MAX_PLANES, (0.0, 0.0, 0.0)),
        "u_plane_normal": _fixed([p.normal for p in planes], MAX_PLANES, (0.0, 1.0, 0.0)),
        "u_plane_mat": _fixed([p.material for p in planes], MAX_PLANES, 0),
        "u_num_lights": len(lights),
        "u_light_pos": _fixed([l.position for l in lights], MAX_LIGHTS, (0.0, 0.0, 0.0)),
        "u_light_color": _fixed([l.color for l in lights], MAX_LIGHTS, (0.0, 0.0, 0.0)),
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
        "u_cam_pos": tuple(camera.position), "u_cam_right": tuple(right), "u_cam_up": tuple(up),
        "u_cam_forward": tuple(forward),
        "u_half_extent": (s * width / height, s),
        "u_resolution": (float(width), float(height)),
        "u_target_distance": float(np.linalg.norm(np.subtract(camera.target, camera.position))),
    }


def glsl_header() -> str:
    """The tracer's own layout constants (inserted after ``#version``, before each method's)."""
    return (f"#define MAX_PLANES {MAX_PLANES}\n"
            f"#define MAX_LIGHTS {MAX_LIGHTS}\n"
            f"#define MATERIAL_TEXELS {MATERIAL_TEXELS}\n"
            f"#define BIH_STACK_SIZE {BIH_STACK_SIZE}\n")
