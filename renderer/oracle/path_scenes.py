"""Small scenes for the path integrator, one lobe or one kind of light each, shared by the check
against Mitsuba 3 (``tests/renderer/gl/test_mitsuba.py``) and the path benchmark
(``bench/experiments/path.py``), so both measure the same scenes.

Each is a scene JSON (docs/FORMATS.md): a grey diffuse floor, an emitting sphere, and the lobe
the scene is about. :func:`path_scene` builds them, and the Cornell box
(``mesh_scene("cornell")``, flat) under the name ``"cornell"``.
"""

from __future__ import annotations

from typing import Any

from ..geometry.scene import Scene
from ..scenes.scenarios import mesh_scene

MATS: list[dict[str, Any]] = [
    {"color": [0.7, 0.7, 0.7], "diffuse": 1.0, "reflective": 0, "ambient": 0},
    {"color": [0, 0, 0], "diffuse": 0, "reflective": 0, "emission": [8, 7, 6]},
]
BASE: dict[str, Any] = {
    "camera": {"position": [0, 3, 8], "target": [0, 0.5, 0], "fov_y": 40},
    "lights": [],
    "materials": MATS,
    "planes": [{"point": [0, 0, 0], "normal": [0, 1, 0], "material": 0}],
}
LAMP: dict[str, Any] = {"center": [0, 2.5, -1], "radius": 0.5, "material": 1}
SCENES: dict[str, dict[str, Any]] = {
    "area_light": {
        **BASE,
        "spheres": [
            {"center": [0, 2.5, 0], "radius": 0.5, "material": 1},
            {"center": [1.2, 0.6, 0], "radius": 0.6, "material": 0},
        ],
    },
    "mirror": {
        **BASE,
        "materials": MATS + [{"color": [1, 1, 1], "diffuse": 0, "reflective": 1}],
        "spheres": [LAMP, {"center": [0.5, 0.8, 0.5], "radius": 0.8, "material": 2}],
        "environment": {"color": [0.2, 0.3, 0.4]},
    },
    "glass_caustic": {
        **BASE,
        "materials": MATS + [{"color": [1, 1, 1], "diffuse": 0, "reflective": 0, "transmissive": 1, "ior": 1.5}],
        "spheres": [
            {"center": [0, 3, 0], "radius": 0.5, "material": 1},
            {"center": [0, 1.0, 0.5], "radius": 0.8, "material": 2},
        ],
    },
    "rough_conductor": {
        **BASE,
        "materials": MATS + [{"color": [1, 1, 1], "diffuse": 0.3, "reflective": 0.7, "roughness": 0.3}],
        "spheres": [LAMP, {"center": [0, 0.8, 0.5], "radius": 0.8, "material": 2}],
        "environment": {"color": [0.3, 0.3, 0.3]},
    },
    "rough_glass": {
        **BASE,
        "materials": MATS
        + [{"color": [1, 1, 1], "diffuse": 0, "reflective": 0, "transmissive": 1, "ior": 1.5, "roughness": 0.3}],
        "spheres": [
            {"center": [0, 3, 0], "radius": 0.5, "material": 1},
            {"center": [0, 1.0, 0.5], "radius": 0.8, "material": 2},
        ],
        "environment": {"color": [0.2, 0.3, 0.4]},
    },
    "mesh_point_light": {
        **BASE,
        "lights": [{"position": [2, 4, 3], "color": [1, 1, 1]}],
        "meshes": [
            {
                "vertices": [[-1, 0.01, -1], [1, 0.01, -1], [0, 1.5, 0], [0, 0.01, 1]],
                "triangles": [[0, 2, 1], [0, 3, 2], [1, 2, 3], [0, 1, 3]],
                "material": 0,
            }
        ],
        "environment": {"color": [0.1, 0.1, 0.15]},
    },
}
NAMES: tuple[str, ...] = (*SCENES, "cornell")


def path_scene(name: str) -> Scene:
    """The scene ``name`` of :data:`NAMES`: one of :data:`SCENES`, or the flat Cornell box."""
    if name == "cornell":
        return mesh_scene("cornell", 0, smooth=False)
    return Scene.from_json(SCENES[name])


# The glTF metallic-roughness materials where Mitsuba 3 has the same model (renderer/oracle/mitsuba_scene.py):
# a white rough conductor, a rough dielectric of transmission 1, an ior-1 dielectric (F0 = 0: Lambert).
PBR_MATERIALS: dict[str, dict[str, Any]] = {
    "pbr_rough_conductor": {"kind": "pbr", "base_color": [1, 1, 1], "metallic": 1.0, "roughness": 0.5},
    "pbr_rough_dielectric": {
        "kind": "pbr",
        "base_color": [1, 1, 1],
        "metallic": 0.0,
        "roughness": 0.4,
        "transmission": 1.0,
        "ior": 1.5,
    },
    "pbr_diffuse": {"kind": "pbr", "base_color": [0.6, 0.5, 0.3], "metallic": 0.0, "roughness": 1.0, "ior": 1.0},
}


def pbr_scene(name: str) -> Scene:
    """The grey floor, the lamp and a sphere of PBR material ``name`` (:data:`PBR_MATERIALS`) under a
    dim environment: the set of :data:`SCENES`, for the comparison of the PBR kind with Mitsuba."""
    return Scene.from_json(
        {
            **BASE,
            "materials": MATS + [PBR_MATERIALS[name]],
            "spheres": [LAMP, {"center": [0, 0.8, 0.5], "radius": 0.8, "material": 2}],
            "environment": {"color": [0.2, 0.25, 0.3]},
        }
    )
