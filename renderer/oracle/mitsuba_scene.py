"""Our scene JSON as a Mitsuba 3 scene, for checking the path integrator against an independent
renderer (docs/SHADING.md, "Path integrator"; ``tests/renderer/gl/test_mitsuba.py``).

What is translated, term by term, so both renderers estimate the same integral:

- the pinhole camera (``perspective``, vertical ``fov_y``, ``look_at``), a box pixel filter;
- ``path`` with ``max_depth`` = our ``max_recursion_depth`` (the same count of segments);
- a material's lobes — weights ``diffuse``, ``reflective``, ``transmissive`` divided by their sum
  where it exceeds 1, the rest absorbed — as nested ``blendbsdf`` of a two-sided ``diffuse``
  (albedo ``color``), a two-sided ``conductor`` of reflectance 1 (``roughconductor`` GGX,
  ``alpha = roughness``, when rough), a ``dielectric`` of ``int_ior = ior`` (``roughdielectric`` GGX,
  ``alpha = roughness``, when rough), and black; both rough lobes sample the visible normals as ours;
- a glTF metallic-roughness (``pbr``) material where Mitsuba has the same model
  (:func:`_pbr_bsdf`): wholly metallic as a ``roughconductor`` (GGX, α = roughness², reflectance
  ``base_color`` — Mitsuba's F is that constant, ours Schlick's from it: equal for a white metal; and
  Mitsuba's Smith masking is the separable form, ours the height-correlated one), an ior-1 dielectric
  (F0 = 0, nothing reflects) as a ``diffuse`` of ``base_color``, transmission 1 as a
  ``roughdielectric`` (transmittance ``base_color``); any other is refused (:class:`NoMitsubaMaterial`);
- ``emission`` as an ``area`` emitter (the side the normal faces, as ours), the environment as a
  ``constant`` emitter (an image as an ``envmap``), a point light of ``color`` C as a ``point`` of intensity π·D²·C;
- spheres, meshes (their world-space triangles) and planes (a square 10⁴ × the scene's size);
- analytic shapes: a cylinder as Mitsuba's ``cylinder`` (an open tube) and its caps as two
  ``disk`` s, a disk as a ``disk``. An annulus (``inner_radius`` > 0), a cone and a torus have
  no Mitsuba 3 shape: a scene with one is refused (:class:`NoMitsubaShape`), not drawn
  without it.

Needs the ``mitsuba`` package (a test dependency); imported when called.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..geometry.scene import Material, Scene, SceneError
from ..geometry.shapes import CONE, CYLINDER, DISK, TORUS
from ..gpu.gpu_layout import light_scale
from ..materials.pbr import PbrMaterial
from ..materials.pbr_brdf import alpha_of

PLANE_EXTENT = 1e4  # a plane's square, in units of the scene's size


def _rgb(c) -> dict:
    return {"type": "rgb", "value": [float(x) for x in c]}


def _bsdf(m: Material) -> dict:
    """The material's lobes as Mitsuba BSDFs (module docstring)."""
    wd, wr, wt = m.diffuse, m.reflective, m.transmissive
    total = wd + wr + wt
    if total > 1.0:
        wd, wr, wt = wd / total, wr / total, wt / total
    lobes: list[tuple[float, dict]] = []
    if wd > 0:
        lobes.append((wd, {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": _rgb(m.color)}}))
    if wr > 0:
        metal = (
            {
                "type": "roughconductor",
                "material": "none",
                "distribution": "ggx",
                "alpha": float(m.roughness),
                "sample_visible": True,  # Mitsuba's default, said here: the noise comparisons need it as ours
            }
            if m.roughness > 0
            else {"type": "conductor", "material": "none"}
        )
        lobes.append((wr, {"type": "twosided", "bsdf": metal}))
    if wt > 0:
        glass: dict[str, Any] = {"type": "dielectric", "int_ior": float(m.ior), "ext_ior": 1.0}
        if m.roughness > 0:
            # Both sample the visible normals (Heitz 2018). Mitsuba's other choice, the full distribution, widens
            # α by Walter's 1.2 − 0.2·√|cos θi| to sample but weights as if it had not: 1.9 % dark at grazing
            # incidence in a white furnace (α = 1, ior 1.01), where the visible normals agree with ours to 0.3 %.
            glass.update(
                {"type": "roughdielectric", "distribution": "ggx", "alpha": float(m.roughness), "sample_visible": True}
            )
        lobes.append((wt, glass))
    rest = 1.0 - sum(w for w, _ in lobes)
    if rest > 1e-12 or not lobes:
        lobes.append(
            (rest if lobes else 1.0, {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": _rgb((0, 0, 0))}})
        )
    # Fold right to left: blend(b, A, B) = (1 − b)·A + b·B.
    weight, bsdf = lobes[-1]
    for w, b in reversed(lobes[:-1]):
        share = weight / (weight + w) if weight + w > 0 else 0.0
        bsdf = {"type": "blendbsdf", "weight": share, "bsdf_0": b, "bsdf_1": bsdf}
        weight += w
    return bsdf


class NoMitsubaShape(SceneError):
    """A shape of our scene that Mitsuba 3 has no form for (``field`` names it)."""


class NoMitsubaMaterial(SceneError):
    """A material of our scene that no Mitsuba 3 BSDF matches (``field`` names it)."""


def _pbr_bsdf(m: PbrMaterial, where: str) -> dict:
    """A glTF metallic-roughness material as the Mitsuba BSDF of the same model (module docstring)."""
    alpha = float(alpha_of(m.roughness))
    sided = (lambda b: {"type": "twosided", "bsdf": b}) if m.double_sided else (lambda b: b)
    if m.metallic == 1.0:
        return sided(
            {
                "type": "roughconductor",
                "material": "none",
                "distribution": "ggx",
                "alpha": alpha,
                "specular_reflectance": _rgb(m.base_color),
                "sample_visible": True,
            }
        )
    if m.metallic == 0.0 and m.transmission == 1.0:
        return {
            "type": "roughdielectric",
            "distribution": "ggx",
            "alpha": alpha,
            "int_ior": float(m.ior),
            "ext_ior": 1.0,
            "specular_transmittance": _rgb(m.base_color),
            "sample_visible": True,
        }
    if m.metallic == 0.0 and m.transmission == 0.0 and m.ior == 1.0:
        return sided({"type": "diffuse", "reflectance": _rgb(m.base_color)})
    raise NoMitsubaMaterial(
        where,
        "Mitsuba 3 has the glTF material's model only where it is wholly metallic, wholly transmissive "
        f"or a dielectric of ior 1 (diffuse); this one has metallic {m.metallic}, transmission "
        f"{m.transmission}, ior {m.ior}",
    )


def _placed(mi: Any, point: Any, n: np.ndarray, scale: float) -> Any:
    """translate(point) · rotation of +z onto the unit vector n · scale: Mitsuba's disk and
    rectangle face +z."""
    axis = np.cross([0.0, 0.0, 1.0], n)
    length = float(np.linalg.norm(axis))
    angle = math.degrees(math.atan2(length, float(n[2])))
    # Mitsuba's rotate takes the axis as given: a non-unit one makes a skewed transform.
    axis = axis / length if length >= 1e-12 else np.array([1.0, 0.0, 0.0])
    return mi.ScalarTransform4f().translate(list(point)).rotate(axis.tolist(), angle).scale([scale] * 3)


def _disk(mi: Any, center: np.ndarray, normal: np.ndarray, radius: float, extras: dict) -> dict:
    """Mitsuba's ``disk`` (the unit disk at z = 0 facing +z) placed at ``center`` facing ``normal``."""
    return {"type": "disk", "to_world": _placed(mi, center.tolist(), normal, radius), **extras}


def _shapes(mi: Any, scene: Scene) -> dict:
    """The analytic shapes as Mitsuba shapes (module docstring); NoMitsubaShape for the others."""
    out: dict[str, Any] = {}
    sh = scene.shapes
    for i in range(len(sh)):
        p, kind, where = sh.params[i], int(sh.kind[i]), sh.where(i)
        if kind in (CONE, TORUS):
            raise NoMitsubaShape(where, f"Mitsuba 3 has no {'cone' if kind == CONE else 'torus'} shape")
        if kind == DISK and p[7] > 0.0:
            raise NoMitsubaShape(f"{where}.inner_radius", "Mitsuba 3 has no annulus (a disk with a hole)")
        extras = _shape_extras(scene, int(sh.material[i]))
        base, axis, radius = p[0:3], p[4:7], float(p[3])
        if kind == DISK:
            out[f"shape_{i}"] = _disk(mi, base, axis, radius, extras)
            continue
        assert kind == CYLINDER
        top = base + p[8] * axis
        out[f"shape_{i}"] = {"type": "cylinder", "p0": base.tolist(), "p1": top.tolist(), "radius": radius, **extras}
        if p[9]:
            out[f"shape_{i}_base"] = _disk(mi, base, -axis, radius, _shape_extras(scene, int(sh.material[i])))
            out[f"shape_{i}_top"] = _disk(mi, top, axis, radius, _shape_extras(scene, int(sh.material[i])))
    return out


def _shape_extras(scene: Scene, mat: int) -> dict:
    m = scene.materials[mat]
    bsdf = _pbr_bsdf(m, f"materials[{mat}]") if isinstance(m, PbrMaterial) else _bsdf(m)
    out: dict[str, Any] = {"bsdf": bsdf}
    if m.emits:
        out["emitter"] = {"type": "area", "radiance": _rgb(m.emission)}
    return out


def scene_dict(
    scene: Scene,
    width: int,
    height: int,
    spp: int,
    max_depth: int,
    seed: int = 0,
    rr_depth: int | None = None,
) -> dict:
    """The Mitsuba 3 scene dictionary (``mi.load_dict``) of ``scene``. ``rr_depth``: the path
    integrator's Russian roulette start (None: Mitsuba's default, 5; 3 starts it where ours does,
    docs/SHADING.md)."""
    import mitsuba as mi

    cam = scene.camera
    integrator: dict[str, Any] = {"type": "path", "max_depth": int(max_depth), "hide_emitters": False}
    if rr_depth is not None:
        integrator["rr_depth"] = int(rr_depth)
    out: dict[str, Any] = {
        "type": "scene",
        "integrator": integrator,
        "sensor": {
            "type": "perspective",
            "fov": float(cam.fov_y),
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=list(cam.position), target=list(cam.target), up=list(cam.up)
            ),
            "film": {
                "type": "hdrfilm",
                "width": int(width),
                "height": int(height),
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": int(spp), "seed": int(seed)},
        },
    }
    if any(scene.environment):
        out["environment"] = {"type": "constant", "radiance": _rgb(scene.environment)}
    env = scene.environment_map
    if env is not None:
        # Our equirect convention and rotation sense are Mitsuba's envmap's (renderer/materials/envmap.py).
        out["environment"] = {
            "type": "envmap",
            "bitmap": mi.Bitmap(np.array(env.texels, dtype=np.float32)),  # (a writable copy)
            "scale": env.scale,
            "to_world": mi.ScalarTransform4f().rotate([0.0, 1.0, 0.0], env.rotation_deg),
        }
    for i, light in enumerate(scene.lights):
        out[f"light_{i}"] = {
            "type": "point",
            "position": list(light.position),
            "intensity": _rgb(np.asarray(light.color) * light_scale(scene)),
        }
    for i in range(scene.n_spheres):
        out[f"sphere_{i}"] = {
            "type": "sphere",
            "center": scene.sphere_centers[i].tolist(),
            "radius": float(scene.sphere_radii[i]),
            **_shape_extras(scene, int(scene.sphere_materials[i])),
        }
    size = _size(scene)
    for i, p in enumerate(scene.planes):
        n = np.asarray(p.normal, dtype=np.float64)
        # A rectangle faces +z: rotate +z onto n, about their cross product.
        to_world = _placed(mi, p.point, n, PLANE_EXTENT * size)
        out[f"plane_{i}"] = {"type": "rectangle", "to_world": to_world, **_shape_extras(scene, p.material)}
    for i, mesh in enumerate(scene.meshes):
        r = scene.mesh_triangle_range(i)  # flat: a smooth mesh's vertex normals are not carried over
        tris = np.asarray(scene.triangle_corners[r.start : r.stop], dtype=np.float64).reshape(-1, 3, 3)
        out[f"mesh_{i}"] = {
            "type": "obj",
            "filename": _obj_file(tris),
            "face_normals": True,
            **_shape_extras(scene, mesh.material),
        }
    out.update(_shapes(mi, scene))
    return out


def _obj_file(tris: np.ndarray) -> str:
    """A temporary OBJ file of the triangles (corners in order, so each face's winding is kept)."""
    import tempfile

    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in tris.reshape(-1, 3)]
    lines += [f"f {3 * k + 1} {3 * k + 2} {3 * k + 3}" for k in range(len(tris))]
    with tempfile.NamedTemporaryFile("w", suffix=".obj", delete=False) as f:
        f.write("\n".join(lines) + "\n")
    return f.name


def _size(scene: Scene) -> float:
    pts = [np.asarray(scene.camera.position)]
    if scene.n_spheres:
        pts += list(scene.sphere_centers)
    if scene.n_triangles:
        pts += list(scene.triangle_corners.reshape(-1, 3))
    return float(max(1.0, np.abs(np.asarray(pts)).max()))


def load(
    scene: Scene,
    width: int,
    height: int,
    spp: int,
    max_depth: int,
    variant: str = "scalar_rgb",
    seed: int = 0,
    rr_depth: int | None = None,
) -> Any:
    """``scene`` loaded into Mitsuba 3 (``mi.Scene``, its variant set to ``variant``), ready for
    ``mi.render``; the arguments as :func:`scene_dict`'s."""
    import os

    import mitsuba as mi

    mi.set_variant(variant)
    d = scene_dict(scene, width, height, spp, max_depth, seed, rr_depth)
    try:
        return mi.load_dict(d)
    finally:  # the meshes' temporary OBJ files are read by now
        for v in d.values():
            if isinstance(v, dict) and v.get("type") == "obj":
                os.unlink(v["filename"])


def render(
    scene: Scene, width: int, height: int, spp: int, max_depth: int, variant: str = "scalar_rgb", seed: int = 0
) -> np.ndarray:
    """Mitsuba 3's ``path`` image of ``scene``: float32 H × W × 3 linear radiance, row 0 at the top."""
    import mitsuba as mi

    loaded = load(scene, width, height, spp, max_depth, variant, seed)
    # The stubs ask a UInt32 seed: in the scalar variants that is a Python int.
    image = mi.render(loaded, spp=spp, seed=seed)  # type: ignore[arg-type]
    return np.asarray(image, dtype=np.float32)[..., :3]
