"""An experiment's raw data on disk: ``figures/NAME.json``, what every report and chart is made from."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from .timing import RenderTiming, Stat


def json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (Stat, RenderTiming)):
        return o.to_json()
    if dataclasses.is_dataclass(o):
        return dataclasses.asdict(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-able: {type(o).__name__}")


def roundtrip(data: Any) -> Any:
    """``data`` as it reads back from its JSON file (what ``--replot`` will draw and write from)."""
    return json.loads(json.dumps(data, default=json_default))


def save(figures: Path, name: str, obj: Any) -> str:
    """Write ``figures/NAME.json``; the path relative to RESULTS.md."""
    (Path(figures) / f"{name}.json").write_text(json.dumps(obj, indent=1, default=json_default))
    return f"figures/{name}.json"


def load(figures: Path, name: str) -> Any:
    return json.loads((Path(figures) / f"{name}.json").read_text())
