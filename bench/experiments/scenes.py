"""Scenes and settings the experiments share: the methods to measure, default settings, scene variants."""

from __future__ import annotations

import dataclasses

from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Scene

SETTING_FIELDS = frozenset(f.name for f in dataclasses.fields(RenderSettings))


def has_setting(name: str) -> bool:
    """Whether this build's RenderSettings knows ``name`` (knobs added later are optional)."""
    return name in SETTING_FIELDS


def method_names(dispatchers: bool = False) -> list[str]:
    """Every acceleration method of ``renderer.config.methods.METHODS``, in registry order (new ones
    join by themselves). ``dispatchers``: also the names that only pick one of them per scene
    (``auto``), i.e. every ``method`` RenderSettings accepts."""
    from renderer.config.settings import METHOD_NAMES

    names = list(METHODS)
    if dispatchers:
        names += [m for m in METHOD_NAMES if m not in names]
    return names


def default_settings() -> RenderSettings:
    return RenderSettings()


def diffuse_only(scene: Scene) -> Scene:
    """The same scene with nothing reflecting or transmitting (kr = kt = 0)."""
    mats = tuple(dataclasses.replace(m, reflective=0.0, transmissive=0.0) for m in scene.materials)
    return dataclasses.replace(scene, materials=mats)
