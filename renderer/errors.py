"""The error of invalid scene or render input, below every module that raises it (the scene, its
environment images), so that none of them imports another for it."""

from __future__ import annotations


class SceneError(ValueError):
    """Invalid scene or render input. ``field`` is the JSON path of the culprit."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message
