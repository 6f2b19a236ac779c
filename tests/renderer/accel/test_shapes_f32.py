"""renderer/accel/shapes_f32.py (the float32 copy of shaders/shapes.glsl) against the float64
oracle of tests/renderer/accel/shapes_cases.py, on every stability case, and the oracle itself
against closed forms and dense sampling."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel import shapes_f32 as S
from tests.renderer.accel.shapes_cases import (
    AGREEMENT,
    CASES,
    DEPTH_REL,
    _local,
    _torus_E,
    oracle,
    oracle_torus,
    pack,
    reference,
    score,
)


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_the_float32_copy_agrees_with_the_float64_oracle(case):
    t, n = S.intersect_shape(case.o, case.d, *case.shape, np.float32(1e30))
    assert t.dtype == np.float32 and n.dtype == np.float32
    sc = score(t, n, *reference(case.name))
    assert sc.agreement >= case.min_agreement, (case.name, sc)
    exact = score(t, n, *reference(case.name, exact=True))
    assert exact.agreement >= case.f64_min_agreement, (case.name, exact)
    hit = t < S.BIG
    assert np.allclose(np.linalg.norm(n[hit], axis=1), 1.0, atol=1e-5)
    assert np.isfinite(t).all() and np.isfinite(n).all()


def test_the_closed_form_quartic_fails_where_the_bracketing_holds():
    """Why the kept torus method is the bracketing one: the closed form misses a thin torus."""
    case = next(c for c in CASES if c.name == "torus_thin_grazing")
    ref = reference(case.name)
    kept = score(*S.intersect_torus_bracket(case.o, case.d, *case.shape, np.float32(1e30)), *ref)
    closed = score(*S.intersect_torus_closed(case.o, case.d, *case.shape, np.float32(1e30)), *ref)
    assert kept.agreement >= AGREEMENT
    assert closed.agreement < 0.95


def test_t_max_and_the_origin_side_are_respected():
    shape = pack(S.TORUS, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 0.25)
    o = np.array([[-3.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [3.0, 0.0, 0.0]], np.float32)
    d = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], np.float32)
    t, n = S.intersect_torus(o, d, *shape, np.float32(1e30))
    # from −3: enters at x = −1.25; from the tube's centre: leaves at x = −0.75; from +3: behind
    np.testing.assert_allclose(t, [1.75, 0.25, S.BIG], rtol=1e-6)
    np.testing.assert_allclose(n[0], [-1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(n[1], [1, 0, 0], atol=1e-6)  # outward: away from the tube's core
    t2, _ = S.intersect_torus(o[:1], d[:1], *shape, np.float32(1.7))
    assert t2[0] == S.BIG


def test_the_oracle_matches_closed_forms_for_quadrics():
    cyl = pack(S.CYLINDER, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.5, 0.5, 2.0, True)
    o = np.array([[-2.0, 0.0, 1.0], [0.0, 0.0, 5.0], [0.3, 0.0, -1.0]], np.float32)
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]], np.float32)
    t, n = oracle(o, d, cyl)
    np.testing.assert_allclose(t, [1.5, 3.0, 1.0])
    np.testing.assert_allclose(n, [[-1, 0, 0], [0, 0, 1], [0, 0, -1]], atol=1e-12)
    cone = pack(S.CONE, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 0.0, 1.0, False)
    t, _ = oracle(np.array([[-2.0, 0.0, 0.5]], np.float32), np.array([[1.0, 0.0, 0.0]], np.float32), cone)
    np.testing.assert_allclose(t, [1.5])  # radius 0.5 at half height


def test_the_torus_oracle_agrees_with_dense_sampling():
    """Every sign change of E found by sampling 20,001 points of [0, 10] is the oracle's first root."""
    rng = np.random.default_rng(3)
    shape = pack(S.TORUS, (0.0, 0.0, 0.0), (0.2, 1.0, 0.3), 1.0, 0.3)
    o = rng.uniform(-3, 3, (200, 3)).astype(np.float32)
    d = rng.uniform(-1.3, 1.3, (200, 3)) - o  # aimed into the torus's bounding box
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    t, _ = oracle_torus(o, d, shape)
    p, dl, _, _ = _local(o, d, shape)
    s = np.linspace(0, 10, 20001)
    first = np.full(200, np.inf)
    for i in range(200):
        e = _torus_E(
            np.repeat(p[i : i + 1], len(s), 0), np.repeat(dl[i : i + 1], len(s), 0), s.astype(np.longdouble), 1.0, 0.3
        )[0]
        ch = np.flatnonzero(np.diff(np.sign(e.astype(np.float64))) != 0)
        if ch.size:
            first[i] = s[ch[0]]
    assert (np.isfinite(first) == np.isfinite(t)).all()
    both = np.isfinite(t)
    assert both.sum() > 40
    assert (np.abs(first[both] - t[both]) <= 10 / 20000).all()


def test_depth_tolerance_is_the_catalogues():
    assert DEPTH_REL == 1e-4 and AGREEMENT == 0.9999
