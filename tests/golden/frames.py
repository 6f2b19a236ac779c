"""The frame catalogue: tiny frames of every one-pass method × mode × integrator on a few scenes.

``frames.npz`` holds, for every case of :func:`cases`, the float image, the depth and the
primary ids of the frame rendered by the code **at commit** :data:`BASE_COMMIT` — the shader
assembled from marks and sections, before the shaders were made of whole chunks. It is a
regression oracle (what the service rendered then, bit for bit), not a correctness oracle
(the float64 reference and Mitsuba tests are those). ``tests/golden/test_frames.py`` renders
the same cases with the code under test and compares.

It was made once, from a worktree of the base commit, never from the code it checks::

    git -C /work/main worktree add /tmp/base-chunks 4d332a2
    .venv/bin/python -m tests.golden.frames --write /tmp/base-chunks

``--write ROOT`` runs this file in a subprocess whose ``renderer`` and ``shaders`` are ROOT's
(``--emit``), so the frames come from that checkout's engine.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

FRAMES = Path(__file__).with_name("frames.npz")
BASE_COMMIT = "4d332a2"

W, H = 24, 16
METHODS = ("bih", "bruteforce", "bvh", "kdtree", "twolevel")
MODES = ("color", "depth", "primid", "normal", "recursion", "heat")
# Path-traced frames: a few paths of a few segments (the path integrator draws colour only).
PATH = {"integrator": "path", "samples_per_pixel": 2, "max_recursion_depth": 4}


def scenes() -> dict[str, Any]:
    """The catalogue's scenes, framed for W × H: spheres with planes, spheres under the sky (an
    environment map), triangles with spheres, analytic shapes with a light, and the Cornell box
    (emitting triangles)."""
    from renderer.scenes.scenarios import framed, mesh_scene, scenario

    aspect = W / H
    return {
        "spheres": framed(scenario(3, 48, seed=1), aspect),
        "sky": framed(scenario(2, 32, seed=1, sky=True), aspect),
        "mesh": framed(mesh_scene("mixed", detail=0), aspect),
        "shapes": framed(mesh_scene("table", detail=0), aspect),
        "cornell": mesh_scene("cornell", detail=0),
    }


def cases() -> list[tuple[str, str, dict[str, Any]]]:
    """(key, scene name, settings) of every frame: on spheres, triangles and shapes each method ×
    mode (Whitted); under the sky and in the Cornell box each method's colour; the path integrator
    where light is more than the point lights' (sky, shapes, Cornell box); the generic
    (unspecialised) colour variant on triangles."""
    modes = {"spheres": MODES, "mesh": MODES, "shapes": MODES, "sky": ("color",), "cornell": ("color",)}
    out = []
    for scene in scenes():
        for method in METHODS:
            for mode in modes[scene]:
                out.append((f"{scene}/{method}/{mode}", scene, {"method": method, "mode": mode}))
            if scene in ("sky", "shapes", "cornell"):
                out.append((f"{scene}/{method}/path", scene, {"method": method, **PATH}))
            if scene == "mesh":
                out.append((f"{scene}/{method}/generic", scene, {"method": method, "specialize": False}))
    return out


def render_all(scene: str) -> dict[str, np.ndarray]:
    """The cases of ``scene`` rendered by the engine importable here: arrays named ``<key>/<array>``.
    (Each method's compiled variants are released after its frames: llvmpipe keeps megabytes per
    program.)"""
    from renderer.config.settings import RenderSettings
    from renderer.gl import GLRenderer

    sc = scenes()
    r = GLRenderer()
    out: dict[str, np.ndarray] = {}
    for key, name, kw in cases():
        if name != scene:
            continue
        res = r.render(sc[name], RenderSettings(width=W, height=H, **kw))
        out[f"{key}/image"] = np.asarray(res.image, np.float32)
        out[f"{key}/depth"] = np.asarray(res.depth, np.float32)
        out[f"{key}/primid"] = np.asarray(res.primid, np.int32)
        r.programs.clear()
        print(key, file=sys.stderr, flush=True)
    return out


def main(argv: list[str]) -> None:
    if argv[:1] == ["--emit"]:  # --emit SCENE OUT.npz
        np.savez_compressed(argv[2], **render_all(argv[1]))
        return
    if argv[:1] != ["--write"] or len(argv) != 2:
        sys.exit("usage: python -m tests.golden.frames --write BASE_WORKTREE")
    root = Path(argv[1]).resolve()
    arrays: dict[str, np.ndarray] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes():  # a process per scene: each frees all it compiled
            part = Path(tmp) / f"{scene}.npz"
            argv_ = [__file__, "--emit", scene, str(part)]
            code = (
                f"import sys; sys.path.insert(0, {str(root)!r}); sys.argv = {argv_!r}; "
                f"import runpy; runpy.run_path({__file__!r}, run_name='__main__')"
            )
            subprocess.run([sys.executable, "-c", code], cwd=root, check=True)
            with np.load(part) as z:
                arrays.update({k: z[k] for k in z.files})
    np.savez_compressed(FRAMES, **arrays)
    print(f"wrote {FRAMES} ({len(arrays) // 3} frames) from {root}")


if __name__ == "__main__":
    main(sys.argv[1:])
