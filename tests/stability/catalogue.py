"""The stability catalogue: every case of ``cases.py`` × every method of
``renderer.config.methods.METHODS``, through the GPU tracer and the float64 reference.

:func:`evaluate` runs one (case, method) and returns its row of the report and its
failures; ``test_catalogue.py`` asserts there are none, and ``write.py`` (``./dev
stability``) runs them all and writes ``docs/STABILITY.md`` with :func:`render_doc`. Tests
only assert: nothing here writes a file.

Per case and method:

- the build terminates and the render finishes within a bound (a hang guard: a
  SIGALRM deadline turns a runaway Python build into a failure);
- no NaN or inf pixel (image and normals), depth finite exactly where there is a hit;
- against the float64 reference of the scene: primid agreement, depth where the ids
  agree (relative), colour PSNR — the case's thresholds (strict unless pinned with a
  reason in ``cases.py``);
- against the reference of the scene *as float32 stores it* (``float32_inputs``):
  the same figures, strict unless pinned. The difference between the two separates
  what float32 *input* quantization costs from what the tracer's arithmetic costs;
- the methods against each other: identical ids (the BIH only prunes; the sphere
  test and the tie rule are shared), compared when both ran in this session — or, where a
  case pins ``method_ties_why`` (rays exactly through edges two triangles share), differing
  on ties only;
- the case's own checks (tree depth, no light leaking, ties only, no leak through a mesh …).

A case runs with ``Case.methods`` (mesh cases: the methods that trace triangles) and may
name ``known_failures``: the test expects those (strict xfail) and the report marks them.
"""

from __future__ import annotations

import contextlib
import math
import platform
import signal
import time

import numpy as np

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.oracle.reference import render_reference
from tests.helpers import ROOT, psnr
from tests.stability.cases import CASES, DEPTH_REL, PRIMID_AGREEMENT, PSNR_MIN, Case, float32_inputs, same_scene

DOC = ROOT / "docs" / "STABILITY.md"
# Hang guards, not timings: a catalogue build takes milliseconds to a second alone, and an
# xdist worker on a machine loaded to 8 and more gets a fraction of a core; a build that never
# ends (listing 3.4 on degenerate input) is caught all the same.
BUILD_BOUND_S = 120.0  # the build of any catalogue scene
RENDER_BOUND_S = 300.0  # one GPU frame
TIE_REL = 1e-5  # ids differ but both depths agree this well: two surfaces at one t


# ------------------------------------------------------------------------ helpers


class Deadline(Exception):
    pass


@contextlib.contextmanager
def deadline(seconds: float, what: str):
    """Raise :class:`Deadline` in the main thread after ``seconds`` (Python code only)."""

    def on_alarm(signum, frame):
        raise Deadline(f"{what} still running after {seconds:g} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def compare(gpu, ref) -> dict:
    """Agreement figures of a GPU frame against a reference frame."""
    same = gpu.primid == ref.primid
    both = (gpu.primid >= 0) & (ref.primid >= 0)
    gd, rd = gpu.depth.astype(np.float64), ref.depth.astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        rel = np.abs(gd - rd) / rd
    hit = same & (ref.primid >= 0)
    tie = ~same & both & (rel <= TIE_REL)
    return {
        "agreement": float(same.mean()),
        "disagree": int((~same).sum()),
        "ties": int(tie.sum()),
        "depth_rel": float(rel[hit].max()) if hit.any() else 0.0,
        "psnr": psnr(gpu.image_u8(), ref.image_u8()),
    }


def settings_of(case: Case, method: str) -> RenderSettings:
    return RenderSettings(
        width=case.width,
        height=case.height,
        method=method,
        mode="color",
        max_prims=case.max_prims,
        max_tree_depth=case.max_tree_depth,
        max_recursion_depth=case.max_recursion_depth,
    )


_CACHE: dict[str, dict] = {}


def prepared(case: Case) -> dict:
    """Scene, float64 reference and float32-input reference of a case (once per case)."""
    if case.name not in _CACHE:
        scene = case.build()
        s = settings_of(case, "bruteforce")
        t0 = time.perf_counter()
        # a hit beyond float32's range (near_axis_denormal_down) overflows the float32 depth array
        with np.errstate(over="ignore"):
            ref64 = render_reference(scene, s)
            scene32 = float32_inputs(scene)
            ref32 = ref64 if same_scene(scene, scene32) else render_reference(scene32, s)
        _CACHE[case.name] = {
            "scene": scene,
            "ref64": ref64,
            "ref32": ref32,
            "exact_inputs": ref32 is ref64,
            "ref_ms": (time.perf_counter() - t0) * 1e3,
            "facts": case.facts(scene) if case.facts else "",
        }
    return _CACHE[case.name]


# ------------------------------------------------------------------------- report


def methods_of(case: Case) -> list[str]:
    """The methods a case runs with: its own list, or every method of METHODS."""
    return [m for m in METHODS if case.methods is None or m in case.methods]


EXPECTED = [(c.name, m) for c in CASES for m in methods_of(c)]


def _fmt_psnr(p: float) -> str:
    return "∞" if math.isinf(p) else f"{p:.1f}"


def _figures(c: dict) -> str:
    return f"{100 * c['agreement']:.2f} % · {c['depth_rel']:.1e} · {_fmt_psnr(c['psnr'])} dB"


def _cell(row: dict) -> str:
    mark = "✓" if row["ok"] else ("✗ (known)" if row.get("known") else "✗")
    a, b = _figures(row["f64"]), _figures(row["f32"])
    s = f"{mark} {a}" + (f" (f32 inputs: {b})" if b != a else "") + f" · {row['render_ms']:.0f} ms"
    if row.get("tree"):
        s += f" · {row['tree']}"
    return s


def _pinned_figures(agreement: float, depth_rel: float, psnr: float | None) -> list[str]:
    """The thresholds of one reference that are looser than the defaults, as text."""
    figures = []
    if agreement < PRIMID_AGREEMENT:
        figures.append(f"primid ≥ {100 * agreement:.2f} %")
    if depth_rel > DEPTH_REL:
        figures.append(f"depth ≤ {depth_rel:.0e} rel.")
    if psnr is not None and psnr < PSNR_MIN:
        figures.append(f"PSNR ≥ {psnr:g} dB")
    return figures


def _pins(case: Case) -> list[str]:
    out = []
    figures = _pinned_figures(case.min_primid_agreement, case.max_depth_rel, case.color_psnr_min)
    if figures:
        whys = " ".join(dict.fromkeys(w for w in (case.why, case.depth_why, case.psnr_why) if w))
        out.append(f"pinned against the float64 scene ({', '.join(figures)}): {whys}")
    if case.f32_why:
        figures = _pinned_figures(case.f32_min_primid_agreement, case.f32_max_depth_rel, case.f32_color_psnr_min)
        same = case.f32_why in (case.why, case.depth_why, case.psnr_why)
        out.append(
            f"pinned against the float32-input scene ({', '.join(figures)}): "
            + ("the same reason." if same else case.f32_why)
        )
    return out


def _shading_section() -> str:
    text = (ROOT / "docs" / "SHADING.md").read_text()
    start = text.index("## Secondary rays")
    end = text.index("\n## ", start + 3)
    body = text[start:end].strip().split("\n", 1)[1].strip()
    return body


def _kind(case: Case) -> str:
    """What the methods a case leaves out cannot trace."""
    return "analytic shapes" if case.build().n_shapes else "triangles"


def render_doc(rows: dict, gl_info: dict) -> str:
    methods = list(METHODS)
    lines = [
        "# Stability catalogue",
        "",
        "Written by `./dev stability` (`tests/stability/write.py`, which runs the whole",
        "catalogue of `tests/stability/test_catalogue.py`); do not edit by hand.",
        "Every case of `tests/stability/cases.py` is rendered by the GLSL tracer with every",
        "method of `renderer.config.methods.METHODS` and by the float64 reference (`renderer/oracle/reference.py`).",
        "",
        "Each cell: ✓/✗ (all checks of the case passed), primid agreement with the reference,",
        "largest relative depth error where the ids agree, colour PSNR (uint8), and — when",
        "float32 rounds the scene's inputs — the same three figures against the reference of",
        "the scene *as float32 stores it* (shown only where they differ); then the GPU frame",
        "time (build + upload + trace + read, the first frame of a shader variant includes its",
        "compilation) and, for tree methods, the tree depth (and the BIH's forced leaves). Default thresholds: primid",
        f"≥ {100 * PRIMID_AGREEMENT:.1f} %, depth ≤ {DEPTH_REL:g} relative, PSNR ≥ {PSNR_MIN:g} dB, build",
        f"≤ {BUILD_BOUND_S:g} s, frame ≤ {RENDER_BOUND_S:g} s; no NaN/inf pixel anywhere.",
        "",
        "| case | what can go wrong | " + " | ".join(methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for case in CASES:
        absent = f"— (no {_kind(case)})"
        cells = [_cell(rows[(case.name, m)]) if (case.name, m) in rows else absent for m in methods]
        what = case.what_can_go_wrong.replace("|", "\\|")
        lines.append(f"| `{case.name}` | {what} | " + " | ".join(cells) + " |")
    lines += ["", "## Facts, pins and notes per case", ""]
    for case in CASES:
        notes = [case.note] if case.note else []
        ran = methods_of(case)
        first = rows[(case.name, ran[0])]
        if first.get("facts"):
            notes.append(first["facts"])
        notes += _pins(case)
        if case.methods is not None:
            notes.append("run with " + ", ".join(ran) + f" only: the other methods do not trace {_kind(case)}")
        per_method = [rows[(case.name, m)]["notes"] for m in ran]
        if all(n == per_method[0] for n in per_method):
            notes += [f"every method: {n}" for n in per_method[0]]
        else:
            notes += [f"{m}: {n}" for m, ns in zip(ran, per_method, strict=True) for n in ns]
        if notes:
            lines.append(
                f"- `{case.name}` ({case.width}×{case.height}, max_prims {case.max_prims}, "
                f"max_tree_depth {case.max_tree_depth}, recursion {case.max_recursion_depth}):"
            )
            lines += [f"  - {n}" for n in notes]
    lines += [
        "",
        "## Offset strategy for secondary rays (from docs/SHADING.md)",
        "",
        _shading_section(),
        "",
        "Why it holds across scales: the rule uses no length, so there is nothing to tune",
        "to the scene's size. Whether a ray leaves or enters its sphere is the sign of",
        "`dot(d, N)`, which float32 gets right except for rays within an ulp of tangent, and",
        "the far root `−b + h` of a sphere the ray enters is about `2|b|` (a chord), never",
        "the cancellation-prone near root. What float32 *does* limit is the input: at",
        "coordinates around 1e6 the spacing of float32 is 0.0625, so centres, hit points and",
        "the camera move by up to 0.031 — harmless for radius 1 (see `offset_1e6`), fatal",
        "for radius 1e-3 (`radius_1e-3_at_1e6`). The cases `scale_1e-3`, `scale_1e3`,",
        "`offset_1e4`, `offset_1e6`, `radius_1e-3_near_origin`, `camera_inside_sphere`,",
        "`tir_inside_glass` and `light_leak_room` measure acne and light leaking: acne would",
        "show as dark speckles (a PSNR drop), leaking as pixels brighter than the reference.",
        "",
        "## Machine",
        "",
        f"- OpenGL: {gl_info.get('renderer')} — {gl_info.get('version')}",
        f"- {platform.platform()}, Python {platform.python_version()}, NumPy {np.__version__}",
        "",
    ]
    return "\n".join(lines)


# ------------------------------------------------------------------------ one case


def evaluate(gl_renderer, case: Case, method: str) -> tuple[dict, list[str]]:
    """Run one (case, method): its report row (``row["ok"]``, figures, notes) and failures.

    Methods are compared with the ones already evaluated for the same case in this process
    (the ids must be identical), so the report's order (``EXPECTED``) compares them all.
    """
    data = prepared(case)
    scene, ref64, ref32 = data["scene"], data["ref64"], data["ref32"]
    failures: list[str] = []
    notes: list[str] = []
    row = {
        "ok": False,
        "known": method in dict(case.known_failures),
        "exact_inputs": data["exact_inputs"],
        "facts": data["facts"],
        "notes": notes,
        "render_ms": float("nan"),
        "f64": {"agreement": 0.0, "depth_rel": math.inf, "psnr": 0.0},
        "f32": {"agreement": 0.0, "depth_rel": math.inf, "psnr": 0.0},
    }
    try:
        # the build on its own, under a deadline: listing 3.4 loops forever on degenerate input
        t0 = time.perf_counter()
        with deadline(BUILD_BOUND_S, "the build"):
            built = METHODS[method].prepare(scene, case.max_prims, case.max_tree_depth, gl_renderer.max_texture_width)
        build_s = time.perf_counter() - t0
        if build_s > BUILD_BOUND_S:
            failures.append(f"build took {build_s:.1f} s")

        # a one-pass method traces the structure just built (render() would build the same again);
        # the multi-pass methods draw their frames in passes of their own, from the scene
        multi_pass = METHODS[method].capabilities.multi_pass
        t0 = time.perf_counter()
        with deadline(RENDER_BOUND_S, "the render"):
            gpu = gl_renderer.render(scene, settings_of(case, method), prepared=None if multi_pass else built)
        render_s = time.perf_counter() - t0
        # the frame's time, build + upload + trace + read (the build is the one above for one-pass methods)
        row["render_ms"] = (render_s if multi_pass else build_s + render_s) * 1e3
        if render_s > RENDER_BOUND_S:
            failures.append(f"render took {render_s:.1f} s")
        st = gpu.stats or {}
        if "depth_max" in st:  # the tree methods' statistics
            row["tree"] = f"tree depth {st['depth_max']}" + (
                f", {st['forced_leaves']} forced" if st.get("forced_leaves") else ""
            )

        for name, arr in (("image", gpu.image), ("normal", gpu.normal)):
            if not np.isfinite(arr).all():
                failures.append(f"{int((~np.isfinite(arr)).any(axis=-1).sum())} {name} pixels are NaN/inf")
        hit = gpu.primid >= 0
        if not np.isfinite(gpu.depth[hit]).all() or not np.isinf(gpu.depth[~hit]).all():
            failures.append("depth is not finite exactly where there is a hit")

        thresholds = {
            "f64": (ref64, case.min_primid_agreement, case.max_depth_rel, case.color_psnr_min),
            "f32": (ref32, case.f32_min_primid_agreement, case.f32_max_depth_rel, case.f32_color_psnr_min),
        }
        for key, (ref, min_agree, max_rel, min_psnr) in thresholds.items():
            if key == "f32" and data["exact_inputs"]:
                row["f32"] = row["f64"]
                continue
            c = compare(gpu, ref)
            row[key] = c
            what = "float64 scene" if key == "f64" else "float32-input scene"
            if c["agreement"] < min_agree:
                failures.append(
                    f"primid agrees with the {what} on {100 * c['agreement']:.3f} % "
                    f"< {100 * min_agree:.2f} % ({c['disagree']} px, {c['ties']} ties)"
                )
            if c["depth_rel"] > max_rel:
                failures.append(f"depth vs the {what} off by {c['depth_rel']:.2e} relative > {max_rel:.0e}")
            if min_psnr is not None and c["psnr"] < min_psnr:
                failures.append(f"colour PSNR vs the {what} {c['psnr']:.1f} dB < {min_psnr:g}")
            if c["disagree"]:
                notes.append(
                    f"{c['disagree']} px differ in id from the {what}, {c['ties']} of them ties "
                    f"(both depths within {TIE_REL:g})"
                )

        # the methods against each other: the BIH only prunes, the sphere test is shared,
        # so the ids must be identical (same t bitwise, same tie rule)
        seen = data.setdefault("primid_by_method", {})
        for other, (ids, depth) in seen.items():
            diff = ids != gpu.primid
            n = int(diff.sum())
            if n and case.method_ties_why:
                # pinned: ties only (both hit, depths within TIE_REL)
                a, b = depth[diff].astype(np.float64), gpu.depth[diff].astype(np.float64)
                with np.errstate(invalid="ignore"):
                    tie = (ids[diff] >= 0) & (gpu.primid[diff] >= 0) & (np.abs(a - b) <= TIE_REL * a)
                if not tie.all():
                    failures.append(f"ids differ from {other}'s on {n} px, {int((~tie).sum())} of them not ties")
                else:
                    notes.append(f"ids differ from {other}'s on {n} px, all ties")
            elif n:
                failures.append(f"ids differ from {other}'s on {n} px")
        if method not in dict(case.known_failures):  # a known failure is no yardstick for the others
            seen[method] = (gpu.primid, gpu.depth)

        # Rasterised first hits (renderer/frame/first_hits.py; the method does not matter to them) against
        # this traversal's primary rays: the same ray and sphere test, so the same ids and t bitwise.
        if method == "bih" and scene.n_triangles == 0 and scene.n_shapes == 0 and scene.n_spheres:
            for how in ("raster", "tiles"):
                with deadline(RENDER_BOUND_S, "the rasterised first hits"):
                    raster = gl_renderer.render(scene, settings_of(case, method).with_(mode="depth", first_hits=how))
                n = int((raster.primid != gpu.primid).sum())
                if n or not np.array_equal(raster.depth, gpu.depth):
                    failures.append(f"rasterised first hits ({how}) differ from the traversal: {n} ids, or depths")

        if case.min_tree_depth is not None and method == "bih":
            if gpu.stats["depth_max"] < case.min_tree_depth:
                failures.append(f"BIH depth_max {gpu.stats['depth_max']} < {case.min_tree_depth}")
        for check in case.checks:
            failures += check(scene, ref64, gpu, method)
    except Deadline as e:
        failures.append(str(e))
    row["ok"] = not failures
    known = dict(case.known_failures).get(method)
    if known:
        notes.append(f"known failure: {known}")
    notes += [f"FAILED: {f}" for f in failures]
    return row, failures
