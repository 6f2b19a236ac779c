"""A disk cache for slow references (float64 renders that take minutes)."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

CACHE_DIR = Path(os.environ.get("POCKETRAY_BENCH_CACHE", Path.home() / ".cache" / "pocketray-bench"))


def cached_array(key: dict, compute: Callable[[], dict[str, np.ndarray]], sources: Sequence[Path] = ()) -> dict:
    """``compute()`` (a dict of arrays), cached on disk under a hash of ``key`` and of ``sources``' text.

    The float64 reference renders of the accuracy experiment take minutes; they only
    change when the scene, the size or the reference tracer's code change.
    """
    h = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode())
    for s in sources:
        h.update(Path(s).read_bytes())
    path = CACHE_DIR / f"{h.hexdigest()[:24]}.npz"
    if path.exists():
        try:
            with np.load(path) as z:
                return {k: z[k] for k in z.files}
        except Exception:
            path.unlink(missing_ok=True)
    out = compute()
    try:
        CACHE_DIR.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, **out)
        tmp.replace(path)
    except OSError:
        pass
    return out
