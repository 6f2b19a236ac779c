"""The shapes experiment's tessellations: vertices on the exact surface of the analytic shape they
stand for, every triangle wound outwards, corner normals the exact ones. The oracle is
renderer/geometry/shapes.py (the analytic record, its float64 ``normals``), not the tessellation code."""

from __future__ import annotations

import numpy as np
import pytest

from bench.experiments.shapes import OBJECTS, shape_row, tessellate
from renderer.geometry.shapes import CONE, CYLINDER, DISK, TORUS, Shapes, normals

LEVEL = 12


def _local(row: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height along the axis and distance from it of points ``x``."""
    q = x - row[0:3]
    y = q @ row[4:7]
    rho = np.linalg.norm(q - y[:, None] * row[4:7], axis=1)
    return y, rho


@pytest.mark.parametrize("name", list(OBJECTS))
def test_vertices_lie_on_the_exact_surface(name):
    row = np.array(shape_row(*OBJECTS[name]))
    v, t, _ = tessellate(row, LEVEL)
    kind, r0, r1, h = int(row[10]), row[3], row[7], row[8]
    y, rho = _local(row, v)
    tol = 1e-12 * (1.0 + np.abs(v).max())
    if kind == TORUS:
        assert len(t) == 4 * LEVEL * LEVEL
        assert np.abs(np.hypot(rho - r0, y) - r1).max() < tol
    elif kind == DISK:
        assert len(t) == LEVEL
        assert np.abs(y).max() < tol and (rho <= r0 + tol).all()
    else:
        assert kind in (CYLINDER, CONE) and len(t) == 4 * LEVEL
        side = np.abs(rho - (r0 + (r1 - r0) * y / h)) < tol
        caps = ((np.abs(y) < tol) & (rho <= r0 + tol)) | ((np.abs(y - h) < tol) & (rho <= r1 + tol))
        assert (side | caps).all() and (y > -tol).all() and (y < h + tol).all()


@pytest.mark.parametrize("name", list(OBJECTS))
def test_triangles_face_outwards_and_normals_are_exact(name):
    row = np.array(shape_row(*OBJECTS[name]))
    shapes = Shapes(np.array([int(row[10])], np.int8), row[None], np.zeros(1, np.int32))
    v, t, n = tessellate(row, LEVEL)
    corners = v[t]
    geo = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    exact = normals(shapes, np.zeros(len(t), np.int64), corners.mean(axis=1))
    assert (np.einsum("ij,ij->i", geo, exact) > 0).all()
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    # Corner normals: the exact normal at each vertex (rim vertices belong to two parts: skipped).
    y, rho = _local(row, v)
    base_rim = (np.abs(rho - row[3]) < 1e-9) & (np.abs(y) < 1e-9)
    top_rim = (np.abs(rho - row[7]) < 1e-9) & (np.abs(y - row[8]) < 1e-9)
    rim = base_rim | top_rim
    keep = ~rim if int(row[10]) in (CYLINDER, CONE) else np.ones(len(v), bool)
    ref = normals(shapes, np.zeros(int(keep.sum()), np.int64), v[keep])
    assert np.abs(n[keep] - ref).max() < 1e-12
