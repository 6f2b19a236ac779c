"""The phone client's footprint and device-mode latency (issue #19), in headless Chromium.

Two measurements, on a phone profile (390 × 844 CSS px at device pixel ratio 3, touch
through the DevTools protocol, as the browser tests):

- **chrome share**: the part of the screen the controls cover — the union of the
  bounding boxes of the toolbar, the statistics overlay and any banner (clipped to the
  screen), over the screen's area — for a thesis scenario (three toolbar buttons in the
  old client), the museum (four) and landscape (844 × 390). Measured after the first full
  frame, with the one-time gesture hint dismissed.
- **gesture → image in device mode** (WebGL2 on ANGLE/SwiftShader here): a 10-step
  one-finger drag sent with ``Input.dispatchTouchEvent`` (each call returns once the
  page has taken the event, so a main thread blocked by a frame delays it); then the
  time from the last touch to the first frame showing the moved camera and to the full
  frame. ``delivered`` = the drag's ten moves from the first to the last.

``--client-dir DIR`` serves another client (e.g. an older one exported with
``git archive <rev> client_web | tar -x -C /tmp/old``) from the same service, for a
before/after comparison.

Usage::

    .venv/bin/python -m bench.client                         # this client
    .venv/bin/python -m bench.client --client-dir /tmp/old/client_web
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from bench.child import ServerChild

ROOT = Path(__file__).resolve().parent.parent

CHROMIUM = os.environ.get("POCKETRAY_CHROMIUM", "/usr/bin/chromium")
GL_ARGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]
PORTRAIT = dict(viewport={"width": 390, "height": 844}, device_scale_factor=3, is_mobile=True, has_touch=True)
LANDSCAPE = dict(viewport={"width": 844, "height": 390}, device_scale_factor=3, is_mobile=True, has_touch=True)
# Small frames: the layout does not depend on the frame's size, and the bench should not wait for llvmpipe.
LAYOUT_QUERY = "width=96&height=160&max_recursion_depth=2&preview_scale=1"

CHROME_SHARE = """() => {
  const W = innerWidth, H = innerHeight;
  const boxes = ['#toolbar', '#overlay', '#banner'].map((s) => document.querySelector(s))
    .filter((e) => e && e.getClientRects().length && getComputedStyle(e).visibility !== 'hidden')
    .map((e) => e.getBoundingClientRect())
    .map((r) => [Math.max(0, r.left), Math.max(0, r.top), Math.min(W, r.right), Math.min(H, r.bottom)])
    .filter(([l, t, r, b]) => r > l && b > t);
  // Union area on a 1-px grid (a handful of boxes: exact enough and simple).
  const xs = [...new Set(boxes.flatMap((b) => [b[0], b[2]]))].sort((a, b) => a - b);
  let area = 0;
  for (let i = 0; i + 1 < xs.length; i++) {
    const x0 = xs[i], x1 = xs[i + 1];
    const spans = boxes.filter((b) => b[0] <= x0 && b[2] >= x1).map((b) => [b[1], b[3]]).sort((a, b) => a[0] - b[0]);
    let covered = 0, top = -Infinity;
    for (const [t, b] of spans) { if (b > top) { covered += b - Math.max(t, top); top = b; } }
    area += covered * (x1 - x0);
  }
  return {share: area / (W * H), boxes: boxes.length};
}"""


class Server(ServerChild):
    """A server child (bench/child.py), optionally serving another client folder."""

    def __init__(self, client_dir: str | None):
        super().__init__(ROOT, {"client_dir": Path(client_dir).resolve()} if client_dir else {}, timeout_s=120)


def wait_full(page, min_frames: int, timeout_ms: float = 300_000) -> None:
    page.wait_for_function(
        """n => { const p = window.pocketray; return p && p.idle && p.frameCount >= n && p.lastFrame
                  && p.lastFrame.level === 'full'; }""",
        arg=min_frames,
        timeout=timeout_ms,
    )


def dismiss_hint(page) -> None:
    page.evaluate("() => { const b = document.querySelector('#hint [data-dismiss]'); if (b) b.click(); }")


def chrome_share(browser, url: str, profile: dict, query: str) -> float:
    ctx = browser.new_context(**profile)
    try:
        page = ctx.new_page()
        page.goto(f"{url}/?{query}")
        wait_full(page, 1)
        dismiss_hint(page)
        page.wait_for_timeout(300)
        return page.evaluate(CHROME_SHARE)["share"]
    finally:
        ctx.close()


def device_latency(browser, url: str, query: str, steps: int = 10) -> dict:
    ctx = browser.new_context(**PORTRAIT)
    try:
        page = ctx.new_page()
        page.goto(f"{url}/?{query}")
        wait_full(page, 1)
        dismiss_hint(page)
        if page.evaluate("() => window.pocketray.lastFrame.renderer") != "device":
            raise SystemExit("device mode did not start (no WebGL2?)")
        cdp = ctx.new_cdp_session(page)

        def touch(kind: str, pts) -> None:
            cdp.send(
                "Input.dispatchTouchEvent",
                {
                    "type": kind,
                    "touchPoints": [
                        {"x": x, "y": y, "id": i, "radiusX": 5, "radiusY": 5, "force": 1}
                        for i, (x, y) in enumerate(pts)
                    ],
                },
            )

        n0 = page.evaluate("() => window.pocketray.frameCount")
        page.evaluate(
            "() => { window.__shown = []; const p = window.pocketray; let last = p.frameCount;"
            " (function poll() { if (p.frameCount !== last) { last = p.frameCount;"
            " window.__shown.push([performance.now(), p.lastFrame.level]); } requestAnimationFrame(poll); })(); }"
        )
        touch("touchStart", [(150, 400)])
        t0 = time.perf_counter()
        for k in range(1, steps + 1):
            touch("touchMove", [(150 + 8 * k, 400)])
        delivered = time.perf_counter() - t0
        t_end_page = page.evaluate("() => performance.now()")
        touch("touchEnd", [])
        wait_full(page, n0 + 1)
        shown = page.evaluate("() => window.__shown")
        after = [t for t, _ in shown if t >= t_end_page]
        full = [t for t, level in shown if level == "full" and t >= t_end_page]
        return {
            "delivered_s": delivered,
            "first_image_s": (after[0] - t_end_page) / 1e3 if after else None,
            "full_image_s": (full[-1] - t_end_page) / 1e3 if full else None,
            "frames_during": len([t for t, _ in shown if t < t_end_page]),
        }
    finally:
        ctx.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--client-dir", help="serve this client folder instead of client_web/")
    ap.add_argument("--url", help="an already running service (its own client)")
    ap.add_argument("--skip-device", action="store_true", help="only the chrome share")
    ap.add_argument(
        "--device-query",
        default="scenario=1&n=512&renderer=device",
        help="the page of the drag (the session's defaults: fit resolution, the still profile)",
    )
    args = ap.parse_args()

    from playwright.sync_api import sync_playwright

    server = None if args.url else Server(args.client_dir)
    url = args.url or server.url
    out: dict = {}
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=GL_ARGS, headless=True)
            out["chrome_share"] = {
                "portrait, scenario 1": chrome_share(browser, url, PORTRAIT, f"scenario=1&n=64&{LAYOUT_QUERY}"),
                "portrait, museum": chrome_share(
                    browser, url, PORTRAIT, f"scenario=museum&n=16&motion=rigid&{LAYOUT_QUERY}"
                ),
                "landscape, scenario 1": chrome_share(browser, url, LANDSCAPE, f"scenario=1&n=64&{LAYOUT_QUERY}"),
            }
            if not args.skip_device:
                out["device_drag"] = device_latency(browser, url, args.device_query)
            browser.close()
    finally:
        if server:
            server.close()
    out["load_average"] = os.getloadavg()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
