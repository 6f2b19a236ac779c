"""The phone's views at rest and its scenes, in headless Chromium on the phone viewport (390 × 844 CSS
px at device pixel ratio 3, touch through CDP), against a ``python -m server`` process:

- **rest**: the Cornell box and the table (``integrator=path`` and their recommended denoiser, OIDN)
  left at rest at the phone's fit resolution with the default settings (refined to 256 samples, no
  time target of the page's own): the samples reached and when (``bench/client.py``'s
  ``rest_convergence``; watched for ``WATCH_S`` each);
- **30 dB**: the same pages at an eighth of the fit resolution (63 × 136: a 1,024-sample reference
  takes minutes where the fit resolution's would take hours), each frame shown compared with the
  view at 1,024 samples (``convergence_timeline``): load → 30 dB and gesture → 30 dB;
- **abandon**: a drag begun while a full frame of the table (Whitted) is in flight, its first preview
  against a drag's at rest (``abandon_latency``);
- **picker**: every demo scene opened by its link with nothing else asked (``picker_scenes``): the
  integrator and denoiser it opened with, the size of its first full frame, the notices.

Each part records the load average (1, 5, 15 min) when it ended: the machine is shared.
Quick mode: scenario 1 opened at 96 × 160 only.
"""

from __future__ import annotations

import json
import os
from typing import Any

from bench import client as C

from .context import Context, RunInfo
from .markdown import md_table

NAME = "phone"
TITLE = "The phone at rest — samples reached, time to 30 dB, a drag during a full frame, the picker's scenes"
WATCH_S = 900.0


def measure(ctx: Context) -> dict:
    from playwright.sync_api import sync_playwright

    server = C.Server(None)
    out: dict[str, Any] = {"watch_s": WATCH_S}
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=C.CHROMIUM, args=C.GL_ARGS, headless=True)
            if ctx.quick:
                out["picker"] = C.picker_scenes(browser, server.url, only=("1",), extra="&width=96&height=160")
                out["picker_load_average"] = os.getloadavg()
                return out
            out["picker"] = C.picker_scenes(browser, server.url)
            out["picker_load_average"] = os.getloadavg()
            out["abandon"] = C.abandon_latency(browser, server.url)
            out["abandon"]["load_average"] = os.getloadavg()
            out["converge"], refs = {}, {}
            for name, query in C.CONVERGE_DEFAULT_PAGES.items():
                C.warm(browser, server.url, query)
                out["converge"][name] = C.convergence_timeline(browser, server.url, query, refs=refs)
                out["converge"][name]["load_average"] = os.getloadavg()
            out["rest"] = {}
            for name, query in C.REST_PAGES.items():
                out["rest"][name] = C.rest_convergence(browser, server.url, query, WATCH_S)
                out["rest"][name]["load_average"] = os.getloadavg()
            browser.close()
    finally:
        server.close()
    return out


def _s(x: Any, digits: int = 1) -> str:
    return "—" if x is None else f"{x:,.{digits}f}"


def _notice(raw: str) -> str:
    """A notice the page logged ({"text", "kind"} as JSON, or its text) as "kind: text"."""
    try:
        n = json.loads(raw)
    except ValueError:
        return raw
    return f"{n.get('kind', 'info')}: {n.get('text', '')}" if isinstance(n, dict) else raw


def _load(la: Any) -> str:
    return "—" if not la else " / ".join(f"{x:.1f}" for x in la)


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    parts = [f"## {TITLE}\n\n{run.caption(1, '')}\n"]
    rest = data.get("rest") or {}
    if rest:
        rows = []
        for name, r in rest.items():
            got, at = r.get("samples_reached"), r.get("reached_at_s")
            rate = got / at if got and at else None
            left = (256 - got) / rate if rate and got < 256 else 0.0
            rows.append(
                [
                    name,
                    r.get("full_size") or "—",
                    _s(r.get("first_image_s")),
                    _s(r.get("first_full_s")),
                    f"{r.get('samples_reached')} at {_s(r.get('reached_at_s'), 0)} s",
                    "yes" if r.get("refine_done") else f"no (watched {r.get('watched_s', 0):.0f} s)",
                    "—" if rate is None else f"{at + left:,.0f} s",
                    _load(r.get("load_average")),
                ]
            )
        parts.append(
            "**At rest, the phone's fit resolution, default settings** (`rest_convergence`: path, OIDN, "
            "`refine_samples` 256, `refine_time_ms` 0 — the stream stops at its samples or the next change, "
            "within the service's `POCKETRAY_MAX_REFINE_MS` of GL time). *256 at*: the time the samples "
            "reached so far extrapolate to at their mean rate, if the later samples cost what these did "
            "at the same load (the first image and the first full frame included: a little early).\n\n"
            + md_table(
                ["page", "size", "first image s", "first full s", "samples reached", "done", "256 at", "load 1/5/15"],
                rows,
                align="llrrrlrl",
            )
            + "\n"
        )
    conv = data.get("converge") or {}
    if conv:
        rows = [
            [
                name,
                f"{_s(m.get('load_first_image_s'), 2)} ({m.get('load_first_size')})",
                _s(m.get("load_db_s"), 2),
                f"{_s(m.get('load_converged_s'))} ({m.get('load_final_samples')}, {_s(m.get('load_final_db'))} dB)",
                _s(m.get("gesture_first_image_s"), 2),
                _s(m.get("gesture_db_s"), 2),
                _load(m.get("load_average")),
            ]
            for name, m in conv.items()
        ]
        parts.append(
            "**Time to 30 dB** (`convergence_timeline`, 63 × 136 on the phone viewport, the default "
            "settings: each frame shown against the same view at 1,024 samples without a denoiser, PSNR "
            "of the 8-bit canvas; the reference continues the session's own accumulation, so a frame of "
            "n samples reads high by 10·log10(1 / (1 − n/1,024)) dB: 1.2 dB at 256, nothing at the few "
            "samples where 30 dB falls).\n\n"
            + md_table(
                [
                    "page",
                    "load → first image s (size)",
                    "load → 30 dB s",
                    "load → refined s (samples, dB)",
                    "gesture → first image s",
                    "gesture → 30 dB s",
                    "load 1/5/15",
                ],
                rows,
                align="lrrrrrl",
            )  # fmt: skip
            + "\n"
        )
    ab = data.get("abandon")
    if ab:
        parts.append(
            "**A drag during a full frame** (`abandon_latency`: the table, Whitted, the fit resolution; "
            "the page's clock from the first touch move to the first preview shown; medians of "
            f"{len(ab.get('rest_all_ms') or [])}).\n\n"
            + md_table(
                ["drag begun", "first preview ms", "each ms"],
                [
                    [
                        "at rest",
                        _s(ab.get("rest_first_preview_ms"), 0),
                        ", ".join(f"{x:.0f}" for x in ab.get("rest_all_ms") or []),
                    ],
                    [
                        f"during a full frame ({_s(ab.get('full_frame_ms_median'), 0)} ms, {ab.get('full_size')})",
                        _s(ab.get("in_flight_first_preview_ms"), 0),
                        ", ".join(f"{x:.0f}" for x in ab.get("in_flight_all_ms") or []),
                    ],
                ],
                align="lrl",
            )  # fmt: skip
            + f"\n\nRatio {_s(ab.get('ratio'), 2)} (target ≤ 2); load average {_load(ab.get('load_average'))}.\n"
        )
    picker = data.get("picker") or []
    if picker:
        rows = []
        for r in picker:
            notices = "; ".join(_notice(n) for n in r.get("notices") or [])
            rows.append(
                [
                    f"`{r['scene']}`",
                    r["intended"],
                    f"{r.get('integrator')}, {r.get('denoise')}",
                    r.get("size") or "—",
                    _s((r.get("t_ms") or 0) / 1e3) if r.get("t_ms") else "—",
                    "yes" if r.get("opened") else f"no ({r.get('error')})",
                    notices.replace("|", "/")[:200] or "—",
                ]
            )
        parts.append(
            "**The picker's scenes** (`picker_scenes`: each link `?scenario=…` alone on the phone viewport; "
            f"load average {_load(data.get('picker_load_average'))}).\n\n"
            + md_table(
                ["scene", "intended", "opened with", "first full frame", "s", "opened", "notices"],
                rows,
                align="lllrrll",
            )
            + "\n"
        )
    return "\n".join(parts)
