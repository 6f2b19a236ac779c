"""``docs/figures/readme_cornell_path_mitsuba.png``: the Cornell-box demo scene (``mesh_scene("cornell")``,
flat-shaded so both renderers see the same triangles) by our path integrator (left) and by
Mitsuba 3's ``path`` integrator (right, ``scalar_rgb``, the scene made by
``renderer/oracle/mitsuba_scene.py``), 192², 1,024 samples, depth 8, both tone-mapped with ACES; prints
the times, the PSNR of the radiance clipped to [0, 1] and the image means.

Run: ``.venv/bin/python scripts/cornell_figure.py`` (about six minutes here).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from PIL import Image

from renderer.config.settings import RenderSettings
from renderer.gl.renderer import GLRenderer
from renderer.image.tonemap import display_u8
from renderer.oracle import mitsuba_scene
from renderer.scenes.scenarios import mesh_scene

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures" / "readme_cornell_path_mitsuba.png"
SIDE, SPP, DEPTH = 192, 1024, 8


def main() -> None:
    scene = mesh_scene("cornell", 2, smooth=False)
    t = time.perf_counter()
    ours = (
        GLRenderer()
        .render(
            scene,
            RenderSettings(
                width=SIDE,
                height=SIDE,
                integrator="path",
                samples_per_pixel=SPP,
                max_recursion_depth=DEPTH,
                format="npy",
            ),
        )
        .image
    )
    t_ours = time.perf_counter() - t
    t = time.perf_counter()
    ref = mitsuba_scene.render(scene, SIDE, SIDE, SPP, DEPTH)
    t_mi = time.perf_counter() - t
    mse = float(np.mean((np.clip(ours, 0, 1) - np.clip(ref, 0, 1)) ** 2))
    print(
        json.dumps(
            {
                "ours_s": t_ours,
                "mitsuba_s": t_mi,
                "psnr_db": -10 * np.log10(mse),
                "mean_ours": float(ours.mean()),
                "mean_mitsuba": float(ref.mean()),
            }
        )
    )
    gap = np.full((SIDE, 4, 3), 255, np.uint8)
    Image.fromarray(np.concatenate([display_u8(ours, "aces", 0.0), gap, display_u8(ref, "aces", 0.0)], axis=1)).save(
        OUT
    )


if __name__ == "__main__":
    main()
