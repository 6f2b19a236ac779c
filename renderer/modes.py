"""What each render mode shows, and the colours it uses (``docs/SHADING.md``).

The GPU tracer (``shaders/raytrace.frag``), the ray engines' read-back
(:mod:`renderer.gl.ray_engine`), the float64 reference (:mod:`renderer.oracle.reference`) and
the browser client's legend all colour with these. The recursion colours are written
here only: the shader assembler (:func:`renderer.frame.shader_source.recursion_color_function`)
emits them into the tracer, and ``GET /api/info`` hands them to the legend;
``tests/renderer/test_modes.py`` checks that the shader's primid and heat literals are the
same numbers as here.
"""

from __future__ import annotations

import numpy as np

MODES = ("color", "depth", "primid", "normal", "recursion", "heat", "cones")
# What the client's mode menu calls each (GET /api/info's mode_labels).
MODE_LABELS = {
    "color": "Colour",
    "depth": "Depth",
    "primid": "Primitive id",
    "normal": "Normal",
    "recursion": "Recursion depth (Fig. 4.2f)",
    "heat": "Traversal heat (Fig. 4.3)",
    "cones": "Tile cones (hre only)",
}
# Modes raytrace.frag implements ("cones" belongs to the hierarchical ray engine).
SINGLE_PASS_MODES = ("color", "depth", "primid", "normal", "recursion", "heat")
# Modes that trace the whole ray tree (the others trace the primary ray only).
RAY_TREE_MODES = ("color", "recursion")
# Modes that show the primary hit alone (no shading, no spawned rays).
PRIMARY_MODES = ("depth", "primid", "normal")
# Modes whose image is the mean of √s × √s sub-pixels at samples_per_pixel = s; the others
# (and every mode's depth, primid and normal arrays) show the ray through the pixel centre.
AVERAGED_MODES = ("color", "recursion", "heat", "cones")

# Fig. 4.2f colours of the `recursion` mode, index = level (0 = primary miss: black).
RECURSION_COLORS = np.array(
    [
        (0.0, 0.0, 0.0),
        (1.0, 0.0, 0.0),
        (0.0, 1.0, 0.0),
        (0.0, 0.0, 1.0),
        (1.0, 1.0, 0.0),
        (1.0, 0.0, 1.0),
        (0.0, 1.0, 1.0),
        (1.0, 1.0, 1.0),
        (1.0, 0.5, 0.0),
    ],
    dtype=np.float64,
)
# What the legend calls them.
RECURSION_COLOR_NAMES = ("black", "red", "green", "blue", "yellow", "magenta", "cyan", "white", "orange")
# Per-id colour multipliers of the `primid` mode.
PRIMID_FACTORS = np.array([0.6180340, 0.7548777, 0.5698403], dtype=np.float64)
# Fig. 4.3 of the `heat` mode: per sphere test (red), gap (green), node visit (blue).
HEAT_SCALE = {"tests": 0.05, "gaps": 0.2, "nodes": 0.2}


def primid_colors(primid: np.ndarray) -> np.ndarray:
    """``fract(id · PRIMID_FACTORS) · 0.8 + 0.2``, black where id = −1; shape (…, 3)."""
    primid = np.asarray(primid)
    x = primid.astype(np.float64)[..., None] * PRIMID_FACTORS
    return np.where((primid >= 0)[..., None], (x - np.floor(x)) * 0.8 + 0.2, 0.0)


def heat_image(nodes: np.ndarray, gaps: np.ndarray, tests: np.ndarray) -> np.ndarray:
    """Fig. 4.3 colours (…, 3): red 0.05·tests, green 0.2·gaps, blue 0.2·nodes, each clamped to 1."""
    return np.minimum(
        np.stack(
            [
                HEAT_SCALE["tests"] * np.asarray(tests, np.float64),
                HEAT_SCALE["gaps"] * np.asarray(gaps, np.float64),
                HEAT_SCALE["nodes"] * np.asarray(nodes, np.float64),
            ],
            axis=-1,
        ),
        1.0,
    )


def depth_grey(depth: np.ndarray, target_distance) -> np.ndarray:
    """The `depth` mode's grey ``d / (d + t)`` (d = camera–target distance), 0 on a miss (t = inf).

    Computed in the precision of its arguments: the reference passes float64, the ray
    engines' read-back float32 (what the shader computes).
    """
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(depth), target_distance / (target_distance + depth), 0.0)
