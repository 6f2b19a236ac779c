"""The phone client's footprint, device-mode latency and the service's frames, in headless Chromium.

Three measurements, on a phone profile (390 × 844 CSS px at device pixel ratio 3, touch
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
- **the service's frames** (``server_timeline``, ``--only server``): navigation → the first image
  → the final (supersampled) one, from the navigation's start on the page's clock; a 10-step
  one-finger drag → the first image asked for after its last move, and the full frame; a 4 s drag
  (a touch move every 16 ms) → the previews shown per second and their sizes — for the default
  page (Whitted) and ``?scenario=mesh:cornell&integrator=path`` (``SERVER_PAGES``).
  ``python -m bench.experiments --only client`` runs it for this client and the one before and
  writes its section of ``docs/RESULTS.md``.

``--client-dir DIR`` serves another client (e.g. an older one exported with
``git archive <rev> client_web | tar -x -C /tmp/old``) from the same service, for a
before/after comparison.

Usage::

    .venv/bin/python -m bench.client                         # this client
    .venv/bin/python -m bench.client --only server --move-s 4  # only the service's frames
    .venv/bin/python -m bench.client --client-dir /tmp/old/client_web
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
import urllib.parse
from pathlib import Path

import httpx

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


class Touch:
    """Touch input through CDP's ``Input.dispatchTouchEvent`` (each call returns once the page took it)."""

    def __init__(self, cdp):
        self.cdp = cdp

    def send(self, kind: str, pts) -> None:
        self.cdp.send(
            "Input.dispatchTouchEvent",
            {
                "type": kind,
                "touchPoints": [
                    {"x": x, "y": y, "id": i, "radiusX": 5, "radiusY": 5, "force": 1} for i, (x, y) in enumerate(pts)
                ],
            },
        )


def device_latency(browser, url: str, query: str, steps: int = 10) -> dict:
    ctx = browser.new_context(**PORTRAIT)
    try:
        page = ctx.new_page()
        page.goto(f"{url}/?{query}")
        wait_full(page, 1)
        dismiss_hint(page)
        if page.evaluate("() => window.pocketray.lastFrame.renderer") != "device":
            raise SystemExit("device mode did not start (no WebGL2?)")
        touch = Touch(ctx.new_cdp_session(page)).send

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


# The server-mode pages: the default page (scenario 1, 512 spheres, the fit resolution, the service's
# still profile) and the Cornell box with the path integrator, each a link.
SERVER_PAGES = {"whitted": "", "path": "scenario=mesh:cornell&integrator=path"}
SHOWN_LOG = """() => { window.__shown = []; const poll = () => { const p = window.pocketray;
  if (p && p.frameCount !== (window.__last || 0)) { window.__last = p.frameCount; const f = p.lastFrame;
  window.__shown.push([performance.now(), f.level, f.part || 'final', f.width, f.height, f.clientMs]); }
  requestAnimationFrame(poll); }; poll(); }"""


def server_timeline(browser, url: str, query: str, move_s: float = 4.0, client_dir: str | None = None) -> dict:
    """The service's frames on the phone viewport: navigation → first image → final image (from the
    navigation's start, the page's clock); a 10-step one-finger drag → the first image after the
    last touch and the full frame; then a drag of ``move_s`` seconds (a touch move every 16 ms):
    the previews shown per second while it moves, and their sizes."""
    ctx = browser.new_context(**PORTRAIT)
    try:
        ctx.add_init_script(f"({SHOWN_LOG})()")
        page = ctx.new_page()
        page.goto(f"{url}/?{query}")
        wait_full(page, 1)
        page.wait_for_function("() => window.pocketray.lastFrame.part !== 'preview'", timeout=300_000)
        load = page.evaluate("() => window.__shown")
        dismiss_hint(page)
        # A client whose links cannot set the integrator (the one before): set on its session through
        # the API, so that its gestures' previews are the path integrator's too (its load is not).
        set_by = "link"
        want = dict(urllib.parse.parse_qsl(query)).get("integrator")
        if want:
            sid = page.evaluate("() => window.pocketray.sessionId")
            got = httpx.get(f"{url}/api/sessions/{sid}").json()["settings"].get("integrator")
            if got != want:
                httpx.patch(f"{url}/api/sessions/{sid}/settings", json={"integrator": want}).raise_for_status()
                set_by, load = "api (the link could not)", []
        touch = Touch(ctx.new_cdp_session(page))
        # A gesture → its first image and the full frame.
        n0 = page.evaluate("() => window.pocketray.frameCount")
        touch.send("touchStart", [(150, 400)])
        for k in range(1, 10):
            touch.send("touchMove", [(150 + 8 * k, 400)])
        t_end = page.evaluate("() => performance.now()")
        touch.send("touchMove", [(230, 400)])
        touch.send("touchEnd", [])
        wait_full(page, n0 + 1)
        page.wait_for_function("() => window.pocketray.lastFrame.part !== 'preview'", timeout=300_000)
        # The images asked for after the last move reached the page (shown − its time since the request):
        # the first shows where the finger stopped.
        after = [e for e in page.evaluate("() => window.__shown") if e[0] - e[5] >= t_end]
        # A long drag: previews per second while the finger moves.
        n1 = len(page.evaluate("() => window.__shown"))
        touch.send("touchStart", [(195, 400)])
        t_move0 = page.evaluate("() => performance.now()")
        t0 = time.perf_counter()
        k = 0
        while time.perf_counter() - t0 < move_s:
            k += 1
            touch.send("touchMove", [(195 + 60 * math.sin(k / 20), 400 + 20 * math.sin(k / 31))])
            time.sleep(max(0.0, t0 + k * 0.016 - time.perf_counter()))
        t_move1 = page.evaluate("() => performance.now()")
        touch.send("touchEnd", [])
        wait_full(page, 1)
        during = [e for e in page.evaluate("() => window.__shown")[n1:] if t_move0 <= e[0] <= t_move1]
        # The rate once the preview size has settled: the last half of the drag.
        half = [e for e in during if e[0] >= (t_move0 + t_move1) / 2]
        full_final = next((e for e in load if e[1] == "full" and e[2] == "final"), None)
        first = load[0] if load else None
        return {
            "load_first_image_s": first[0] / 1e3 if first else None,
            "load_first_size": f"{first[3]}x{first[4]}" if first else None,
            "load_final_image_s": full_final[0] / 1e3 if full_final else None,
            "load_first_over_final": first[0] / full_final[0] if first and full_final else None,
            "load_images": len(load),
            "gesture_first_image_s": (after[0][0] - t_end) / 1e3 if after else None,
            "gesture_full_image_s": next(
                ((e[0] - t_end) / 1e3 for e in after if e[1] == "full" and e[2] == "final"), None
            ),
            "moving_previews_per_s": len(during) / ((t_move1 - t_move0) / 1e3),
            "moving_previews_per_s_2nd_half": len(half) / ((t_move1 - t_move0) / 2e3),
            "moving_preview_sizes": sorted({f"{e[3]}x{e[4]}" for e in during}),
            "touch_moves": k,
            "integrator_set_by": set_by,
        }
    finally:
        ctx.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--client-dir", help="serve this client folder instead of client_web/")
    ap.add_argument("--url", help="an already running service (its own client)")
    ap.add_argument("--skip-device", action="store_true", help="no device-mode drag")
    ap.add_argument(
        "--only", default="share,device,server", help="parts: share (chrome share), device (drag), server (timelines)"
    )
    ap.add_argument("--move-s", type=float, default=4.0, help="the long drag's duration (server timelines)")
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
            parts = set(args.only.split(","))
            if "server" in parts:
                out["server"] = {}
                for name, query in SERVER_PAGES.items():
                    server_timeline(browser, url, query, move_s=0.5)  # warm: the service compiles its variants
                    out["server"][name] = server_timeline(browser, url, query, move_s=args.move_s)
            if "share" in parts:
                out["chrome_share"] = {
                    "portrait, scenario 1": chrome_share(browser, url, PORTRAIT, f"scenario=1&n=64&{LAYOUT_QUERY}"),
                    "portrait, museum": chrome_share(
                        browser, url, PORTRAIT, f"scenario=museum&n=16&motion=rigid&{LAYOUT_QUERY}"
                    ),
                    "landscape, scenario 1": chrome_share(browser, url, LANDSCAPE, f"scenario=1&n=64&{LAYOUT_QUERY}"),
                }
            if "device" in parts and not args.skip_device:
                out["device_drag"] = device_latency(browser, url, args.device_query)
            browser.close()
    finally:
        if server:
            server.close()
    out["load_average"] = os.getloadavg()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
