"""The README's pictures, made by the engine and the client (not by hand):

- ``docs/figures/readme_frame.png`` — a rendered frame: thesis scenario 3, 4,096 spheres,
  BIH, 640 × 1088 with the service's 'still' profile;
- ``docs/figures/readme_modes.png`` — a gallery of the render modes of that scene (each
  mode labelled);
- ``docs/figures/readme_phone.png`` — the browser client on a phone-sized screen (headless
  Chromium through Playwright, as tests/browser does), against a service started for it.

Run: ``.venv/bin/python scripts/readme_images.py [--only frame,modes,phone]`` (about a
minute here). The client is being polished: re-run it to retake the screenshot.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "browser"))

FIGURES = ROOT / "docs" / "figures"
SCENE = dict(number=3, n=4096, seed=0)
GALLERY_MODES = ("color", "normal", "depth", "primid", "recursion", "heat", "cones")
GALLERY_SIZE = (240, 408)  # width, height of one tile (the phone's 640 × 1088 aspect)


def scene():
    from renderer.scenes.scenarios import scenario

    return scenario(SCENE["number"], SCENE["n"], SCENE["seed"])


def frame(renderer) -> Path:
    from PIL import Image

    from renderer.config.settings import RenderSettings
    from renderer.frame.profiles import STILL

    still = {k: v for k, v in STILL.items() if k in RenderSettings.__dataclass_fields__}
    res = renderer.render(scene(), RenderSettings(method="bih", width=640, height=1088, **still))
    out = FIGURES / "readme_frame.png"
    Image.fromarray(res.image_u8(), "RGB").save(out, optimize=True)
    return out


def modes(renderer) -> Path:
    from PIL import Image, ImageDraw

    from renderer.config.settings import RenderSettings

    w, h = GALLERY_SIZE
    tiles = []
    for mode in GALLERY_MODES:
        method = "hre" if mode == "cones" else "bih"
        res = renderer.render(
            scene(),
            RenderSettings(method=method, mode=mode, width=w, height=h, max_recursion_depth=5, samples_per_pixel=1),
        )
        tile = Image.fromarray(res.image_u8(), "RGB")
        draw = ImageDraw.Draw(tile)
        label = mode if mode != "cones" else "cones (hre)"
        draw.rectangle([0, 0, 8 + 7 * len(label), 18], fill=(0, 0, 0))
        draw.text((4, 3), label, fill=(255, 255, 255))
        tiles.append(tile)
    gap = 6
    sheet = Image.new("RGB", (len(tiles) * w + (len(tiles) - 1) * gap, h), (255, 255, 255))
    for i, tile in enumerate(tiles):
        sheet.paste(tile, (i * (w + gap), 0))
    out = FIGURES / "readme_modes.png"
    sheet.save(out, optimize=True)
    return out


def phone() -> Path:
    from browser_support import CHROMIUM, CHROMIUM_ARGS, Server
    from playwright.sync_api import sync_playwright

    query = "scenario=3&n=4096&seed=0&width=320&height=544&max_recursion_depth=3"
    out = FIGURES / "readme_phone.png"
    with tempfile.TemporaryDirectory() as tmp:
        server = Server(Path(tmp))
        server.start()
        try:
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
                ctx = browser.new_context(
                    viewport={"width": 360, "height": 740}, device_scale_factor=2, is_mobile=True, has_touch=True
                )
                page = ctx.new_page()
                page.goto(f"{server.base}/?{query}")
                # The first frames: wait until the client has shown one and is idle.
                page.wait_for_function("() => document.querySelector('canvas, img') !== null", timeout=60_000)
                page.wait_for_timeout(6_000)
                page.screenshot(path=str(out))
                browser.close()
        finally:
            server.stop()
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", default="frame,modes,phone", help="comma-separated: frame, modes, phone")
    args = p.parse_args(argv)
    which = set(args.only.split(","))
    FIGURES.mkdir(parents=True, exist_ok=True)
    made = []
    if which & {"frame", "modes"}:
        from renderer.gl.renderer import GLRenderer

        renderer = GLRenderer()
        if "frame" in which:
            made.append(frame(renderer))
        if "modes" in which:
            made.append(modes(renderer))
    if "phone" in which:
        made.append(phone())
    for path in made:
        print(f"{path.relative_to(ROOT)}: {path.stat().st_size:,} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
