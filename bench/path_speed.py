"""The path integrator's speed against Mitsuba 3's on the Cornell box, and where our time goes.

    python -m bench.path_speed                     # 320 × 544, 64 spp, depth 8, every method, profile
    python -m bench.path_speed --runs 5 --methods bih --no-profile
    python -m bench.path_speed --quick             # 40 × 68, 1 run (smoke)

**Speed.** ``path_scene("cornell")`` (``renderer/oracle/path_scenes.py``) traced by ours — every one-pass
method that traces ``integrator=path`` (brute force only when asked) — and by Mitsuba 3's ``path``
integrator (``llvm_ad_rgb``, the scene converted by ``renderer/oracle/mitsuba_scene.py``), at equal size,
samples per pixel and depth (our ``max_recursion_depth`` = Mitsuba's ``max_depth``; Mitsuba's
Russian roulette from our segment, ``rr_depth`` 3), as ``bench/experiments/path.py`` runs them.
Repetitions are interleaved (ours per method, Mitsuba, ours …) so a change of the machine's load
falls on every engine; each engine's first frame is untimed (our variant's compile; Mitsuba's
kernels). Time = the median wall clock of the whole frame: ours ``GLRenderer.render`` (build,
upload, passes, read-back), Mitsuba ``mi.render`` and the read-back of its image. Samples per
second = width × height × spp / time; the ratio is ours / Mitsuba's from the same run.

**Profile** (``bih``): the frame traced by variants of its own shader text, each changed in one
place (:data:`PATCHES`; an anchor that is not found once fails the run), timed interleaved in
process CPU time (llvmpipe's threads included; the wall clock of a shared machine moves more
than the differences measured):

- ``coherent``: every lane of a 4 × 4 block of pixels traces the block's first pixel's samples
  (the same pixel seed and camera rays), so llvmpipe's lanes — 8 pixels run as one — do the same
  work and none waits for another: the same paths' statistics, no divergence;
- ``coherent, trace ×2``: … and every ray traced twice (the second's hit compared with the first's,
  so it cannot be dropped): the difference is one traversal per ray (planes, tree, triangles);
- ``coherent, rnd ×2``: … and every random number hashed twice: the difference is the sampler;
- ``fixed``: the frame at 1 sample and depth 1 (build, upload, one primary ray, read-back).

So the frame = fixed + traversal + sampling + shading (the rest of the loop: surfaces, materials,
next-event estimation, BSDF sampling, the loop's bookkeeping) + lane idle (the frame − coherent).
Rays per sample and the loop's lane use come from the counting variant of
``bench/experiments/path.py`` (``counting_source``): a pixel's rays over a 16-sample pass, mean ÷
max over 4 × 2 pixels (a group runs its loop as long as its slowest lane).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.experiments.path import _QUERY, MITSUBA_VARIANT, RR_DEPTH, counting_source, ours_settings, path_methods
from renderer.gl.renderer import GLRenderer
from renderer.oracle import mitsuba_scene
from renderer.oracle.path_scenes import path_scene

SCENE = "cornell"
SIZE = (320, 544)
SIZE_QUICK = (40, 68)
SPP = 64
DEPTH = 8
RUNS = 3
MITSUBA = "Mitsuba 3 llvm"

# The profile's changes to path_main (shaders/lighting.glsl): (anchor, replacement), each anchor
# found exactly once; "coherent" is made by :func:`patched` itself.
_TRACE = "        Hit h = intersect_scene(q);\n"
PATCHES: dict[str, tuple[tuple[str, str], ...]] = {
    "coherent": (),
    "trace2": (
        (
            _QUERY,
            # The second query differs by a shift the compiler cannot prove zero (done < 2^20), so
            # both traversals run; their hits agree, so the image is the first's.
            _TRACE + "        Query q2 = q; q2.skip = q.skip | (done >> 20);\n"
            "        Hit h2 = intersect_scene(q2);\n"
            "        if (h2.id != h.id) h.t = -1.0;\n" + _QUERY[len(_TRACE) :],
        ),
    ),
    "rnd2": (
        ("uint g_dim;\n", "uint g_dim;\nuint g_junk = 0u;\n"),
        (
            "    g_dim += 1u;\n",
            "    g_dim += 1u;\n    g_junk ^= hash_u(g_sample_seed ^ hash_u(g_dim * 0x85ebca6bu + g_pixel_seed));\n",
        ),
        (
            "    o_image = vec4(sum, float(primary_id));\n",
            "    if (g_junk == 0x9e3779b9u && u_sample_count < 0) sum += vec3(1.0);\n"
            "    o_image = vec4(sum, float(primary_id));\n",
        ),
    ),
}
PROFILE = {
    "frame": (),
    "coherent": ("coherent",),
    "coherent, trace ×2": ("coherent", "trace2"),
    "coherent, rnd ×2": ("coherent", "rnd2"),
}


def patched(src: str, names: tuple[str, ...]) -> str:
    """A path variant's text with the patches ``names`` applied."""
    for name in names:
        for old, new in PATCHES[name]:
            if src.count(old) != 1:
                raise RuntimeError(f"patch {name}: the anchor {old.strip()!r} is not in the path shader once")
            src = src.replace(old, new)
    if "coherent" in names:  # every pixel position path_main reads: the 4 × 4 block's first pixel's
        head, body = src.split("void path_main() {\n", 1)
        main, rest = body.split("\n}\n", 1)  # path_main's closing brace, the first at column 0
        if main.count("gl_FragCoord") < 3:
            raise RuntimeError("patch coherent: path_main reads no pixel position (gl_FragCoord) to replace")
        block = "    vec4 frag = vec4(floor(gl_FragCoord.xy * 0.25) * 4.0 + 0.5, gl_FragCoord.zw);\n"
        src = head + "void path_main() {\n" + block + main.replace("gl_FragCoord", "frag") + "\n}\n" + rest
    return src


class PatchedRenderer(GLRenderer):
    """A GLRenderer whose path variants are compiled from patched text (``patch(src)``)."""

    def __init__(self, patch, **kw: Any) -> None:
        super().__init__(**kw)
        self._patch = patch

    def fragment_text(self, src: str, features: tuple[str, ...]) -> str:
        return self._patch(src) if "PATH" in features else src


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _cpu(fn) -> float:
    """Process CPU time of ``fn`` (llvmpipe's threads included): unlike the wall clock, it does not
    grow with the other jobs of a shared machine, which a difference of two frames cannot afford."""
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def speed(methods: list[str], w: int, h: int, spp: int, depth: int, runs: int, mitsuba: bool, log) -> dict:
    """Median seconds per frame per engine (interleaved), and the samples' mean radiance of each."""
    scene = path_scene(SCENE)
    r = GLRenderer()
    engines: dict[str, Any] = {}
    means: dict[str, float] = {}
    for m in methods:

        def ours(m: str = m) -> None:
            means[m] = float(r.render(scene, ours_settings(m, w, h, spp, depth)).image[..., :3].mean())

        engines[m] = ours
    if mitsuba:
        import mitsuba as mi

        loaded = mitsuba_scene.load(scene, w, h, spp, depth, MITSUBA_VARIANT, 0, rr_depth=RR_DEPTH)

        def theirs() -> None:
            img = mi.render(loaded, spp=spp, seed=0)  # type: ignore[arg-type]
            means[MITSUBA] = float(np.asarray(img, dtype=np.float32)[..., :3].mean())  # waits for the kernels

        engines[MITSUBA] = theirs
    for name, fn in engines.items():  # untimed: compiles our variant, Mitsuba's kernels
        log(f"warm-up {name}")
        fn()
    times: dict[str, list[float]] = {e: [] for e in engines}
    loads = [_load()]
    for k in range(runs):
        for name, fn in engines.items():
            times[name].append(_timed(fn))
            log(f"run {k + 1}/{runs} {name}: {times[name][-1]:.2f} s (load {_load()})")
        loads.append(_load())
    return {"times": times, "mean": means, "load": loads}


def profile(w: int, h: int, spp: int, depth: int, runs: int, log, ctx=None) -> dict:
    """The profile's frames (median CPU seconds, interleaved), the fixed cost, rays and lane use.
    ``ctx``: the GL context to draw with (a caller's own: a new context would become the current one
    in this thread, under the caller's renderer)."""
    scene = path_scene(SCENE)
    settings = ours_settings("bih", w, h, spp, depth)
    plain = PatchedRenderer(lambda s: s, ctx=ctx)
    renderers = {name: PatchedRenderer(lambda s, p=p: patched(s, p), ctx=plain.ctx) for name, p in PROFILE.items()}
    fixed = ours_settings("bih", w, h, 1, 1)
    counter = PatchedRenderer(counting_source, ctx=plain.ctx)
    means: dict[str, float] = {}
    jobs = {
        name: (lambda name=name, r=r: means.__setitem__(name, float(r.render(scene, settings).image[..., :3].mean())))
        for name, r in renderers.items()
    }
    jobs["fixed"] = lambda: plain.render(scene, fixed)
    for name, fn in jobs.items():
        log(f"profile warm-up {name}")
        fn()
    times: dict[str, list[float]] = {n: [] for n in jobs}
    for k in range(runs):
        for name, fn in jobs.items():
            times[name].append(_cpu(fn))
            log(f"profile run {k + 1}/{runs} {name}: {times[name][-1]:.2f} s CPU")
    # Rays per sample (all, and path segments) over the frame; the loop's lane use over one pass.
    img = counter.render(scene, settings).image.astype(np.float64)
    rays, segments = float(img[..., 0].mean()), float(img[..., 1].mean())
    per_pass = counter.render(scene, ours_settings("bih", w, h, 16, depth)).image[..., 0].astype(np.float64)
    g = per_pass[: h // 2 * 2, : w // 4 * 4].reshape(h // 2, 2, w // 4, 4).transpose(0, 2, 1, 3).reshape(-1, 8)
    lane_use = float(g.mean() / g.max(axis=1).mean())
    return {"times": times, "mean": means, "rays": rays, "segments": segments, "lane_use": lane_use}


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def speed_table(d: dict, w: int, h: int, spp: int) -> str:
    med = {e: statistics.median(t) for e, t in d["times"].items()}
    mit = med.get(MITSUBA)
    lines = [_row(["engine", "s per frame (median)", "runs (s)", "Msamples/s", "ours / Mitsuba", "mean radiance"])]
    lines.append("|:---|---:|---:|---:|---:|---:|")
    for e, t in med.items():
        rate = w * h * spp / t / 1e6
        ratio = f"**{mit / t:.2f}×**" if mit is not None and e != MITSUBA else "—"
        runs = " / ".join(f"{x:.2f}" for x in d["times"][e])
        lines.append(
            _row([e if e == MITSUBA else f"ours: {e}", f"{t:.2f}", runs, f"{rate:.3f}", ratio, f"{d['mean'][e]:.4f}"])
        )
    return "\n".join(lines)


def profile_table(p: dict, w: int, h: int, spp: int) -> str:
    med = {n: statistics.median(t) for n, t in p["times"].items()}
    frame, coh = med["frame"], med["coherent"]
    fixed = med["fixed"]
    trav = med["coherent, trace ×2"] - coh
    samp = med["coherent, rnd ×2"] - coh
    shading = coh - fixed - trav - samp
    idle = frame - coh
    rows = [
        ("fixed (build, upload, 1 spp depth 1, read-back)", fixed),
        ("traversal (planes, tree, triangles; coherent lanes)", trav),
        ("sampling (random numbers)", samp),
        ("shading and loop (surfaces, materials, NEE, BSDF, bookkeeping)", shading),
        ("lane idle (frame − coherent)", idle),
    ]
    lines = [_row(["part of the frame", "CPU s", "share"]), "|:---|---:|---:|"]
    for name, t in rows:
        lines.append(_row([name, f"{t:.2f}", f"{t / frame:.0%}"]))
    lines.append(_row(["**frame**", f"**{frame:.2f}**", "100%"]))
    n = w * h * spp
    rays = n * p["rays"]
    variants = ", ".join(f"{k} {v:.2f}" for k, v in med.items())
    lines.append("")
    lines.append(
        f"Variants (median CPU s): {variants}. Rays per sample {p['rays']:.2f} ({p['segments']:.2f} path segments, "
        f"{p['rays'] - p['segments']:.2f} shadow rays): {rays / frame / 1e6:.2f} Mrays per CPU second; per ray "
        f"{frame / rays * 1e9:.0f} ns of CPU, of them traversal {trav / rays * 1e9:.0f} ns. Loop lane use "
        f"(rays per 16-sample pass, mean ÷ max over 4 × 2 pixels): {p['lane_use']:.2f}."
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default=None, help="WxH (default 320x544)")
    ap.add_argument("--spp", type=int, default=SPP)
    ap.add_argument("--depth", type=int, default=DEPTH)
    ap.add_argument("--runs", type=int, default=RUNS)
    ap.add_argument(
        "--methods",
        default=",".join(m for m in path_methods() if m != "bruteforce"),
        help="comma-separated (bruteforce only if named: it is no contender)",
    )
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--no-speed", action="store_true", help="the profile only")
    ap.add_argument("--no-profile", action="store_true")
    ap.add_argument("--profile-size", default=None, help="WxH of the profile's frames (default: --size)")
    ap.add_argument("--quick", action="store_true", help="40 × 68, 1 run")
    ap.add_argument("--json", type=Path, help="write the raw measurements here")
    ap.add_argument("-v", "--verbose", action="store_true", help="each frame's time on stderr")
    a = ap.parse_args(argv)
    w, h = (int(x) for x in a.size.split("x")) if a.size else (SIZE_QUICK if a.quick else SIZE)
    pw, ph = (int(x) for x in a.profile_size.split("x")) if a.profile_size else (w, h)
    runs = 1 if a.quick else a.runs
    methods = [m for m in a.methods.split(",") if m]

    def log(msg: str) -> None:
        if a.verbose:
            print(msg, file=sys.stderr, flush=True)

    gl = GLRenderer().info
    print(
        f"# path integrator, {SCENE}, {w} × {h}, {a.spp} spp, depth {a.depth} (Mitsuba rr_depth {RR_DEPTH}), "
        f"{runs} interleaved runs; GL: {gl['renderer']}; {os.cpu_count()} CPUs; "
        f"DRJIT_LIBLLVM_PATH={os.environ.get('DRJIT_LIBLLVM_PATH', 'default')}"
    )
    out: dict[str, Any] = {"size": [w, h], "spp": a.spp, "depth": a.depth, "runs": runs, "gl": gl}
    if not a.no_speed:
        d = speed(methods, w, h, a.spp, a.depth, runs, not a.no_mitsuba, log)
        out["speed"] = d
        print(f"\n## Speed (load average during: {' → '.join(map(str, d['load']))})\n")
        print(speed_table(d, w, h, a.spp), flush=True)
    if not a.no_profile:
        load0 = _load()
        p = profile(pw, ph, a.spp, a.depth, runs, log)
        out["profile"] = p
        print(f"\n## Where the time goes (bih, {pw} × {ph}, {a.spp} spp; load average {load0} → {_load()})\n")
        print(profile_table(p, pw, ph, a.spp))
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
