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
    .venv/bin/python -m bench.client --only dense              # previews/s at 4,096 spheres
    .venv/bin/python -m bench.client --client-dir /tmp/old/client_web
"""

from __future__ import annotations

import argparse
import base64
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


def phone_page(browser, url: str, query: str):
    """A new phone-sized context (PORTRAIT) and its page opened at ``query``, logging every frame it
    shows (``window.__shown``); the caller closes the context."""
    ctx = browser.new_context(**PORTRAIT)
    try:
        ctx.add_init_script(f"({SHOWN_LOG})()")
        page = ctx.new_page()
        page.goto(f"{url}/?{query}")
    except BaseException:
        ctx.close()
        raise
    return ctx, page


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
# Every frame shown: its time, level, part, size, request → screen ms, and the service's total and trace ms
# (its Server-Timing; null where the client does not keep it).
SHOWN_LOG = """() => { window.__shown = []; const poll = () => { const p = window.pocketray;
  if (p && p.frameCount !== (window.__last || 0)) { window.__last = p.frameCount; const f = p.lastFrame;
  const t = f.timing || {};
  window.__shown.push([performance.now(), f.level, f.part || 'final', f.width, f.height, f.clientMs,
    t.total ?? null, t.trace ?? null]); }
  requestAnimationFrame(poll); }; poll(); }"""


# Dense scenes on the phone viewport (the default page's settings otherwise): previews per second while
# a finger moves, the client asking for the service's interactive profile (``--only dense``).
DENSE_PAGES = {
    "whitted, scenario 3, 4,096 spheres": "scenario=3&n=4096",
    "whitted, scenario 2, 4,096 spheres": "scenario=2&n=4096",
}


def _median(xs: list) -> float | None:
    xs = sorted(x for x in xs if x is not None)
    return None if not xs else (xs[len(xs) // 2] + xs[(len(xs) - 1) // 2]) / 2


def short_drag(page, touch: Touch) -> float:
    """A one-finger drag of 80 px in ten moves across the view; the page's clock (ms) just before
    the last move: a frame asked for after it shows where the finger stopped."""
    touch.send("touchStart", [(150, 400)])
    for k in range(1, 10):
        touch.send("touchMove", [(150 + 8 * k, 400)])
    t_end = page.evaluate("() => performance.now()")
    touch.send("touchMove", [(230, 400)])
    touch.send("touchEnd", [])
    return t_end


def server_timeline(browser, url: str, query: str, move_s: float = 4.0, client_dir: str | None = None) -> dict:
    """The service's frames on the phone viewport: navigation → first image → final image (from the
    navigation's start, the page's clock); a 10-step one-finger drag → the first image after the
    last touch and the full frame; then a drag of ``move_s`` seconds (a touch move every 16 ms):
    the previews shown per second while it moves, and their sizes."""
    ctx, page = phone_page(browser, url, query)
    try:
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
        t_end = short_drag(page, touch)
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
            # Where a preview's time goes (medians over the drag): request → screen on the page, and
            # the service's part of it (admission → encoded body) and its trace.
            "moving_client_ms": _median([e[5] for e in during]),
            "moving_server_ms": _median([e[6] for e in during if len(e) > 6]),
            "moving_trace_ms": _median([e[7] for e in during if len(e) > 7]),
            "touch_moves": k,
            "integrator_set_by": set_by,
        }
    finally:
        ctx.close()


# A drag begun while the table's full frame (Whitted, the phone's fit resolution) is in flight
# (``--only abandon``), and the views at rest refined on the phone viewport (``--only rest``).
ABANDON_QUERY = "scenario=mesh:table&integrator=whitted"
REST_PAGES = {
    "cornell, path": "scenario=mesh:cornell&integrator=path",
    "table, path": "scenario=mesh:table&integrator=path",
}


def _first_preview_after(page, t: float, timeout_s: float = 120.0) -> float | None:
    """The page's clock (ms) from `t` to the first preview shown after it (its request made after `t`)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        hit = [e for e in page.evaluate("() => window.__shown") if e[1] == "preview" and e[0] - (e[5] or 0) >= t]
        if hit:
            return hit[0][0] - t
        time.sleep(0.02)
    return None


def _drag_from(page, touch: Touch, x: float, y: float, moves: int = 6) -> float:
    """A drag of `moves` touch moves 16 ms apart from (x, y); the page's clock at its first move."""
    touch.send("touchStart", [(x, y)])
    t = page.evaluate("() => performance.now()")
    for k in range(1, moves + 1):
        touch.send("touchMove", [(x + 6 * k, y)])
        time.sleep(0.016)
    touch.send("touchEnd", [])
    return t


def abandon_latency(browser, url: str, query: str = ABANDON_QUERY, repeats: int = 3) -> dict:
    """The first preview of a drag at rest (nothing in flight but the refinement stream) against that
    of a drag begun while the full frame is in flight (0.5 s after the previous drag's preview: the
    full frame is asked for 0.2 s after the last gesture and takes seconds here), the page's clock,
    from the first touch move to the preview on screen."""
    ctx, page = phone_page(browser, url, query)
    try:
        wait_full(page, 1)
        dismiss_hint(page)
        touch = Touch(ctx.new_cdp_session(page))
        rest, busy, full_ms = [], [], []
        for _ in range(repeats):
            wait_full(page, 1)
            time.sleep(0.3)
            t = _drag_from(page, touch, 150, 400)
            rest.append(_first_preview_after(page, t))
            time.sleep(0.5)  # the full frame of the moved view is in flight now
            t = _drag_from(page, touch, 150, 420)
            busy.append(_first_preview_after(page, t))
        wait_full(page, 1)
        shown = page.evaluate("() => window.__shown")
        full_ms = [e[5] for e in shown if e[1] == "full" and e[2] == "final"]
        size = next((f"{e[3]}x{e[4]}" for e in shown if e[1] == "full"), None)
        r, b = _median(rest), _median(busy)
        return {
            "rest_first_preview_ms": r,
            "in_flight_first_preview_ms": b,
            "ratio": b / r if r and b else None,
            "rest_all_ms": rest,
            "in_flight_all_ms": busy,
            "full_frame_ms_median": _median(full_ms),
            "full_size": size,
        }
    finally:
        ctx.close()


def rest_convergence(browser, url: str, query: str, watch_s: float = 90.0) -> dict:
    """A page left at rest for `watch_s`: its first image, its first full-size image and the samples
    the refinement reaches, with the time (from the navigation's start, the page's clock)."""
    ctx, page = phone_page(browser, url, query)
    try:
        t0 = time.monotonic()
        parts: list = []
        while time.monotonic() - t0 < watch_s:
            time.sleep(1.0)
            parts = page.evaluate(
                "() => (window.pocketray && window.pocketray.refinement ? window.pocketray.refinement.parts : [])"
            )
            if parts and parts[-1]["done"]:
                break
        shown = page.evaluate("() => window.__shown")
        samples = page.evaluate("() => window.pocketray.lastFrame && window.pocketray.lastFrame.samples")
        full = next((e for e in shown if e[1] == "full"), None)
        return {
            "first_image_s": shown[0][0] / 1e3 if shown else None,
            "first_full_s": full[0] / 1e3 if full else None,
            "full_size": f"{full[3]}x{full[4]}" if full else None,
            "samples_reached": samples,
            "reached_at_s": shown[-1][0] / 1e3 if shown else None,
            "refine_parts": len(parts),
            "refine_done": bool(parts and parts[-1]["done"]),
            "reason": parts[-1]["reason"] if parts else None,
            "watched_s": watch_s,
        }
    finally:
        ctx.close()


def picker_scenes(
    browser, url: str, timeout_ms: float = 600_000, only: tuple[str, ...] = (), extra: str = ""
) -> list[dict]:
    """Every scene of the picker (renderer/scenes/scenarios.py's DEMO_SCENES; ``only``: these values) opened by
    its link on the phone viewport with nothing else asked (``extra``: more of the query): the integrator
    the session opened with, the size of its first full frame, the page's notices and errors, and the
    time from the navigation to that frame."""
    from renderer.scenes.scenarios import DEMO_SCENES

    rows = []
    for d in DEMO_SCENES:
        if only and str(d.value) not in only:
            continue
        ctx, page = phone_page(browser, url, f"scenario={urllib.parse.quote(str(d.value))}{extra}")
        try:
            row: dict = {"scene": str(d.value), "intended": d.settings.get("integrator", "whitted")}
            try:
                wait_full(page, 1, timeout_ms)
                row["opened"] = True
            except Exception as e:  # a scene that never shows a full frame is the finding itself
                row["opened"], row["error"] = False, type(e).__name__
            got = page.evaluate(
                """() => { const p = window.pocketray; const f = p && p.lastFrame;
                  return { integrator: p && p.state.render ? p.state.render.integrator : null,
                           denoise: p && p.state.render ? p.state.render.denoise : null,
                           size: f ? `${f.width}x${f.height}` : null, level: f ? f.level : null,
                           t_ms: (window.__shown.find(e => e[1] === 'full') || [null])[0],
                           notices: (p ? p.notices : []).map(n => typeof n === 'string' ? n : JSON.stringify(n)),
                           errors: p ? p.errors.map(String) : [] }; }"""
            )
            rows.append({**row, **got})
        finally:
            ctx.close()
    return rows


# The convergence pages: the Cornell box with the path integrator at an eighth of the fit resolution
# (503 × 1,088 / 8: the client's smallest preview) so that a reference of 1,024 samples takes a minute
# on a loaded llvmpipe, refined to 256 samples (no time target short of the service's longest stream).
CONVERGE_SIZE = "width=63&height=136"
CONVERGE_PAGES = {
    "path": f"scenario=mesh:cornell&integrator=path&{CONVERGE_SIZE}&refine_samples=256&refine_time_ms=60000",
    "path, oidn": f"scenario=mesh:cornell&integrator=path&{CONVERGE_SIZE}&refine_samples=256&refine_time_ms=60000"
    "&denoise=oidn",
}
# The phone's default settings (the scenes' recommended ones: path, OIDN, refined to 256 samples, no
# time target of the page's own) at an eighth of the fit resolution: a 1,024-sample reference of each
# takes minutes on a loaded llvmpipe where the fit resolution's would take hours.
CONVERGE_DEFAULT_PAGES = {
    "cornell, defaults": f"scenario=mesh:cornell&{CONVERGE_SIZE}",
    "table, defaults": f"scenario=mesh:table&{CONVERGE_SIZE}",
}
# Every frame shown: its time, level, part, size, samples, the refinement parts so far, and the canvas's
# pixels (RGBA, kept in the page until read) — the canvas shows the service's tone-mapped image as is.
CANVAS_LOG = """() => { window.__shown = []; window.__pixels = []; const poll = () => { const p = window.pocketray;
  if (p && p.frameCount !== (window.__last || 0)) { window.__last = p.frameCount; const f = p.lastFrame;
  const c = document.querySelector('#view'); let k = -1;
  if (window.__capture) { k = window.__pixels.length;
    window.__pixels.push(c.getContext('2d').getImageData(0, 0, c.width, c.height).data.slice()); }
  window.__shown.push([performance.now(), f.level, f.part || 'final', f.width, f.height, f.clientMs,
    f.samples ?? null, p.refinement ? p.refinement.parts.length : 0, k, c.width, c.height]); }
  requestAnimationFrame(poll); }; poll(); }"""
PIXELS = """k => { const a = window.__pixels[k]; let s = ''; const B = 0x8000;
  for (let i = 0; i < a.length; i += B) s += String.fromCharCode.apply(null, a.subarray(i, i + B));
  window.__pixels[k] = null; return btoa(s); }"""


def _psnr_8bit(a, b) -> float:
    import numpy as np

    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)) / 255.0**2
    return math.inf if mse == 0 else -10.0 * math.log10(mse)


def reference_png(url: str, sid: str, samples: int, step: int = 16) -> tuple[object, int, float]:
    """The session's view at ``samples`` samples per pixel, without a denoiser, as the service tone-maps
    it (png → RGB uint8): ``accumulate=1`` frames of ``step`` samples each add to the session's
    accumulation until it holds ``samples`` (samples are the same paths whichever frame traces them, so
    it goes on from the ones the refinement traced when the key is the same). Returns (image, samples, s)."""
    import io

    import numpy as np
    from PIL import Image

    t0 = time.perf_counter()
    held, body = 0, b""
    with httpx.Client(timeout=600) as http:
        while held < samples:
            r = http.get(
                f"{url}/api/sessions/{sid}/frame",
                params={"accumulate": 1, "samples_per_pixel": step, "denoise": "off", "format": "png"},
            )
            r.raise_for_status()
            held, body = int(r.headers["x-samples"]), r.content
    image = np.asarray(Image.open(io.BytesIO(body)).convert("RGB"))
    return image, held, time.perf_counter() - t0


def _images(page, shown: list, reference) -> list[dict]:
    """Each captured frame of ``shown`` at the reference's size: its time, samples and PSNR (dB)."""
    import numpy as np

    out = []
    h, w = reference.shape[:2]
    for e in shown:
        if e[8] < 0:
            continue
        data = base64.b64decode(page.evaluate(PIXELS, e[8]))
        if (e[9], e[10]) != (w, h):
            continue  # a preview (a smaller frame): shown, not compared
        rgb = np.frombuffer(data, np.uint8).reshape(h, w, 4)[..., :3]
        out.append({"t_ms": e[0], "part": e[2], "samples": e[6], "parts": e[7], "psnr_db": _psnr_8bit(rgb, reference)})
    return out


def wait_refined(page, parts: int, timeout_ms: float = 300_000) -> None:
    """Until the refinement stream has ended after at least ``parts`` parts (the last one ``done``)."""
    page.wait_for_function(
        """n => { const r = window.pocketray.refinement; const p = r.parts;
                  return p.length >= n && p[p.length - 1].done && !window.pocketray.refining; }""",
        arg=parts,
        timeout=timeout_ms,
    )


def warm(browser, url: str, query: str) -> None:
    """Load ``query``'s page once, refined to a few samples: the service compiles the page's variants."""
    ctx = browser.new_context(**PORTRAIT)
    try:
        page = ctx.new_page()
        few = query.replace("refine_samples=256", "refine_samples=8")
        page.goto(f"{url}/?{few if 'refine_samples=' in few else few + '&refine_samples=8'}")
        wait_full(page, 1)
        wait_refined(page, 1)
    finally:
        ctx.close()


def convergence_timeline(
    browser, url: str, query: str, ref_samples: int = 1024, db: float = 30.0, refs: dict | None = None
) -> dict:
    """The path integrator's frames converging on the phone viewport: load → first image → each
    refinement frame (its arrival, samples, PSNR of the canvas against the session's view at
    ``ref_samples`` samples, no denoiser) → the stream's end; then a 10-step drag → first image →
    the first frame ≥ ``db`` against the new view's reference, and the stream's end. ``refs``: the
    references already made, by camera (the same drag gives the same view: made once for all pages)."""
    refs = {} if refs is None else refs

    def reference(page, sid: str) -> tuple[object, int, float]:
        key = json.dumps(httpx.get(f"{url}/api/sessions/{sid}").json()["camera"], sort_keys=True)
        if key not in refs:
            refs[key] = reference_png(url, sid, ref_samples)
        return refs[key]

    ctx = browser.new_context(**PORTRAIT)
    try:
        ctx.add_init_script(f"window.__capture = true; ({CANVAS_LOG})()")
        page = ctx.new_page()
        page.goto(f"{url}/?{query}")
        wait_full(page, 1)
        wait_refined(page, 1)
        load = page.evaluate("() => window.__shown")
        load_parts = page.evaluate("() => window.pocketray.refinement.parts")
        sid = page.evaluate("() => window.pocketray.sessionId")
        ref, ref_n, ref_s = reference(page, sid)
        load_images = _images(page, load, ref)
        dismiss_hint(page)
        n_shown = len(load)
        n_parts = len(load_parts)
        touch = Touch(ctx.new_cdp_session(page))
        t_end = short_drag(page, touch)
        wait_refined(page, n_parts + 1)
        shown = page.evaluate("() => window.__shown")[n_shown:]
        gesture_parts = page.evaluate("() => window.pocketray.refinement.parts")[n_parts:]
        gref, gref_n, gref_s = reference(page, sid)
        after = [e for e in shown if e[0] - e[5] >= t_end]
        gesture_images = _images(page, after, gref)

        def first_at(images: list[dict], t0: float) -> float | None:
            return next(((i["t_ms"] - t0) / 1e3 for i in images if i["psnr_db"] >= db), None)

        def last(images: list[dict]) -> dict | None:
            return images[-1] if images else None

        return {
            "load_first_image_s": load[0][0] / 1e3 if load else None,
            "load_first_size": f"{load[0][3]}x{load[0][4]}" if load else None,
            "load_db_s": first_at(load_images, 0.0),
            "load_converged_s": load_images[-1]["t_ms"] / 1e3 if load_images else None,
            "load_final_samples": (load_parts[-1]["samples"] if load_parts else None),
            "load_final_db": (last(load_images) or {}).get("psnr_db"),
            "load_reason": load_parts[-1]["reason"] if load_parts else None,
            "load_images": load_images,
            "gesture_first_image_s": (after[0][0] - t_end) / 1e3 if after else None,
            "gesture_db_s": first_at(gesture_images, t_end),
            "gesture_converged_s": (gesture_images[-1]["t_ms"] - t_end) / 1e3 if gesture_images else None,
            "gesture_final_samples": gesture_parts[-1]["samples"] if gesture_parts else None,
            "gesture_final_db": (last(gesture_images) or {}).get("psnr_db"),
            "gesture_images": gesture_images,
            "reference_samples": [ref_n, gref_n],
            "reference_s": [ref_s, gref_s],
        }
    finally:
        ctx.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--client-dir", help="serve this client folder instead of client_web/")
    ap.add_argument("--url", help="an already running service (its own client)")
    ap.add_argument("--skip-device", action="store_true", help="no device-mode drag")
    ap.add_argument(
        "--only",
        default="share,device,server",
        help="parts: share (chrome share), device (drag), server (timelines), dense (4,096 spheres' previews), "
        "abandon (a drag during a full frame), rest (samples reached at rest), picker (every demo scene opened), "
        "converge (time to 30 dB at an eighth of the fit resolution, default settings)",
    )
    ap.add_argument("--move-s", type=float, default=4.0, help="the long drag's duration (server timelines)")
    ap.add_argument("--rest-s", type=float, default=90.0, help="how long a view is left at rest (--only rest)")
    ap.add_argument("--repeats", type=int, default=3, help="drags of each kind (--only abandon)")
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
            if "dense" in parts:
                out["dense"] = {}
                for name, query in DENSE_PAGES.items():
                    server_timeline(browser, url, query, move_s=0.5)  # warm: the service compiles its variants
                    out["dense"][name] = server_timeline(browser, url, query, move_s=args.move_s)
            if "abandon" in parts:
                out["abandon"] = abandon_latency(browser, url, repeats=args.repeats)
                out["abandon"]["load_average"] = os.getloadavg()
            if "rest" in parts:
                out["rest"] = {}
                for name, q in REST_PAGES.items():
                    out["rest"][name] = rest_convergence(browser, url, q, args.rest_s)
                    out["rest"][name]["load_average"] = os.getloadavg()
                    print(json.dumps({name: out["rest"][name]}), flush=True)
            if "picker" in parts:
                out["picker"] = picker_scenes(browser, url)
                out["picker_load_average"] = os.getloadavg()
            if "converge" in parts:
                out["converge"] = {}
                refs: dict = {}
                for name, query in CONVERGE_DEFAULT_PAGES.items():
                    warm(browser, url, query)
                    out["converge"][name] = convergence_timeline(browser, url, query, refs=refs)
                    out["converge"][name]["load_average"] = os.getloadavg()
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
