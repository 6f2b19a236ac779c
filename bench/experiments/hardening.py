"""Hardening: the attack's figures before and after, and a soak.

Measured against real ``python -m server`` processes on loopback by ``bench/hostile.py`` (the
defects' figures, the memory of the largest requests, ``/api/health`` while six maximum bodies
arrive) and ``bench/soak.py`` (honest clients and a hostile one for a while, then ``kill -9``
and a restart: nothing acknowledged may be lost).

"Before" is the code before the issue: measured when ``POCKETRAY_BEFORE`` names a checkout of
it (``git worktree add /tmp/before c16d587``), else carried over from the last run's
``figures/hardening.json`` with the commit it was measured at.
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path

from . import data as saved_data
from .context import Context, RunInfo
from .markdown import md_table

NAME = "hardening"
TITLE = "Hardening — the attack of issue #17, before and after, and a soak"

ROOT = Path(__file__).resolve().parents[2]


def _bench(name: str):
    """bench/NAME.py, imported when used (the service's benchmarks are heavy to import)."""
    return importlib.import_module(f"bench.{name}")


def measure_side(root: Path, quick: bool, parts: list[str]) -> dict:
    hostile = _bench("hostile")
    args = hostile.parser().parse_args([])
    if quick:
        args.target_side, args.bad_spheres, args.max_body, args.max_spheres, args.stall_wait = (
            512,
            15_000,
            2 << 20,
            1 << 16,
            10.0,
        )
    out = {"commit": _commit(root), "loadavg": round(os.getloadavg()[0], 2)}
    for part in parts:
        if part == "health_parse":
            args.parse_only = True
            out[part] = hostile.PARTS["health"](root, args)
            args.parse_only = False
        else:
            out[part] = hostile.PARTS[part](root, args)
    out["loadavg_end"] = round(os.getloadavg()[0], 2)
    return out


def _commit(root: Path) -> str:
    import subprocess

    return subprocess.run(
        ["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()


BEFORE_PARTS = ["targets", "bad", "health", "health_parse", "stalled"]
AFTER_PARTS = ["targets", "bad", "largest", "recipe", "health", "health_parse", "stalled"]


# --quick (part of the tests, whose smoke run has a few minutes for every experiment): one part and a
# 5-second soak, enough to show that the scripts work.
QUICK_PARTS = ["bad"]


def measure(ctx: Context) -> dict:
    old = saved_data.load(ctx.figures, NAME) if (ctx.figures / f"{NAME}.json").exists() else {}
    before_root = os.environ.get("POCKETRAY_BEFORE")
    before = (
        measure_side(Path(before_root), ctx.quick, QUICK_PARTS if ctx.quick else BEFORE_PARTS)
        if before_root
        else old.get("before")
    )
    after = measure_side(ROOT, ctx.quick, QUICK_PARTS if ctx.quick else AFTER_PARTS)
    soak = _bench("soak").run_soak(ROOT, 5 if ctx.quick else 300, 1 if ctx.quick else 4)
    return {"before": before, "after": after, "soak": soak}


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    return render(data)


def _ms(x) -> str:
    return f"{x:,.0f}" if isinstance(x, (int, float)) else str(x)


def render(data: dict) -> str:
    b, a, soak = data.get("before") or {}, data["after"], data["soak"]

    def get(d: dict, *path, fmt=_ms):
        for k in path:
            if not isinstance(d, dict) or k not in d:
                return "—"
            d = d[k]
        return fmt(d)

    rows = [
        [
            f"frames at 11 sizes from {get(a, 'targets', 'sizes', fmt=lambda v: v[0])} down by 8 px (JPEG, depth 1): "
            "resident memory after (peak), MiB",
            f"{get(b, 'targets', 'rss_after_mib')} ({get(b, 'targets', 'rss_peak_mib')})",
            f"{get(a, 'targets', 'rss_after_mib')} ({get(a, 'targets', 'rss_peak_mib')})",
        ],
        [
            f"a body of {get(a, 'bad', 'body_mb', fmt=str)} MB, invalid spheres (three errors each): the 422's size, "
            "bytes",
            get(b, "bad", "answer_bytes"),
            get(a, "bad", "answer_bytes"),
        ],
        [
            "… errors listed / its peak memory above the idle process, MiB",
            f"{get(b, 'bad', 'errors_listed')} / +{get(b, 'bad', 'peak_above_idle_mib')}",
            f"{get(a, 'bad', 'errors_listed')} / +{get(a, 'bad', 'peak_above_idle_mib')}",
        ],
        [
            f"/api/health while six scenes of {get(a, 'health', 'body_mb', fmt=str)} MB are read, parsed and "
            "validated (refused after): p50 / p99 / max ms",
            f"{get(b, 'health_parse', 'p50_ms')} / {get(b, 'health_parse', 'p99_ms')} / "
            f"{get(b, 'health_parse', 'max_ms')}",
            f"{get(a, 'health_parse', 'p50_ms')} / {get(a, 'health_parse', 'p99_ms')} / "
            f"{get(a, 'health_parse', 'max_ms')}",
        ],
        [
            "… and while six are created as sessions (parse, build, plan): p50 / p99 / max ms",
            f"{get(b, 'health', 'p50_ms')} / {get(b, 'health', 'p99_ms')} / {get(b, 'health', 'max_ms')}",
            f"{get(a, 'health', 'p50_ms')} / {get(a, 'health', 'p99_ms')} / {get(a, 'health', 'max_ms')}",
        ],
        [
            "… the six sessions' peak memory above the idle process, MiB",
            f"+{get(b, 'health', 'rss_peak_above_idle_mib')}",
            f"+{get(a, 'health', 'rss_peak_above_idle_mib')}",
        ],
        [
            "a body stalled after a few bytes (Content-Length: 100000): closed after, s",
            get(b, "stalled", "seconds", fmt=str),
            get(a, "stalled", "seconds", fmt=str),
        ],
    ]
    table = md_table(["", f"before (`{b.get('commit', '—')}`)", f"after (`{a['commit']}`)"], rows, "lrr")
    mem = md_table(
        ["request (eight at once: POCKETRAY_QUEUE_SIZE)", "one: peak above idle, MiB", "eight: MiB"],
        [
            [
                f"scene body of {get(a, 'largest', 'body_mb', fmt=str)} MB ({get(a, 'largest', 'spheres')} spheres), "
                "POST /api/sessions",
                f"+{get(a, 'largest', 'x1', 'peak_above_idle_mib')}",
                f"+{get(a, 'largest', 'x8', 'peak_above_idle_mib')}",
            ],
            [
                f"recipe of {get(a, 'recipe', 'n')} spheres (scenario 3)",
                f"+{get(a, 'recipe', 'x1', 'peak_above_idle_mib')}",
                f"+{get(a, 'recipe', 'x8', 'peak_above_idle_mib')}",
            ],
        ],
        "lrr",
    )
    kinds = soak["kinds"]
    soak_rows = [
        [
            k,
            v["n"],
            f"{v['per_s']:.2f}",
            _ms(v["p50_ms"]),
            _ms(v["p99_ms"]),
            ", ".join(f"{c}×{n}" for c, n in sorted(v["codes"].items())),
        ]
        for k, v in kinds.items()
        if k != "hostile session unchanged"
    ]
    soak_table = md_table(["requests", "n", "per s", "p50 ms", "p99 ms", "answers"], soak_rows, "lrrrrl")
    h, r = soak["health"], soak["rss_mib"]
    unchanged = kinds.get("hostile session unchanged", {}).get("codes", {}).get("200") == 1
    return f"""## {TITLE}

`bench/hostile.py` and `bench/soak.py` against `python -m server` on loopback (default settings,
a temporary SQLite file; load average {a.get("loadavg")}–{a.get("loadavg_end")} during the "after"
run, {b.get("loadavg", "—")}–{b.get("loadavg_end", "—")} during the "before" run, on a machine shared
with other work). Resident memory is the server process's (`/proc/PID/status`: VmRSS after, VmHWM
the peak); the idle process is ≈ 170 MiB. A test under `tests/server/` reproduces every defect.

{table}

The render targets are now a pool bounded in bytes (`POCKETRAY_MAX_TARGET_BYTES`, 256 MiB: a 4096²
target, 512 MiB, is never kept); the 422 lists 20 errors and a count, the spheres validated 2,048 at
a time; large bodies are parsed on one thread off the event loop without full garbage collections,
the depth counted without a regex, freed a chunk at a time, and the GIL switch interval is 1 ms; a
request silent for `POCKETRAY_REQUEST_IDLE_TIMEOUT_S` (5 s) is answered 408 and closed. The six
sessions' builds (a BIH of {get(a, "health", "spheres")} spheres each, on the request threads) are what is
left in the second health row.

### Memory of the largest requests (docs/API.md, "Memory budget")

{mem}

At most `POCKETRAY_QUEUE_SIZE` (8) large bodies are read and as many frames planned at once, so
the budget of 3 GiB above the idle process holds with the default `POCKETRAY_MAX_BODY_BYTES`
(16 MiB) and `POCKETRAY_MAX_SPHERES` (2^21).

### Soak: {soak["users"]} clients and a hostile one for {soak["seconds"]} s

Each client has its own session (scenario 3, 512 spheres, 96 × 160 JPEG, depth 2) and loops: a pan,
a read, a pinch with `?frame=1`, a frame; 503/409 retried as told. The hostile client loops through
stalled bodies (up to 8 open), 20,000 bad spheres, duplicate keys, 1,000-deep nesting, UTF-16,
loose types and a refused `mode=cones` gesture. Load average {soak["loadavg_start"]:.2f} →
{soak["loadavg_end"]:.2f}.

{soak_table}

- honest requests held: **{soak["honest_requests_per_s"]:.1f} per s**; `/api/health` (every 100 ms):
  p50 {h["p50_ms"]} ms, p99 {h["p99_ms"]} ms, max {h["max_ms"]} ms;
- resident memory: {r["start"]} MiB at the start, {r["max"]} MiB at most, {r["end"]} MiB at the end
  (every 60 s: {", ".join(str(m) for m in r["every_60_s"])} MiB);
- then `kill -9` and a restart on the same file: **{len(soak["lost"])} of {soak["sessions"]} sessions
  lost anything** — each at version 1 + the {soak["acknowledged_changes"]:,} changes acknowledged to
  its client, none applied twice; the hostile client's session was {"unchanged" if unchanged else "CHANGED"}
  after all its refused requests.

Raw data: [`figures/hardening.json`](figures/hardening.json)."""
