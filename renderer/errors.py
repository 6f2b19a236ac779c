"""The error of invalid scene or render input, and the checks that raise it, below every module that
uses them (the scene, its materials and textures, its environment images), so that none of them
imports another for them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


class SceneError(ValueError):
    """Invalid scene or render input. ``field`` is the JSON path of the culprit."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def finite_number(
    value: Any,
    where: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """``value`` as a finite float within the bounds given (SceneError at ``where`` otherwise)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SceneError(where, f"expected a number, got {type(value).__name__}")
    x = float(value)
    if not math.isfinite(x):
        raise SceneError(where, f"must be a finite number, got {x}")
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise SceneError(where, f"must be {'>' if lo_open else '>='} {lo}, got {x}")
    if hi is not None and (x > hi or (hi_open and x == hi)):
        raise SceneError(where, f"must be {'<' if hi_open else '<='} {hi}, got {x}")
    return x


def json_object(d: Any, where: str, allowed: set[str]) -> dict:
    """``d`` as a JSON object whose keys are all in ``allowed`` (SceneError at ``where`` otherwise)."""
    if not isinstance(d, dict):
        raise SceneError(where, "expected an object")
    unknown = set(d) - allowed
    if unknown:
        raise SceneError(f"{where}.{sorted(unknown)[0]}", f"unknown field (allowed: {', '.join(sorted(allowed))})")
    return d


def construct(cls: Any, kw: dict, where: str) -> Any:
    """``cls(**kw)``, a SceneError's field prefixed with ``where``."""
    try:
        return cls(**kw)
    except SceneError as e:
        # Prefix the nested path so the message names the full JSON field.
        inner = e.field if e.field.startswith(where) else f"{where}.{e.field}"
        raise SceneError(inner, e.message) from None
