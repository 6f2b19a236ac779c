"""The torus methods and the quadrics of shaders/shapes.glsl on every stability case: agreement
with the float64 oracle, largest relative Δt, ns per ray of a timed draw (llvmpipe).

    PYTHONPATH=. .venv/bin/python bench/shapes_solvers.py [--repeat N]

Agreement: the share of the case's 16,384 rays whose hit/miss agrees with the oracle and whose
depth is within 1e-4 relative (tests/renderer/accel/shapes_cases.py); the oracle intersects
the shape as float32 stores it, and in the second agreement column as built in float64.
Timings only here, never in tests.
"""

from __future__ import annotations

import argparse

from renderer.accel.shapes_f32 import TORUS
from renderer.gl.context import create_context
from tests.renderer.accel.shapes_cases import CASES, reference, score
from tests.renderer.gl.shapes_gl import ShapesGL

TORUS_METHODS = {
    "B bracket (kept)": "intersect_torus_bracket",
    "A closed form": "intersect_torus_closed",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed draws per case and method")
    args = ap.parse_args()
    gl = ShapesGL(create_context())
    print(
        "| case | method | agreement | hit/miss differ | depth > 1e-4 | max rel Δt "
        "| agreement, float64 inputs | ns/ray |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for case in CASES:
        ref = reference(case.name)
        kind = int(case.shape[2, 2])
        methods = TORUS_METHODS if kind == TORUS else {"quadric": "intersect_shape"}
        for label, fn in methods.items():
            gl.run(case.o, case.d, case.shape, fn)  # compile and warm up
            t, n, per = gl.run(case.o, case.d, case.shape, fn, repeat=args.repeat)
            sc = score(t, n, *ref)
            ex = score(t, n, *reference(case.name, exact=True))
            print(
                f"| `{case.name}` | {label} | {100 * sc.agreement:.3f} % | {sc.mask_diff} | {sc.depth_bad} "
                f"| {sc.max_rel_dt:.1e} | {100 * ex.agreement:.3f} % | {per * 1e9 / len(t):.0f} |"
            )
    print(f"\n{len(CASES)} cases × 16,384 rays, {args.repeat} timed draws each")


if __name__ == "__main__":
    main()
