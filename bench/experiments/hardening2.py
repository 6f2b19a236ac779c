"""Hardening, second pass: the attacks on WebSockets, model files, slow clients, metrics, quotas
and the loopback stack, before and after.

Every part is one of ``bench/hostile.py``'s, run against real ``python -m server`` processes (and,
for ``stack``, ``python -m server.tools.stack``: Redis, two render processes and HAProxy) on loopback.
"Before" is the code before these fixes: measured when ``POCKETRAY_BEFORE`` names a checkout of it
(``git worktree add --detach /tmp/before 88a5747``), else carried over from the last run's
``figures/hardening2.json`` with the commit it was measured at.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from . import data as saved_data
from .context import Context, RunInfo
from .hardening import measure_side
from .markdown import md_table

NAME = "hardening2"
TITLE = "Hardening, second pass — WebSockets, model files, slow clients, metrics, quotas, the stack"

ROOT = Path(__file__).resolve().parents[2]

PARTS = [
    "ws_keepalive",
    "ws_slots",
    "ws_flood",
    "model_accessor",
    "model_chain",
    "unread",
    "frames",
    "trickle",
    "metrics",
    "flood",
    "stack",
]
# --quick (the tests' smoke run): the cheapest part, enough to show the wiring works.
QUICK_PARTS = ["ws_slots"]


def measure(ctx: Context) -> dict:
    old = saved_data.load(ctx.figures, NAME) if (ctx.figures / f"{NAME}.json").exists() else {}
    before_root = os.environ.get("POCKETRAY_BEFORE")
    parts = QUICK_PARTS if ctx.quick else PARTS
    before = measure_side(Path(before_root), ctx.quick, parts) if before_root else old.get("before")
    return {"before": before, "after": measure_side(ROOT, ctx.quick, parts)}


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    return render(data)


def _get(d: Any, *path: str) -> Any:
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def _n(x: Any, unit: str = "") -> str:
    if x is None:
        return "—"
    if isinstance(x, float) and not x.is_integer():
        return f"{x:,.1f}{unit}"
    return f"{x:,.0f}{unit}" if isinstance(x, (int, float)) else str(x)


def _codes(codes: Any) -> str:
    """{code: count} or a list of codes as "200×3, 429×5"."""
    if isinstance(codes, list):
        counted: dict[str, int] = {}
        for c in codes:
            counted[str(c)] = counted.get(str(c), 0) + 1
        codes = counted
    if not isinstance(codes, dict) or not codes:
        return "—"
    return ", ".join(f"{str(k).replace('HTTP/1.1 ', '')}×{v}" for k, v in sorted(codes.items()))


def _keepalive(p: Any) -> str:
    if not isinstance(p, dict):
        return "—"
    if p.get("cut"):
        return f"cut after {_n(p.get('lived_s'))} s (close {p.get('close_code')}), {_n(p.get('answers'))} answers"
    return f"lived the {_n(p.get('talk_s'))} s, {_n(p.get('answers'))} answers"


def _slots(p: Any) -> str:
    if not isinstance(p, dict):
        return "—"
    return f"{p.get('opened')} of {p.get('websockets')} opened; then /api/health {p.get('then_health')}"


def _flood(p: Any, count: str) -> str:
    q = _get(p, count)
    if not isinstance(q, dict):
        return "—"
    close = f"closed {q['close_code']}" if q.get("close_code") else "not closed"
    return (
        f"{_n(q.get('answers'))} answers, {close}; /api/health p99 {_n(q.get('health_p99_ms'))} ms, "
        f"max {_n(q.get('health_max_ms'))} ms"
    )


def _model(p: Any, key: str, health: bool = False) -> str:
    q = _get(p, key)
    if isinstance(q, str):
        return q
    if not isinstance(q, dict):
        return "—"
    each = q.get("each_s") or []
    text = f"{_codes(q.get('codes'))} after {_n(max(each) if each else None)} s"
    if "peak_above_idle_mib" in q:
        text += f", server +{_n(q['peak_above_idle_mib'])} MiB"
    if health:
        text += f"; /api/health p99 {_n(q.get('health_p99_ms'))} ms"
    return text


def _unread(p: Any) -> str:
    if not isinstance(p, dict):
        return "—"
    return (
        f"{_codes(p.get('answers'))}; {p.get('connections_still_open')} still open; "
        f"+{_n(p.get('rss_above_idle_45s_after_mib'))} MiB held later, peak +{_n(p.get('rss_peak_above_idle_mib'))} MiB"
    )


def _frames(p: Any) -> str:
    if not isinstance(p, dict):
        return "—"
    peak = _n(p.get("peak_above_idle_mib"))
    return f"{_codes(p.get('codes'))} ({_n(p.get('retries_503'))} × 503 retried); peak +{peak} MiB"


def _trickle(p: Any) -> str:
    if not isinstance(p, dict):
        return "—"
    return (
        f"honest {_codes(p.get('honest_answers'))}; trickles {_codes(p.get('trickle_answers'))}; "
        f"/api/health p99 {_n(p.get('health_p99_ms'))} ms"
    )


def _metrics(p: Any) -> str:
    if not isinstance(p, dict):
        return "—"
    return (
        f"{_n(p.get('series_before'))} → {_n(p.get('series_after'))} series, {_n(p.get('metrics_kib'))} KiB, "
        f"scrape {_n(p.get('scrape_ms'))} ms"
    )


def _sessions(p: Any) -> str:
    f = _get(p, "flood")
    if not isinstance(f, dict):
        return "—"
    return f"{_codes(f.get('codes'))} in {_n(f.get('seconds'))} s"


def _quota(p: Any) -> str:
    u = _get(p, "uploads")
    if not isinstance(u, dict):
        return "—"
    return (
        f"{_codes(u.get('codes'))} under a {_n(u.get('quota_mib'))} MiB quota; store file {_n(u.get('sqlite_mib'))} MiB"
    )


def _phase(p: Any, phase: str) -> str:
    q = _get(p, phase)
    if not isinstance(q, dict):
        err = _get(p, "error")
        return "stack stopped" if err or phase != "load" else "—"
    kinds = ", ".join(f"{k} ×{v}" for k, v in sorted((q.get("failures") or {}).items()))
    text = f"{q.get('failed')} of {q.get('requests')} failed ({_n(q.get('failed_pct'))} %)"
    return text + (f": {kinds}" if kinds else "")


def _end(p: Any) -> str:
    e = _get(p, "end")
    if not isinstance(e, dict):
        return "—"
    running = "running" if e.get("stack_running") else "stopped"
    return (
        f"{e.get('lost_writes')} of {_n(e.get('acknowledged_gestures'))} acknowledged writes lost, "
        f"{e.get('sessions_unreadable')} sessions unreadable; stack {running} with {e.get('render_processes')} "
        "render processes"
    )


ROWS = [
    ("1", "a WebSocket sending a gesture every 0.5 s", "ws_keepalive", _keepalive),
    ("2", "WebSockets opened and closed one after another", "ws_slots", _slots),
    ("3", "20,000 tiny invalid messages at once on one WebSocket", "ws_flood", lambda p: _flood(p, "20000")),
    ("3", "… 60,000", "ws_flood", lambda p: _flood(p, "60000")),
    ("4", "a glTF accessor claiming 30,000,000 VEC3, no data", "model_accessor", lambda p: _model(p, "30,000,000 x1")),
    ("4", "… three at once", "model_accessor", lambda p: _model(p, "30,000,000 x3")),
    ("4", "… 90,000,000", "model_accessor", lambda p: _model(p, "90,000,000 x1")),
    ("5", "a GLB chain of 25,000 nodes", "model_chain", lambda p: _model(p, "25,000 x1", health=True)),
    ("5", "… 50,000 nodes", "model_chain", lambda p: _model(p, "50,000 x1", health=True)),
    ("7", "10 clients that never read a 4096² normal npy frame", "unread", _unread),
    ("8", "8 concurrent 4096² normal npy frames", "frames", _frames),
    ("9", "8 bodies trickled a byte every 4 s; an honest client's 132 kB bodies", "trickle", _trickle),
    ("10", "4,000 requests with made-up methods and paths, then /metrics", "metrics", _metrics),
    ("11", "sessions created from one address for 10 s", "flood", _sessions),
    ("11", "30 sessions of a 3.2 MB scene each", "flood", _quota),
    ("12", "stack: 80 clients for 15 s", "stack", lambda p: _phase(p, "load")),
    ("13", "… then kill -9 of a render process, 10 s", "stack", lambda p: _phase(p, "kill")),
    ("14", "… then Redis stopped for 5 s", "stack", lambda p: _phase(p, "redis_paused")),
    ("14", "… and the 5 s after it returns", "stack", lambda p: _phase(p, "redis_back")),
    ("13", "… at the end", "stack", _end),
]


def render(data: dict) -> str:
    b, a = data.get("before") or {}, data["after"]
    rows = []
    for finding, attack, part, fmt in ROWS:
        if part not in a and part not in b:
            continue
        rows.append([finding, attack, fmt(b.get(part)), fmt(a.get(part))])
    other = {part: c for part, c in (a.get("commits") or {}).items() if c != a.get("commit")}
    commits = (
        "The after column's parts " + ", ".join(f"`{p}`" for p in other) + f" ran at `{next(iter(other.values()))}`, "
        "the same service code."
        if other
        else ""
    )
    table = md_table(["#", "attack", f"before (`{b.get('commit', '—')}`)", f"after (`{a.get('commit')}`)"], rows)
    return f"""## {TITLE}

The attacks of the second review, each a part of `python -m bench.hostile` against real servers on
loopback (default settings, a temporary SQLite file; the stack's parts against `python -m server.tools.stack`
with `POCKETRAY_QUEUE_SIZE` 80 and `POCKETRAY_REDIS_TIMEOUT_S` 2). Load average
{a.get("loadavg")}–{a.get("loadavg_end")} during the "after" run, {b.get("loadavg", "—")}–{b.get("loadavg_end", "—")}
during the "before" run, on a machine shared with other work. Memory is the server process's resident
memory above its idle size (VmHWM for peaks). `#` is the finding's number in the review; every
finding has a test in `tests/` that reproduces it (docs/API.md, "Hardening", names them with the
settings that bound each attack).

{table}

Finding 6 (a binary STL whose count disagrees with its length answered with a missing module's name;
a PLY short of its declared faces and an OBJ face of index 0 accepted) is about correctness, not load:
`tests/renderer/io/test_model_guard.py` holds those files. The frames of row 8 all come from one address:
once one 192 MiB answer waits for its client, that address's next requests get 429
(`POCKETRAY_MAX_UNSENT_BYTES_PER_CLIENT`); from several addresses they queue in the frame byte budget
(503 + Retry-After, as the 9 refused of row 7). {commits}

What changed, in short: WebSockets keep their connection slot and lose the request timers through the
upgrade, and are closed on idleness (1001) or a message flood (1008); model files are checked against
their declared counts and lengths before anything is allocated and parsed in worker processes with a
memory limit and a deadline; a client that does not take its answer is cut after
`POCKETRAY_WRITE_TIMEOUT_S` and one address's unsent bytes are bounded; frames reserve their estimated
bytes in `POCKETRAY_MAX_FRAME_BYTES_IN_FLIGHT` (one 4096² normal npy frame at a time); a large body must
keep a minimum rate and one address holds at most `POCKETRAY_BODY_SLOTS_PER_CLIENT` of the slots;
metrics labels come from closed sets; sessions have a creation rate per address and a store quota in
bytes; the stack's balancer caps clients, forwards their address, re-sends what is safe, answers in
JSON with Retry-After and keeps the processes in through a Redis outage, and its supervisor restarts a
dead child.
"""
