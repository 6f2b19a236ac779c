"""Textures the project makes itself — nothing to download — for the ``materials`` demo scene.

Each function ``(size, ...) -> Texture`` draws a square RGBA8 image of ``size`` pixels a side in
NumPy alone, deterministically (a ``seed`` drives the noise through its own generator: the same
arguments give the same texels on every machine). The noise is tileable value noise
(:func:`tileable_noise`): its lattice repeats with the image, so that a texture meant to repeat
(the checker, the tiles, the brushed metal) has no seam where it wraps.

Conventions are the glTF ones :mod:`renderer.materials.texture` keeps: row 0 is the image's top
(V = 0); base colour textures are sRGB-encoded (``srgb=True``); the data textures are linear —
metallic in blue and roughness in green (glTF's metallicRoughnessTexture), and tangent-space normals
encoded as ``0.5 + 0.5·n`` with +X towards +U (right) and +Y towards the image's top (glTF's
normalTexture: the bitangent points up the image).

:func:`tinted_glass` is the material a tinted glass needs: no texture, only transmission, an index
of refraction and KHR_materials_volume's attenuation."""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from .pbr import PbrMaterial
from .texture import Texture

MIN_SIZE, MAX_SIZE = 8, 4096  # pixels a side: big enough to hold a pattern, within MAX_TEXTURE_SIDE


def _size(size: int) -> int:
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or not MIN_SIZE <= size <= MAX_SIZE:
        raise SceneError("size", f"must be an integer in {MIN_SIZE} … {MAX_SIZE} pixels, got {size!r}")
    return int(size)


def _divides(size: int, count: int, name: str) -> int:
    """``count`` (cells across the image) checked to divide ``size`` whole, so the pattern wraps."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1 or size % count:
        raise SceneError(
            name, f"must be a positive integer dividing the size ({size}) so the image wraps, got {count!r}"
        )
    return int(count)


def _bytes(x: np.ndarray) -> np.ndarray:
    """uint8 of values in [0, 1] (rounded to nearest)."""
    return np.clip(np.rint(np.asarray(x, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)


def _rgba(rgb: np.ndarray, alpha: float = 1.0) -> np.ndarray:
    """(H, W, 4) uint8 from (H, W, 3) values in [0, 1] and a constant alpha."""
    h, w = rgb.shape[:2]
    return np.concatenate([_bytes(rgb), np.full((h, w, 1), _bytes(np.array(alpha)), np.uint8)], axis=2)


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear (IEC 61966-2-1's curve)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))


def tileable_noise(size: int, cells: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """float64 (size, size) in [0, 1]: value noise on a lattice of ``cells`` = (across, down)
    random values, smoothly (C¹, smoothstep) interpolated, the lattice wrapping at the image's
    edges: the image tiles without a seam."""
    cx, cy = cells
    lattice = rng.random((cy, cx))
    t = np.arange(size, dtype=np.float64) / size
    x, y = t * cx, t * cy
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = x - x0, y - y0
    sx, sy = fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy)
    x1, y1 = (x0 + 1) % cx, (y0 + 1) % cy
    x0, y0 = x0 % cx, y0 % cy
    top = lattice[y0][:, x0] * (1.0 - sx) + lattice[y0][:, x1] * sx
    bottom = lattice[y1][:, x0] * (1.0 - sx) + lattice[y1][:, x1] * sx
    return top * (1.0 - sy)[:, None] + bottom * sy[:, None]


def fractal_noise(size: int, cells: tuple[int, int], octaves: int, rng: np.random.Generator) -> np.ndarray:
    """float64 (size, size) in [0, 1]: ``octaves`` of :func:`tileable_noise`, each twice the
    lattice of the one before at half its weight (still tileable)."""
    total, weight, out = 0.0, 1.0, np.zeros((size, size))
    for k in range(octaves):
        across, down = cells[0] << k, cells[1] << k
        if across > size or down > size:
            break
        out += weight * tileable_noise(size, (across, down), rng)
        total += weight
        weight *= 0.5
    return out / total


# ---- the textures ------------------------------------------------------------------------------
def checker(
    size: int = 256,
    squares: int = 8,
    light: tuple[float, float, float] = (0.8, 0.8, 0.78),
    dark: tuple[float, float, float] = (0.08, 0.08, 0.09),
) -> Texture:
    """A checkerboard floor's base colour: ``squares`` × ``squares`` squares alternating ``light``
    and ``dark`` (linear RGB in [0, 1], stored sRGB-encoded), the top-left square light. An even
    ``squares`` dividing ``size`` makes the image repeat seamlessly (a square never meets its own
    colour across the wrap)."""
    size = _size(size)
    squares = _divides(size, squares, "squares")
    if squares % 2:
        raise SceneError("squares", f"must be even so the checker alternates across the wrap, got {squares}")
    cell = (np.arange(size) * squares) // size
    odd = (cell[:, None] + cell[None, :]) % 2 == 1
    rgb = np.where(odd[..., None], np.asarray(dark, float), np.asarray(light, float))
    return Texture(_rgba(_linear_to_srgb(rgb)), srgb=True, name="checker")


def wood(size: int = 256, rings: float = 26.0, seed: int = 1) -> tuple[Texture, Texture]:
    """A plank sawn along a trunk, as (base colour, metallic-roughness). The trunk's axis runs
    along U (the image's rows) a little below the board, so its growth rings (``rings`` per
    image height of radius) meet the face as stretched bands; tileable noise bends them (the
    grain). The ring's position within a year mixes pale earlywood and dark latewood (sRGB base
    colour); roughness is higher in the porous earlywood (0.65) than in the dense latewood
    (0.45); metallic 0 (blue)."""
    size = _size(size)
    rng = np.random.default_rng(seed)
    v = (np.arange(size, dtype=np.float64) + 0.5) / size
    grain = fractal_noise(size, (2, 8), 4, rng) - 0.5
    fibres = tileable_noise(size, (min(size, 4), min(size, 128)), rng) - 0.5
    # distance from the trunk's axis (0.12 under the face, across V), bent by the grain
    radius = np.sqrt((v[:, None] - 0.45) ** 2 + 0.12**2) + 0.05 * grain
    phase = (radius * rings) % 1.0
    ramp = np.clip((phase - 0.45) / 0.45, 0.0, 1.0)
    late = ramp * ramp * (3.0 - 2.0 * ramp)  # a year's wood darkens towards its end
    late = np.clip(late + 0.15 * fibres, 0.0, 1.0)
    early_rgb, late_rgb = np.array([0.55, 0.33, 0.16]), np.array([0.25, 0.12, 0.05])
    rgb = early_rgb * (1.0 - late[..., None]) + late_rgb * late[..., None]
    base = Texture(_rgba(_linear_to_srgb(rgb)), srgb=True, name="wood")
    roughness = 0.65 - 0.2 * late
    mr = np.stack([np.zeros_like(roughness), roughness, np.zeros_like(roughness)], axis=-1)
    return base, Texture(_rgba(mr), name="wood_metallic_roughness")


def brushed_metal(size: int = 256, roughness: float = 0.3, spread: float = 0.2, seed: int = 2) -> Texture:
    """Brushed metal's metallic-roughness texture: metallic 1 (blue) and a roughness (green) of
    streaks along U — noise that changes a hundred times faster down the image than across it,
    as a brush or a lathe leaves fine grooves along its stroke, over a dozen broader bands —
    about ``roughness`` ± ``spread`` / 2 with a few grooves up to ``spread`` / 2 rougher still,
    within [0, 1]. Tileable: the streaks run on across the wrap."""
    size = _size(size)
    if not (0.0 <= roughness <= 1.0 and 0.0 <= spread <= 1.0):
        raise SceneError("roughness", f"roughness and spread must be in 0 … 1, got {roughness}, {spread}")
    rng = np.random.default_rng(seed)
    down = min(size, 256)
    fine = 0.6 * tileable_noise(size, (2, down), rng) + 0.4 * tileable_noise(size, (4, down // 2), rng)
    bands = tileable_noise(size, (1, 12), rng)  # broad bands of polish: what a phone's few pixels still show
    streaks = 0.5 * fine + 0.5 * bands
    scratches = (tileable_noise(size, (8, down), rng) > 0.9) * 0.5  # a few deeper grooves
    g = np.clip(roughness + spread * (streaks - 0.5) + spread * scratches, 0.0, 1.0)
    mr = np.stack([np.zeros_like(g), g, np.ones_like(g)], axis=-1)
    return Texture(_rgba(mr), name="brushed_metal_metallic_roughness")


def tiles(
    size: int = 256, count: int = 4, grout: float = 0.06, bevel: float = 0.12, depth: float = 0.06, seed: int = 3
) -> tuple[Texture, Texture]:
    """Bevelled square tiles, as (base colour, normal map). ``count`` × ``count`` tiles; each
    tile's edge band (``grout`` of a tile, each side: the recessed joint) is flat, then its face
    rises across ``bevel`` of a tile to a flat top; ``depth`` is that rise as a share of a tile.
    The normal map's tangent-space normals are the height field's (unit length, +Y up the image),
    encoded ``0.5 + 0.5·n``; the height field wraps, so the map tiles seamlessly. The base colour
    is a glazed cream per tile (each a little different) and grey grout (sRGB)."""
    size = _size(size)
    count = _divides(size, count, "count")
    if not (0.0 <= grout < 0.5 and 0.0 < bevel and grout + bevel < 0.5 and 0.0 < depth <= 1.0):
        raise SceneError("bevel", "grout ≥ 0, bevel > 0 with grout + bevel < 0.5 of a tile, depth in (0, 1]")
    rng = np.random.default_rng(seed)
    t = (np.arange(size, dtype=np.float64) + 0.5) * count / size  # pixel centres, in tiles
    f = t % 1.0
    edge = np.minimum(f, 1.0 - f)  # distance to the nearest joint, in tiles
    rise = np.clip((edge - grout) / bevel, 0.0, 1.0)
    height = np.minimum(rise[:, None], rise[None, :]) * depth  # rows × columns, in tiles
    # slopes by central differences over the wrapped field (per tile: one pixel is count / size tiles)
    step = count / size
    d_col = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) / (2.0 * step)  # ∂h/∂u
    d_row = (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) / (2.0 * step)  # ∂h/∂(down)
    # the surface z = h: n ∝ (−∂h/∂x, −∂h/∂y, 1) with x along U and y up the image (= −down)
    n = np.stack([-d_col, d_row, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normal = Texture(_rgba(0.5 + 0.5 * n), wrap_s="repeat", wrap_t="repeat", name="tiles_normal")
    cell = np.floor(t).astype(np.int64)
    tint = rng.uniform(-0.04, 0.04, (count, count))[cell[:, None], cell[None, :]]
    glaze = np.stack([0.78 + tint, 0.74 + tint, 0.64 + tint * 0.5], axis=-1)
    joint = np.array([0.3, 0.3, 0.3])
    in_joint = (np.minimum(edge[:, None], edge[None, :]) < grout)[..., None]
    base = Texture(_rgba(_linear_to_srgb(np.where(in_joint, joint, glaze))), srgb=True, name="tiles")
    return base, normal


def tinted_glass(
    color: tuple[float, float, float] = (0.35, 0.75, 0.55), distance: float = 3.0, ior: float = 1.5
) -> PbrMaterial:
    """A clear tinted glass (no texture): a smooth dielectric that refracts all it does not
    reflect (transmission 1, ``ior``), white light turning ``color`` (linear RGB) after
    ``distance`` world units inside it (KHR_materials_volume's attenuation: thicker parts are
    deeper in colour)."""
    return PbrMaterial(
        base_color=(1.0, 1.0, 1.0),
        metallic=0.0,
        roughness=0.0,
        ior=ior,
        transmission=1.0,
        attenuation_color=color,
        attenuation_distance=distance,
    )


def mean_factor(texture: Texture) -> np.ndarray:
    """float64 (4,): the texture's average RGBA as the factor it multiplies would see it, linear
    (an sRGB texture's colour channels decoded first): what an untextured copy of a material puts
    in place of the texture."""
    p = texture.pixels.astype(np.float64) / 255.0
    rgb = srgb_to_linear(p[..., :3]) if texture.srgb else p[..., :3]
    return np.concatenate([rgb.reshape(-1, 3).mean(axis=0), [p[..., 3].mean()]])
