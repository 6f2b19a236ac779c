"""The phone client's frames from the service: load → first image → final image, gesture → first
image, previews per second while a finger moves — the client before the quick first image and the
preview sizing, and now.

Runs ``bench/client.py``'s ``server_timeline`` in headless Chromium on the phone viewport (390 × 844
CSS px at device pixel ratio 3, touch through CDP) against a ``python -m server`` process started
for each client: this checkout's ``client_web/``, and the one of ``BEFORE`` taken out of git (the
same service). Two pages: the default one (scenario 1, 512 spheres, Whitted, the service's still
profile, the fit resolution 503 × 1,088) and the Cornell box with ``integrator=path``. Quick mode:
this client only, the default page at 96 × 160, a short drag.
"""

from __future__ import annotations

import statistics
import subprocess
import tempfile
from pathlib import Path
from typing import Any

from bench import client as C

from .context import Context, RunInfo
from .markdown import md_table

NAME = "client"
TITLE = "The phone client — first image after load, gesture → image, previews while moving"

ROOT = Path(__file__).resolve().parents[2]
# The client before the quick first image, the measured preview size and the link's settings.
BEFORE = "7d74ebc"
FIGURES = (
    "load_first_image_s",
    "load_final_image_s",
    "load_first_over_final",
    "gesture_first_image_s",
    "gesture_full_image_s",
    "moving_previews_per_s",
    "moving_previews_per_s_2nd_half",
)


def side(client_dir: Path | None, pages: dict[str, str], runs: int, move_s: float) -> dict:
    """Every page's timeline (medians of ``runs`` after an untimed one that compiles the variants)."""
    from playwright.sync_api import sync_playwright

    server = C.Server(str(client_dir) if client_dir else None)
    out: dict[str, Any] = {}
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=C.CHROMIUM, args=C.GL_ARGS, headless=True)
            for name, query in pages.items():
                C.server_timeline(browser, server.url, query, move_s=min(move_s, 0.5))
                samples = [C.server_timeline(browser, server.url, query, move_s=move_s) for _ in range(runs)]
                row: dict[str, Any] = {"samples": samples}
                for k in FIGURES:
                    values = [s[k] for s in samples if s.get(k) is not None]
                    row[k] = statistics.median(values) if values else None
                row["sizes"] = sorted({z for s in samples for z in s["moving_preview_sizes"]}, key=_pixels)
                row["load_first_size"] = samples[-1]["load_first_size"]
                row["integrator_set_by"] = samples[-1]["integrator_set_by"]
                out[name] = row
            browser.close()
    finally:
        server.close()
    return out


REF_SAMPLES = 1024  # the converged image each frame is compared with
DB = 30.0  # the target


def converge(runs: int) -> dict:
    """The Cornell box refining to 256 samples, without and with OIDN (``C.CONVERGE_PAGES``): each
    frame's PSNR against the same view at ``REF_SAMPLES`` samples, after an untimed load of each page
    that compiles its variants."""
    from playwright.sync_api import sync_playwright

    server = C.Server(None)
    out: dict[str, Any] = {}
    refs: dict = {}
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=C.CHROMIUM, args=C.GL_ARGS, headless=True)
            for query in C.CONVERGE_PAGES.values():
                C.warm(browser, server.url, query)
            for name, query in C.CONVERGE_PAGES.items():
                out[name] = [
                    C.convergence_timeline(browser, server.url, query, REF_SAMPLES, DB, refs) for _ in range(runs)
                ]
            browser.close()
    finally:
        server.close()
    return out


def _pixels(size: str) -> int:
    w, h = (int(x) for x in size.split("x"))
    return w * h


def measure(ctx: Context) -> dict:
    if ctx.quick:
        pages = {"whitted": "width=96&height=160&max_recursion_depth=2"}
        return {"before": None, "after": side(None, pages, 1, 0.5), "before_rev": BEFORE}
    runs = max(1, min(ctx.runs, 3))
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", BEFORE, "client_web"], check=True, capture_output=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        before = side(Path(tmp) / "client_web", C.SERVER_PAGES, runs, 4.0)
    after = side(None, C.SERVER_PAGES, runs, 4.0)
    return {"before": before, "after": after, "before_rev": BEFORE, "converge": converge(1)}


def _s(x: Any, digits: int = 2) -> str:
    return "—" if x is None else f"{x:.{digits}f}"


def _median(samples: list[dict], key: str) -> Any:
    values = [s[key] for s in samples if s.get(key) is not None]
    return statistics.median(values) if values else None


def _converge_section(conv: dict) -> str:
    """The convergence table: load → first image → 30 dB → the refinement's end, gesture → first image
    → 30 dB → the end, without and with the denoiser, and the denoiser's share of the time to 30 dB."""
    if not conv:
        return ""
    med = {page: {k: _median(samples, k) for k in samples[0]} for page, samples in conv.items()}
    base = med.get("path") or {}
    rows = []
    for page, m in med.items():
        first, end = m.get("load_first_image_s"), m.get("load_converged_s")
        rows.append(
            [
                page,
                f"{_s(first)} ({conv[page][-1].get('load_first_size') or '—'})",
                _s(m.get("load_db_s")),
                f"{_s(end)} ({m.get('load_final_samples')}, {_s(m.get('load_final_db'), 1)} dB)",
                _s(first / end if first and end else None),
                _s(m.get("gesture_first_image_s")),
                _s(m.get("gesture_db_s")),
                f"{_s(m.get('gesture_converged_s'))} ({m.get('gesture_final_samples')}, "
                f"{_s(m.get('gesture_final_db'), 1)} dB)",
                "—"
                if page == "path" or not all(x.get(k) for x in (m, base) for k in ("load_db_s", "gesture_db_s"))
                else f"{m['load_db_s'] / base['load_db_s']:.2f} / {m['gesture_db_s'] / base['gesture_db_s']:.2f}",
            ]
        )
    table = md_table(
        [
            "page",
            "load → first image s (size)",
            f"load → {DB:g} dB s",
            "load → refined s (samples, dB)",
            "first / refined",
            "gesture → first image s",
            f"gesture → {DB:g} dB s",
            "gesture → refined s (samples, dB)",
            f"to {DB:g} dB: × without (load / gesture)",
        ],
        rows,
        align="lrrrrrrrr",
    )
    trace = []
    for page, samples in conv.items():
        pts = samples[-1]["gesture_images"]
        # the first frame holding at least 4, 16, 64 and 256 samples
        marks = [m for m in (next((p for p in pts if p["samples"] >= n), None) for n in (4, 16, 64, 256)) if m]
        trace.append(f"{page}: " + ", ".join(f"{p['samples']} spp {p['psnr_db']:.1f} dB" for p in marks[:8]))
    refs = conv["path"][-1]
    return f"""
**Convergence** (`bench/client.py`'s `convergence_timeline`): the Cornell box, `integrator=path`, at
63 × 136 (an eighth of the fit resolution, the client's smallest preview) on the same phone
viewport, refined to 256 samples (`refine_samples=256&refine_time_ms=60000`), without and with
`denoise=oidn`. The page's hook logs every frame shown (time, samples of `refinement.parts`) and the
canvas's pixels; each frame the size of the reference is compared with the same view at
≥ {REF_SAMPLES:,} samples without a denoiser, as the service tone-maps it (png, 8 bits: the
canvas shows the service's tone-mapped image as is), PSNR over RGB. The reference continues the
session's accumulation (`accumulate=1`, 16 samples a frame: {refs["reference_samples"][0]:,} and
{refs["reference_samples"][1]:,} samples, {refs["reference_s"][0]:.0f} s and {refs["reference_s"][1]:.0f} s),
so the 256 samples the stream traced are among its own — the MSE of a frame of n samples
against it is (1 − n / N) of the true one's, N its samples: the PSNR reads high by 1.2 dB at 256
samples, 0.3 dB at 64. Previews
(smaller frames) are shown but not compared. *refined*: the stream's last frame (`done`). The
gesture's view is the same for both pages (the same drag), so is its reference. Targets: the first
image ≤ 0.25 × the refined one's time; {DB:g} dB in half the time with the denoiser as without (× ≤ 0.5).
One run each, after an untimed load of each page.

{table}

PSNR along the gesture's refinement (samples of the frame shown: dB) — {"; ".join(trace)}.
"""


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    rows = []
    for label, key in ((f"before ({data.get('before_rev')})", "before"), ("now", "after")):
        for page, row in (data.get(key) or {}).items():
            note = "" if row.get("integrator_set_by") == "link" else " ¹"
            rows.append(
                [
                    f"{label}, {page}{note}",
                    f"{_s(row['load_first_image_s'])} ({row.get('load_first_size') or '—'})",
                    _s(row["load_final_image_s"]),
                    _s(row["load_first_over_final"]),
                    _s(row["gesture_first_image_s"]),
                    _s(row["gesture_full_image_s"]),
                    _s(row["moving_previews_per_s"], 1),
                    _s(row["moving_previews_per_s_2nd_half"], 1),
                    ", ".join(row.get("sizes") or []) or "—",
                ]
            )
    table = md_table(
        [
            "client, page",
            "load → first image s (size)",
            "load → final image s",
            "first / final",
            "gesture → first image s",
            "gesture → full frame s",
            "previews/s moving",
            "… last half",
            "preview sizes while moving",
        ],
        rows,
        align="lrrrrrrrl",
    )
    footnote = (
        "\n¹ The client before could not set the integrator by its link: the bench set it on its session\n"
        "through the API after the page loaded, so its load figures are not the path integrator's (left out).\n"
        if any("¹" in r[0] for r in rows)
        else ""
    )
    return f"""## {TITLE}

{run.caption(run.runs, "medians; a service process started for each client")}

Headless Chromium on the phone viewport (390 × 844 CSS px, device pixel ratio 3; the fit
resolution 503 × 1,088), `bench/client.py`'s `server_timeline`: seconds from the navigation's
start to the first image and to the final (supersampled) one; a 10-step one-finger drag → the
first image asked for after its last move, and the full frame; then a 4 s drag (a touch move
every 16 ms): the previews shown per second, over the whole drag and over its last half (the
preview size settled), and their sizes. Pages: *whitted* — the default page (scenario 1, 512
spheres, the service's still profile: 4 samples, depth 8); *path* —
`/?scenario=mesh:cornell&integrator=path`. Targets: the first image ≤ 0.25 × the final one's
time; ≥ 10 previews per second while moving, both integrators.

{table}
{footnote}{_converge_section(data.get("converge") or {})}"""
