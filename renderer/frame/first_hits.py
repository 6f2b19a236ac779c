"""First hits by rasterisation: a primary-ray frame without a traversal per pixel.

Every sphere's primary rays fill a region of the image; its bounding rectangle is drawn as a
quad (one instance per sphere, ``shaders/first_hits.vert``) whose fragments test that sphere
alone with the tracer's own ray and test (``FIRST_HITS_SPHERES`` in ``shaders/raytrace.frag``).
The depth test keeps the nearest: the depth is t's exact order (``shaders/depth_order.glsl``)
and the instances come in descending id order under ≤, so on a tie the lower id, drawn later,
wins — :func:`closer`'s rule. A pass of the planes (and misses) comes first, writing their
depth. The same ids and distances as the traversal, bit for bit (tests/renderer/gl/
test_first_hits.py): the fragment computes the same float32 ray and the same test.

Or per tile (:func:`tile_lists`, ``FIRST_HITS_TILES``): one quad per screen tile that some
sphere's rectangle meets, listing those spheres by a near bound; its fragments test the list in
that order and stop once the next bound passes the best hit — one fragment per pixel, no depth
test among spheres, the same exact result.

The rectangle is exact in float64: with the camera's orthonormal (right, up, forward) and a
sphere at (x, y, z) in that frame, radius r, the rays of image-plane coordinate u (directions
forward + u·right + v·up) form the plane x' = u·z' through the eye; it meets the sphere when
|x − u z| ≤ r √(1 + u²), so u lies between the roots of (z² − r²) u² − 2xz u + x² − r² = 0 (the
same in v with y). A sphere reaching the camera's plane (z ≤ r) has no such bound and covers the
whole frame; one wholly behind it (z < −r) is dropped. The rectangle is widened by one fragment
for the float32 rounding of rays and spheres.

GL-free: the quads are data for :mod:`renderer.gl.frame`.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from .. import limits
from ..geometry.scene import Scene
from ..gpu import gpu_layout
from ..modes import PRIMARY_MODES
from . import cost


class FrameSettings(Protocol):
    """What of a frame's settings the choice reads (:class:`renderer.config.settings.RenderSettings` has it;
    named here so that the core need not import the settings and the methods; read-only, as a frozen
    dataclass's fields are)."""

    @property
    def first_hits(self) -> str: ...
    @property
    def mode(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...


# The per-instance record of shaders/first_hits.vert (total: 36 bytes): the quad's corners in
# normalised device coordinates, the sphere as float32 (centre, radius), its record key.
INSTANCE = np.dtype([("rect", "<f4", 4), ("sphere", "<f4", 4), ("key", "<u4")])
INSTANCE_FORMAT = "4f 4f 1u/i"
INSTANCE_ATTRIBUTES: tuple[str, ...] = ("a_rect", "a_sphere", "a_key")
# A sphere this close to the camera's plane (z ≤ r · (1 + NEAR_SLACK)) covers the whole frame.
NEAR_SLACK = 1e-6
MARGIN = 1.0  # fragments the rectangle is widened by on every side


def eligible(scene: Scene, mode: str, path: bool) -> bool:
    """Whether a frame can take its first hits from rasterised spheres: primary rays only (the
    modes of :data:`~renderer.modes.PRIMARY_MODES`), spheres and planes only (no triangles, no
    analytic shapes: their first hits come from the traversal)."""
    return mode in PRIMARY_MODES and not path and scene.n_triangles == 0 and scene.n_shapes == 0


def chosen(scene: Scene, settings: FrameSettings, path: bool, method: str, stats: dict[str, Any]) -> str:
    """How the frame finds its first hits if not by the traversal: ``"raster"`` (a quad per sphere),
    ``"tiles"`` (a quad per tile and its list) or ``""`` (the traversal) — the ``first_hits``
    setting, ``auto`` by :func:`cheapest` (``method`` and its build's ``stats``: the traversal's
    estimate). Tiles whose lists would pass ``MAX_TILE_PAIRS`` entries trace instead."""
    how = settings.first_hits
    if how == "trace" or not eligible(scene, settings.mode, path):
        return ""
    size = (settings.width, settings.height)
    if how == "tiles" and tile_counts(instances(scene, size, size), size)[0] > limits.MAX_TILE_PAIRS:
        return ""  # lists too long to make (spheres that each cover much of the frame): the traversal
    if how in ("raster", "tiles"):
        return how
    return cheapest(scene, settings, method, stats)


def cheapest(scene: Scene, settings: FrameSettings, method: str, stats: dict[str, Any]) -> str:
    """The cost model's choice for ``auto``: ``"raster"``, ``"tiles"`` or ``""`` (the traversal) —
    :func:`renderer.frame.cost.first_hits_ms` and :func:`renderer.frame.cost.tiles_ms` against
    :func:`renderer.frame.cost.traversal_ms`. The traversal past ``FIRST_HITS_AUTO_MAX_SPHERES`` spheres
    (their quads would cost more to make than most frames to trace); without spheres, the traversal
    where there are planes (the same full-screen pass) and a clear where there are none."""
    n = scene.n_spheres
    if n == 0:  # nothing to rasterise: a frame without planes either is then one clear, not a pass
        return "" if scene.planes else "raster"
    if n > limits.FIRST_HITS_AUTO_MAX_SPHERES:
        return ""
    w, h = settings.width, settings.height  # one pass: the modes that show primary hits trace pixel centres
    quads = instances(scene, (w, h), (w, h))
    pairs, tile_pixels = tile_counts(quads, (w, h))
    planes = bool(scene.planes)
    options = {
        "": cost.traversal_ms(method, stats, scene, settings),
        "raster": cost.first_hits_ms(covered_fragments(quads, (w, h)), w * h, planes),
    }
    if pairs <= limits.MAX_TILE_PAIRS:
        options["tiles"] = cost.tiles_ms(pairs, tile_pixels, w * h, planes)
    return min(options, key=options.__getitem__)


def frame_cost(
    how: str, scene: Scene, settings: FrameSettings, traced: cost.FrameCost, model: cost.CostModel = cost.DEFAULT_MODEL
) -> cost.FrameCost:
    """The cost of a frame whose first hits are rasterised (``how``: ``"raster"`` or ``"tiles"``), in
    place of ``traced``, its traversal's estimate: what its quads will really shade — every quad's
    fragments, overlaps counted each time (spheres that all cover the same pixels cost their number
    of fragments per pixel), or every (tile, sphere) pair of the lists. One pass (the modes of
    :data:`~renderer.modes.PRIMARY_MODES` trace pixel centres); ``tests_per_ray``: the sphere tests of
    one pixel, ``ms_per_pixel`` the trace's ms per pixel (what a band of rows costs on average)."""
    w, h = settings.width, settings.height
    quads = instances(scene, (w, h), (w, h))
    planes = bool(scene.planes)
    if how == "tiles":
        pairs, tile_pixels = tile_counts(quads, (w, h))
        trace = cost.tiles_ms(pairs, tile_pixels, w * h, planes)
        tests = pairs * TILE * TILE / (w * h)  # a tile's every pixel may test its whole list
    else:
        fragments = covered_fragments(quads, (w, h))
        trace = cost.first_hits_ms(fragments, w * h, planes)
        tests = fragments / (w * h)
    ms = model.ns_frame / 1e6 + trace
    return cost.FrameCost(
        passes=1,
        pixels=w * h,
        rays_per_pixel=1.0,
        nodes_per_ray=0.0,
        tests_per_ray=tests,
        coverage=traced.coverage,
        ms=ms,
        ms_per_pixel=trace / max(1, w * h),
        bound_ms=ms * model.upper,
        degenerate=False,
    )


def image_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sphere, the image-plane ranges its primary rays can have: ``u`` (n, 2) and ``v`` (n, 2)
    (the coordinates of :func:`renderer.gpu.gpu_layout.camera_uniforms`: u = (2x/W − 1)·half_extent.x),
    and ``state`` (n,) int8: 0 bounded, 1 the whole frame (reaches the camera's plane), −1 none
    (wholly behind the camera). float64, from the float32 spheres the records hold."""
    c = scene.sphere_centers.astype(np.float32).astype(np.float64)
    r = scene.sphere_radii.astype(np.float32).astype(np.float64)
    right, up, forward = scene.camera.basis()
    p = c - np.asarray(scene.camera.position, dtype=np.float32).astype(np.float64)
    x, y, z = p @ right, p @ up, p @ forward
    state = np.zeros(len(r), dtype=np.int8)
    state[z <= r * (1.0 + NEAR_SLACK)] = 1
    state[z < -r] = -1
    a = np.where(state == 0, z * z - r * r, 1.0)

    def roots(w: np.ndarray) -> np.ndarray:
        s = r * np.sqrt(np.maximum(w * w + z * z - r * r, 0.0))
        return np.stack([(w * z - s) / a, (w * z + s) / a], axis=1)

    return roots(x), roots(y), state


def instances(
    scene: Scene,
    grid: tuple[int, int],
    target: tuple[int, int],
    scale: float = 1.0,
    offset: tuple[float, float] = (0.5, 0.5),
    keys: np.ndarray | None = None,
    bounds: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """The quads of one pass (:data:`INSTANCE` records, descending id, off-frame ones dropped).

    ``grid``: the pass's ray grid (W, H) (``u_resolution``); ``target``: the window (fragments);
    ``scale`` and ``offset``: the pass uniforms (a fragment at x traces grid column
    (x − ½)·scale + offset.x, rows from the top). ``keys``: the spheres' record keys (default: id |
    material, as :func:`renderer.gpu.gpu_layout.sphere_records`); ``bounds``: :func:`image_bounds`,
    when the caller has it already."""
    n = scene.n_spheres
    if n == 0:
        return np.zeros(0, dtype=INSTANCE)
    u, v, state = image_bounds(scene) if bounds is None else bounds
    gw, gh = float(grid[0]), float(grid[1])
    tw, th = float(target[0]), float(target[1])
    s = math.tan(math.radians(scene.camera.fov_y) / 2.0)
    hx, hy = s * gw / gh, s
    px = (u / hx + 1.0) * gw / 2.0  # grid columns, (n, 2) ascending
    row = (1.0 - v[:, ::-1] / hy) * gh / 2.0  # grid rows from the top, ascending
    fx = (px - offset[0]) / scale + 0.5  # fragment x of those columns
    fy = (gh - row[:, ::-1] - offset[1]) / scale + 0.5  # fragment y (from the bottom), ascending
    x0 = np.clip(fx[:, 0] - MARGIN, 0.0, tw)
    x1 = np.clip(fx[:, 1] + MARGIN, 0.0, tw)
    y0 = np.clip(fy[:, 0] - MARGIN, 0.0, th)
    y1 = np.clip(fy[:, 1] + MARGIN, 0.0, th)
    whole = state == 1
    x0[whole], y0[whole], x1[whole], y1[whole] = 0.0, 0.0, tw, th
    keep = (state >= 0) & (x1 > x0) & (y1 > y0)
    ids = np.flatnonzero(keep)[::-1]
    out = np.empty(len(ids), dtype=INSTANCE)
    out["rect"] = np.stack(
        [2.0 * x0[ids] / tw - 1.0, 2.0 * y0[ids] / th - 1.0, 2.0 * x1[ids] / tw - 1.0, 2.0 * y1[ids] / th - 1.0], axis=1
    )
    out["sphere"][:, :3] = scene.sphere_centers[ids]
    out["sphere"][:, 3] = scene.sphere_radii[ids]
    if keys is None:
        keys = gpu_layout.sphere_keys(scene)
    out["key"] = keys[ids]
    return out


def covered_fragments(quads: np.ndarray, target: tuple[int, int]) -> float:
    """Fragments the quads of one pass shade (their areas in the window; overlaps counted each time)."""
    if len(quads) == 0:
        return 0.0
    r = quads["rect"].astype(np.float64)
    return float(np.sum((r[:, 2] - r[:, 0]) * (r[:, 3] - r[:, 1])) * target[0] * target[1] / 4.0)


# --------------------------------------------------------------------------- tiles
# The per-tile variant: the window cut into TILE × TILE tiles, each listing the spheres whose
# rectangle meets it, nearest-possible first; a tile's fragments test its list in that order and
# stop once the next sphere cannot start before the best hit.
TILE = 16
# Per tile (total: 24 bytes): its rectangle (normalised device coordinates), and its list's
# first entry and length in the entries' texture.
TILE_INSTANCE = np.dtype([("rect", "<f4", 4), ("list", "<u4", 2)])
TILE_FORMAT = "4f 2u/i"
TILE_ATTRIBUTES: tuple[str, ...] = ("a_rect", "a_list")
ENTRY_TEXELS = 2  # per entry: (centre, radius) as float bits; (key, t_near as float bits, 0, 0)


def tile_spans(quads: np.ndarray, target: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """Per quad, the tiles its rectangle meets: columns x0 … x1 − 1 and rows y0 … y1 − 1 (int32)."""
    tw, th = int(target[0]), int(target[1])
    rect = quads["rect"].astype(np.float64)
    x0 = np.floor((rect[:, 0] + 1.0) * tw / 2.0 / TILE).astype(np.int32)
    x1 = np.ceil((rect[:, 2] + 1.0) * tw / 2.0 / TILE).astype(np.int32)  # exclusive
    y0 = np.floor((rect[:, 1] + 1.0) * th / 2.0 / TILE).astype(np.int32)
    y1 = np.ceil((rect[:, 3] + 1.0) * th / 2.0 / TILE).astype(np.int32)
    return x0, x1, y0, y1


def tile_counts(quads: np.ndarray, target: tuple[int, int]) -> tuple[int, float]:
    """What :func:`tile_lists` would make of ``quads``, without making it: its (tile, sphere) pairs and
    the pixels of the tiles with a list (the rectangles summed on a grid of tiles)."""
    if len(quads) == 0:
        return 0, 0.0
    tw, th = int(target[0]), int(target[1])
    x0, x1, y0, y1 = tile_spans(quads, target)
    nx, ny = -(-tw // TILE), -(-th // TILE)
    marks = np.zeros((ny + 1, nx + 1), dtype=np.int64)
    np.add.at(marks, (y0, x0), 1)
    np.add.at(marks, (y0, x1), -1)
    np.add.at(marks, (y1, x0), -1)
    np.add.at(marks, (y1, x1), 1)
    listed = np.cumsum(np.cumsum(marks, axis=0), axis=1)[:ny, :nx] > 0
    cols = np.minimum(np.arange(1, nx + 1) * TILE, tw) - np.arange(nx) * TILE
    rows = np.minimum(np.arange(1, ny + 1) * TILE, th) - np.arange(ny) * TILE
    pixels = float((listed * rows[:, None] * cols[None, :]).sum())
    return int(((x1 - x0) * (y1 - y0)).sum()), pixels


def near_bounds(scene: Scene) -> np.ndarray:
    """Per sphere, float32 bounds below every t its float32 test can return for a primary ray: the
    eye's distance to the centre less the radius, lowered by a relative 1e-5 (the test's rounding is
    far below it, and by 1e-5 of the coordinates' size, which o − c is rounded at), 0 for a sphere
    around the eye."""
    c = scene.sphere_centers.astype(np.float32).astype(np.float64)
    r = scene.sphere_radii.astype(np.float32).astype(np.float64)
    eye = np.asarray(scene.camera.position, dtype=np.float32).astype(np.float64)
    d = np.linalg.norm(c - eye, axis=1) - r
    # The test's o − c rounds at float32's spacing of the larger coordinates, eye's or centre's.
    size = np.maximum(np.abs(c).max(axis=1, initial=0.0), np.abs(eye).max())
    return np.maximum(d - 1e-5 * (d + r + size), 0.0).astype(np.float32)


def tile_lists(
    scene: Scene,
    grid: tuple[int, int],
    target: tuple[int, int],
    scale: float = 1.0,
    offset: tuple[float, float] = (0.5, 0.5),
    bounds: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The tiles of one pass that some sphere's rectangle meets (:data:`TILE_INSTANCE`) and their
    lists' entries (uint32, (k · ENTRY_TEXELS, 4)): per tile, its spheres by increasing near bound,
    then id. The rectangles are :func:`instances`'."""
    quads = instances(scene, grid, target, scale, offset, bounds=bounds)
    tw, th = int(target[0]), int(target[1])
    if len(quads) == 0:
        return np.zeros(0, dtype=TILE_INSTANCE), np.zeros((ENTRY_TEXELS, 4), dtype=np.uint32)
    ids = (quads["key"] & np.uint32(gpu_layout.SPHERE_ID_MASK)).astype(np.int64)
    near = near_bounds(scene)[ids]
    table = np.zeros((len(quads), ENTRY_TEXELS, 4), dtype=np.uint32)  # each quad's entry
    table[:, 0] = quads["sphere"].view(np.uint32).reshape(-1, 4)
    table[:, 1, 0] = quads["key"]
    table[:, 1, 1] = near.view(np.uint32)
    # The quads in list order (near bound, then id): one stable sort by tile then orders every list.
    rank = np.lexsort((ids, near))
    x0, x1, y0, y1 = (a[rank] for a in tile_spans(quads, target))
    nx = np.int32(-(-tw // TILE))
    wx = x1 - x0
    per = wx * (y1 - y0)
    r = np.repeat(np.arange(len(rank), dtype=np.int32), per)  # the (ranked) quad of each (tile, sphere) pair
    k = np.arange(len(r), dtype=np.int32) - np.repeat((np.cumsum(per) - per).astype(np.int32), per)
    wxr = wx[r]
    tile = (y0[r] + k // wxr) * nx + (x0[r] + k % wxr)
    # Tile numbers fit 16 bits at any accepted image size ((MAX_IMAGE_SIDE / TILE)² = 2^16), where
    # NumPy's stable sort is a radix sort: linear in the pairs.
    small = int(nx) * -(-th // TILE) <= 1 << 16
    order = np.argsort(tile.astype(np.uint16) if small else tile, kind="stable")
    tile = tile[order]
    entries = table[rank[r[order]]]
    first = np.flatnonzero(np.r_[True, tile[1:] != tile[:-1]])
    counts = np.diff(np.r_[first, len(tile)])
    t = tile[first].astype(np.int64)
    tx, ty = t % int(nx), t // int(nx)
    tiles = np.empty(len(t), dtype=TILE_INSTANCE)
    fx0, fy0 = tx * TILE, ty * TILE
    fx1, fy1 = np.minimum(fx0 + TILE, tw), np.minimum(fy0 + TILE, th)
    tiles["rect"] = np.stack([fx0 / tw, fy0 / th, fx1 / tw, fy1 / th], 1) * 2.0 - 1.0
    tiles["list"] = np.stack([first, counts], 1)
    return tiles, entries.reshape(-1, 4)
