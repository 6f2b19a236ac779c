"""Device against server frames/s: the same tracer in the browser's WebGL2 and on the server.

Scenario 3 (seeded), n = 64, 256, 1,024, 4,096 (radius 1), BIH (max_prims 8), colour,
max_recursion_depth 3 (as ``bench/latency.py``), at 320 × 544 and 640 × 1,088, in headless
Chromium (Debian's, ``/usr/bin/chromium``; WebGL2 on ANGLE/SwiftShader without a GPU):

- **device**: the client's device renderer (``window.pocketray.device.bench``) loads the
  session's data once (GET device-data: the BIH built on the server, packed by
  renderer.gpu.gpu_layout; the shader from GET /api/shader) and renders the session's camera
  repeatedly; one frame = the trace (waited for with a one-pixel read-back) + the display
  pass. A camera move needs nothing else: the tree is fetched again only when the scene or
  its settings change.
- **server**: the page fetches ``GET …/frame`` (JPEG q85) and decodes it
  (``createImageBitmap``) back to back; one frame = request → decoded image. Every server
  frame rebuilds the BIH (as the thesis does).

frames/s = 1000 / median frame ms. Each side gets a budget of ``--budget`` seconds per point
(after one warm-up frame); a point whose one frame is predicted over ``--skip-over`` seconds
(from the smaller n or the smaller size already measured) is skipped and marked so.

Usage::

    .venv/bin/python -m bench.device                    # starts its own server; writes docs/device.md
    .venv/bin/python -m bench.device --url http://127.0.0.1:8000 --out -   # table to stdout only
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import httpx

from bench.latency import Server, server_timing  # a server child process

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
SIZES = ((320, 544), (640, 1088))
NS = (64, 256, 1024, 4096)
DEPTH = 3

SERVER_LOOP = """async (p) => {
  const times = [], trace = [];
  const url = `/api/sessions/${p.sid}/frame?width=${p.width}&height=${p.height}&format=jpeg&quality=85`;
  const one = async () => {
    const t = performance.now();
    const r = await fetch(url, {cache: 'no-store'});
    if (!r.ok) throw new Error(`frame: ${r.status} ${await r.text()}`);
    const st = r.headers.get('Server-Timing');
    const bm = await createImageBitmap(await r.blob());
    bm.close();
    return [performance.now() - t, st];
  };
  const [first] = await one();
  let spent = first;
  while (times.length < p.frames && spent < p.budgetMs) {
    const [t, st] = await one();
    times.push(t); trace.push(st); spent += t;
  }
  return {first, times, timing: trace};
}"""


def device_page(pw, url: str):
    """A WebGL2 Chromium (GL_ARGS) with a small client page of the service at ``url`` ready, whose device
    renderer renders any session by id: (browser, page, the device's probe). Exits when this Chromium
    has no WebGL2 for the tracer."""
    browser = pw.chromium.launch(executable_path=CHROMIUM, args=GL_ARGS, headless=True)
    page = browser.new_page(viewport={"width": 360, "height": 640})
    page.goto(f"{url}/?scenario=1&n=8&width=16&height=16&max_recursion_depth=1&renderer=server")
    page.wait_for_function("() => window.pocketray && window.pocketray.status === 'ready'", timeout=120_000)
    probe = page.evaluate("() => window.pocketray.device.probe()")
    if not probe.get("ok"):
        raise SystemExit(f"no WebGL2 for the tracer in this Chromium: {probe}")
    return browser, page, probe


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", help="an already running service (default: start one)")
    ap.add_argument("--frames", type=int, default=8, help="frames per point and side (after a warm-up frame)")
    ap.add_argument("--budget", type=float, default=20.0, help="seconds per point and side")
    ap.add_argument("--skip-over", type=float, default=20.0, help="skip a point whose frame is predicted over this (s)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "device.md"), help="Markdown file to write ('-': none)")
    args = ap.parse_args()

    from playwright.sync_api import sync_playwright

    server = None if args.url else Server(queue_size=8)
    url = args.url or server.url
    load0 = os.getloadavg()[0]
    rows, renderer = [], ""
    try:
        with sync_playwright() as pw, httpx.Client(base_url=url, timeout=300) as http:
            gl_renderer = http.get("/api/ready").json().get("gl_renderer")
            browser, page, probe = device_page(pw, url)
            renderer = probe["renderer"]
            measured: dict[tuple[str, int, int], float] = {}  # (side, n, width) → one frame, s
            for w, h in SIZES:
                for n in NS:
                    sid = http.post(
                        "/api/sessions",
                        json={
                            "scenario": 3,
                            "n": n,
                            "seed": 0,
                            "radius": 1.0,
                            "settings": {
                                "width": w,
                                "height": h,
                                "max_recursion_depth": DEPTH,
                                "method": "bih",
                                "max_prims": 8,
                                "mode": "color",
                            },
                        },
                    ).json()["id"]
                    row = {"n": n, "size": f"{w}×{h}"}
                    for side in ("device", "server"):
                        guess = predict(measured, side, n, w)
                        if guess > args.skip_over:
                            row[side] = {"skipped": guess}
                            continue
                        t0 = time.perf_counter()
                        if side == "device":
                            r = page.evaluate(
                                "(p) => window.pocketray.device.bench(p)",
                                {
                                    "session": sid,
                                    "width": w,
                                    "height": h,
                                    "frames": args.frames,
                                    "budgetMs": args.budget * 1e3,
                                    "method": "bih",
                                    "mode": "color",
                                    "max_recursion_depth": DEPTH,
                                    "max_prims": 8,
                                },
                            )
                        else:
                            r = page.evaluate(
                                SERVER_LOOP,
                                {
                                    "sid": sid,
                                    "width": w,
                                    "height": h,
                                    "frames": args.frames,
                                    "budgetMs": args.budget * 1e3,
                                },
                            )
                        times = r["times"] or [r["first"]]
                        row[side] = {**r, "median": statistics.median(times), "wall": time.perf_counter() - t0}
                        measured[side, n, w] = row[side]["median"] / 1e3
                        print(
                            f"  {side:6s} n={n:5d} {w}×{h}: {row[side]['median']:8.1f} ms/frame ({len(times)} frames)",
                            file=sys.stderr,
                            flush=True,
                        )
                    rows.append(row)
                    http.delete(f"/api/sessions/{sid}")
            browser.close()
    finally:
        if server:
            server.close()
    load1 = os.getloadavg()[0]
    table = markdown(rows)
    print(table)
    if args.out != "-":
        write_section(Path(args.out), document(table, renderer, gl_renderer, load0, load1, args))
        print(f"written: {args.out}", file=sys.stderr)


BEGIN, END = "<!-- bench/device.py: begin -->", "<!-- bench/device.py: end -->"


def write_section(path: Path, section: str) -> None:
    """Replace the generated part of ``path`` (between the markers), or write it alone."""
    block = f"{BEGIN}\n{section.rstrip()}\n{END}\n"
    text = path.read_text() if path.exists() else ""
    if BEGIN in text and END in text:
        text = text[: text.index(BEGIN)] + block + text[text.index(END) + len(END) :].lstrip("\n")
    else:
        text = (text.rstrip() + "\n\n" if text.strip() else "") + block
    path.write_text(text)


def predict(measured: dict, side: str, n: int, w: int) -> float:
    """One frame's seconds, guessed from what was measured: a smaller n at this size (×1.5 per
    step, generous for a tree) or this n at a smaller size (× the pixel ratio)."""
    guesses = [0.0]
    for (s, nn, ww), sec in measured.items():
        if s != side:
            continue
        if ww == w and nn < n:
            guesses.append(sec * 1.5)
        elif nn == n and ww < w:
            guesses.append(sec * (w / ww) ** 2)
    return max(guesses)


def fmt(v: float, digits: int = 0) -> str:
    return f"{v:,.{digits}f}"


def markdown(rows: list[dict]) -> str:
    out = [
        "| n | size | device ms/frame (p50) | device frames/s "
        "| device load ms (fetch + build + upload; + compile the first time) "
        "| server ms/frame (p50) | server frames/s | server trace ms (p50) | device ÷ server frames/s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        d, s = r["device"], r["server"]
        if "skipped" in d:
            dcols = [f"skipped (≈ {d['skipped']:.0f} s/frame predicted)", "–", "–"]
        else:
            dcols = [f"{fmt(d['median'])} ({len(d['times'])})", fmt(1e3 / d["median"], 2), fmt(d["load"]["total"])]
        if "skipped" in s:
            scols = [f"skipped (≈ {s['skipped']:.0f} s/frame predicted)", "–", "–"]
        else:
            trace = [server_timing(t).get("trace") for t in s["timing"] if t]
            trace = [t for t in trace if t is not None]
            scols = [
                f"{fmt(s['median'])} ({len(s['times'])})",
                fmt(1e3 / s["median"], 2),
                fmt(statistics.median(trace)) if trace else "–",
            ]
        ratio = fmt(s["median"] / d["median"], 2) if "median" in d and "median" in s else "–"
        out.append(f"| {r['n']:,} | {r['size']} | " + " | ".join(dcols + scols) + f" | {ratio} |")
    return "\n".join(out)


def document(table: str, renderer: str, gl_renderer: str | None, load0: float, load1: float, args) -> str:
    return f"""### Device against server: frames/s

`bench/device.py` (`.venv/bin/python -m bench.device`): scenario 3, BIH (max_prims 8), colour,
max_recursion_depth {DEPTH}, the session's home camera; headless Chromium (`/usr/bin/chromium`,
flags `{" ".join(GL_ARGS)}`). **Device**: the client's WebGL2 renderer, `{renderer}`; one
frame = trace (waited for with a one-pixel `readPixels`) + display pass; the data (tree built on
the server, packed by `renderer.gpu.gpu_layout`) and the shader are loaded once — "load" is that one-off
cost, paid again only when the scene or its settings change, never for a camera move. **Server**:
the same page fetching `GET …/frame` as JPEG q85 and decoding it, back to back; the server
(`{gl_renderer}`) rebuilds the BIH for every frame. frames/s = 1000 / p50 frame ms; the number of
frames measured is in brackets (budget {args.budget:g} s per point and side after a warm-up
frame). The 2-core machine was shared with other work: load average {load0:.1f} at the start,
{load1:.1f} at the end.

{table}

Both "GPUs" here are the same 2 CPU cores: Mesa's llvmpipe for the server, SwiftShader (Vulkan,
through ANGLE) for Chromium, so this table compares two software rasterisers running the same
GLSL, not a phone against a server; the last column is how fast SwiftShader runs this shader
relative to llvmpipe (plus the server's per-frame BIH build, encoding and HTTP on the server side).
On a phone the device column is its GPU, with no network in the loop; the server column adds the
network and the queue shared with other clients.
"""


if __name__ == "__main__":
    main()
