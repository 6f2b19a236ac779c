"""The machine a run measures on, and the revision it measures."""

from __future__ import annotations

import os
import platform
from pathlib import Path

import numpy as np

from bench.engine import machine as engine_machine

ROOT = Path(__file__).resolve().parents[2]


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _mem_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / (1 << 20)
    except OSError:
        pass
    return None


def machine_info() -> dict[str, str]:
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    mem = _mem_gib()
    return {
        "cpu": _cpu_model(),
        "cores": f"{os.cpu_count()} logical CPUs ({usable} usable by this process)",
        "memory": f"{mem:.1f} GiB" if mem else "unknown",
        "os": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "engine.machine": engine_machine(),
    }


def revision() -> str:
    """The checked-out commit, read from .git without running git (a worktree's .git is a
    file naming its git directory; branches may live in the common directory's refs)."""
    try:
        git = ROOT / ".git"
        if git.is_file():  # a linked worktree
            git = (ROOT / git.read_text().split("gitdir:", 1)[1].strip()).resolve()
        common = (git / (git / "commondir").read_text().strip()).resolve() if (git / "commondir").exists() else git
        head = (git / "HEAD").read_text().strip()
        if head.startswith("ref: "):
            for base in (git, common):
                ref = base / head[5:]
                if ref.exists():
                    return ref.read_text().strip()[:12]
            packed = common / "packed-refs"
            for line in packed.read_text().splitlines() if packed.exists() else []:
                if line.endswith(head[5:]):
                    return line.split()[0][:12]
            return "unknown"
        return head[:12]
    except (OSError, IndexError):
        return "unknown"
