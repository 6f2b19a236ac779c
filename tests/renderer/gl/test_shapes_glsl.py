"""shaders/shapes.glsl on the GPU (llvmpipe): every stability case of
tests/renderer/accel/shapes_cases.py, one ray per pixel, against the float64 oracle (the
target: ≥ 99.99 % of rays agree on hit/miss with depth within 1e-4 relative, unless the case
pins a figure with its reason; against the inputs as float32 stores them and as built in
float64) and against the NumPy float32 copy (renderer/accel/shapes_f32.py)."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.accel import shapes_f32 as S
from tests.renderer.accel.shapes_cases import CASES, pack, reference, score
from tests.renderer.gl.shapes_gl import ShapesGL


@pytest.fixture(scope="module")
def shapes_gl(gl_renderer):
    return ShapesGL(gl_renderer.ctx)


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_the_shader_agrees_with_the_float64_oracle_and_the_float32_copy(shapes_gl, case):
    t, n, _ = shapes_gl.run(case.o, case.d, case.shape, "intersect_shape")
    sc = score(t, n, *reference(case.name))
    assert sc.agreement >= case.min_agreement, (case.name, sc)
    exact = score(t, n, *reference(case.name, exact=True))
    assert exact.agreement >= case.f64_min_agreement, (case.name, exact)
    assert np.isfinite(t).all() and np.isfinite(n).all()
    if case.why:  # a pinned case is beyond float32: two float32 codes round it differently
        return
    tm, _ = S.intersect_shape(case.o, case.d, *case.shape, np.float32(1e30))
    hit, hit_m = t < S.BIG, tm < S.BIG
    assert (hit != hit_m).mean() <= 1e-3, case.name  # the copy decides as the shader (rounding apart)
    both = hit & hit_m
    rel = np.abs(t[both] - tm[both]) / tm[both]
    assert (rel <= 1e-4).mean() >= 0.999, case.name


def test_each_kind_by_name_and_by_the_dispatcher(shapes_gl):
    o = np.array([[-3.0, 0.0, 0.1], [0.0, 0.0, 5.0]], np.float32)
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]], np.float32)
    o = np.repeat(o, 8, 0)[:16]
    d = np.repeat(d, 8, 0)[:16]
    shapes = {
        "intersect_cylinder": (pack(S.CYLINDER, (0, 0, -1), (0, 0, 1), 0.5, 0.5, 2.0, True), [2.5, 4.0]),
        "intersect_cone": (pack(S.CONE, (0, 0, -1), (0, 0, 1), 1.0, 0.5, 2.0, True), [3.0 - 0.725, 4.0]),
        "intersect_disk": (pack(S.DISK, (0, 0, 0), (0, 0, 1), 1.0, 0.0), [S.BIG, 5.0]),
        "intersect_torus": (
            pack(S.TORUS, (0, 0, 0), (0, 0, 1), 1.0, 0.25),
            [3.0 - 1.25 + 0.25 - np.sqrt(0.25**2 - 0.1**2), S.BIG],
        ),
    }
    for name, (shape, want) in shapes.items():
        for fn in (name, "intersect_shape"):
            t, _, _ = shapes_gl.run(o, d, shape, fn)
            np.testing.assert_allclose(t[[0, 8]], want, rtol=1e-5, err_msg=f"{fn} on {name}")
