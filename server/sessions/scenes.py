"""Scenes of sessions: request bodies → validated ``Scene``, stored *sources*, a cache.

A session's scene is stored as a *source*, not re-serialised for every change:

- a thesis scenario is its recipe ``{"scenario", "n", "seed", "radius"}`` (a few
  bytes; ``renderer.scenes.scenarios.scenario`` is deterministic), and an animated Museum
  its recipe ``{"museum": {"n", "kind", "seed", "absent"}}``;
- an uploaded scene is its small parts (and motions) as JSON plus the sphere arrays,
  the meshes' arrays (world-space vertices, triangles, normals, each mesh's rows
  concatenated; the JSON says how many rows are whose) and the analytic shapes' records
  (kind, 12 numbers, material: :class:`renderer.geometry.shapes.Shapes` as it holds them), in one
  compressed ``.npz``.

An animated scene (one with motions) is an :class:`~renderer.scenes.animation.AnimatedScene`;
``SessionScene`` is either kind. The renderer poses it at the frame's ``time``.

The camera is not part of the source (it lives in the session state), so a
gesture never rewrites the scene. ``SceneCache`` keeps recently used scenes per
process, keyed by the session's scene revision token, so a frame does not
rebuild its scene from the source either.
"""

from __future__ import annotations

import io
import json
import threading
import zipfile
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from renderer.geometry.scene import VERTEX_ATTRIBUTES, Camera, Material, Mesh, Scene, SceneError, make_mesh
from renderer.geometry.shapes import Shapes
from renderer.gpu import texture_layout
from renderer.materials.envmap import SKY_REF
from renderer.materials.kinds import material_from_json
from renderer.materials.texture import Texture
from renderer.scenes.animation import AnimatedScene, motion_from_json, motion_to_json, museum
from renderer.scenes.scenarios import content_box, object_boxes, scenario

from ..contract.scene import CameraModel, SceneModel

_RECIPE = b"R"
_ARRAYS = b"A"

SessionScene = Scene | AnimatedScene


def scene_from_model(
    model: SceneModel, where: str = "scene", images: dict[str, np.ndarray] | None = None
) -> SessionScene:
    """A validated Scene — an AnimatedScene when it has motions — from a request body
    (SceneError names the JSON field); ``images``: the environment images its JSON may name. The
    analytic shapes are read by the renderer from the small part (``Shapes.from_json``)."""
    small = model.model_dump(exclude={"spheres", "motions", "meshes"})
    small["environment"] = {k: v for k, v in small["environment"].items() if v is not None}
    try:
        base = Scene.from_json(small, images)
        n = len(model.spheres)
        centers = np.array([s.center for s in model.spheres], dtype=np.float64).reshape(n, 3)
        radii = np.array([s.radius for s in model.spheres], dtype=np.float64).reshape(n)
        mats = np.array([s.material for s in model.spheres], dtype=np.int64).reshape(n)
        meshes = []
        for i, m in enumerate(model.meshes):
            try:
                attributes = {a: getattr(m, a) for a, *_ in VERTEX_ATTRIBUTES if getattr(m, a) is not None}
                meshes.append(make_mesh(m.vertices, m.triangles, m.material, m.normals, m.transform, **attributes))
            except SceneError as e:
                raise SceneError(f"meshes[{i}].{e.field}", e.message) from None
        scene = base.with_geometry(centers, radii, mats, meshes)
        return with_motions(scene, [m.model_dump(exclude_none=True) for m in model.motions])
    except SceneError as e:
        raise SceneError(f"{where}.{e.field}" if where else e.field, e.message) from None


def with_motions(scene: Scene, motions: list[dict]) -> SessionScene:
    """``scene`` animated by the motions' JSON (SceneError ``motions[i].<field>``); no motions: ``scene``."""
    if not motions:
        return scene
    return AnimatedScene(scene, tuple(motion_from_json(m, f"motions[{i}]") for i, m in enumerate(motions)))


def museum_source(n: int, kind: str, seed: int, absent: float) -> bytes:
    return _RECIPE + json.dumps({"museum": {"n": n, "kind": kind, "seed": seed, "absent": absent}}).encode()


def camera_from_model(model: CameraModel, where: str = "camera") -> Camera:
    """A validated Camera (SceneError with ``camera.<field>``)."""
    return Camera.from_json(model.model_dump(), where)


def scenario_source(number: int, n: int, seed: int, radius: float, sky: bool = False) -> bytes:
    recipe: dict[str, Any] = {"scenario": number, "n": n, "seed": seed, "radius": radius}
    if sky:  # (absent otherwise: a source stored before skies reads the same)
        recipe["sky"] = True
    return _RECIPE + json.dumps(recipe).encode()


def scene_source(scene: SessionScene) -> bytes:
    """Lights, materials, planes, motions and how the meshes are cut as JSON; spheres, mesh
    rows and shape records as arrays (compressed npz). The meshes are stored in world space, as
    the scene holds them, and the shapes as their float64 records, so that a stored scene loads
    bit for bit as it was."""
    motions = [motion_to_json(m) for m in scene.motions] if isinstance(scene, AnimatedScene) else []
    if isinstance(scene, AnimatedScene):
        scene = scene.scene
    small: dict[str, Any] = {
        "lights": [x.to_json() for x in scene.lights],
        "materials": [m.to_json() for m in scene.materials],
        "planes": [p.to_json() for p in scene.planes],
        "motions": motions,
    }
    arrays: dict[str, Any] = {
        "centers": scene.sphere_centers,
        "radii": scene.sphere_radii,
        "materials": scene.sphere_materials,
    }
    env = environment_json(scene)
    if env is not None:
        small["environment"] = env
    if scene.environment_map is not None and scene.environment_map.ref != SKY_REF:
        # an uploaded image is stored beside the scene, uncompressed (the quota counts its texels);
        # the sky is made again from its name
        arrays["env_texels"] = scene.environment_map.texels
    if scene.meshes:
        small["meshes"] = [
            {"material": m.material, "vertices": len(m.vertices), "triangles": m.n_triangles, "smooth": m.smooth}
            | ({"attributes": sorted(m.attributes)} if m.attributes else {})
            for m in scene.meshes
        ]
        for name, *_ in VERTEX_ATTRIBUTES:  # (absent without: a source stored before them reads the same)
            rows = [getattr(m, name) for m in scene.meshes if getattr(m, name) is not None]
            if rows:
                arrays[f"mesh_{name}"] = np.concatenate(rows)
        arrays["mesh_vertices"] = np.concatenate([m.vertices for m in scene.meshes])
        arrays["mesh_triangles"] = np.concatenate([m.triangles for m in scene.meshes])
        smooth = [m.normals for m in scene.meshes if m.normals is not None]  # the smooth ones
        arrays["mesh_normals"] = np.concatenate(smooth) if smooth else np.zeros((0, 3))
    if scene.textures:
        # kept as decoded, uncompressed (the quota counts their texels, as an environment image's)
        small["textures"] = [{k: v for k, v in t.to_json().items() if k != "png"} for t in scene.textures]
        for i, t in enumerate(scene.textures):
            arrays[f"texture_{i}"] = t.pixels
    if scene.n_shapes:  # (absent for a scene without: a source stored before shapes reads the same)
        arrays["shape_kind"] = scene.shapes.kind
        arrays["shape_params"] = scene.shapes.params
        arrays["shape_materials"] = scene.shapes.material
    arrays["meta"] = np.frombuffer(json.dumps(small).encode(), dtype=np.uint8)
    return _ARRAYS + _npz(arrays, stored={"env_texels", *(f"texture_{i}" for i in range(len(scene.textures)))})


def _npz(arrays: dict[str, np.ndarray], stored: set[str]) -> bytes:
    """An ``.npz`` of ``arrays`` (``np.load`` reads it): compressed, except the members in
    ``stored``, kept as they are — an environment image's texels, which hardly compress, which the
    store's quota counts as the bytes the service holds, and whose compression took seconds."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, a in arrays.items():
            member = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_STORED if name in stored else zipfile.ZIP_DEFLATED
            with z.open(member, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.asanyarray(a), allow_pickle=False)
    return buf.getvalue()


def environment_json(scene: Scene) -> dict[str, Any] | None:
    """The scene's ``environment`` object of scene JSON (None: black, absent)."""
    if scene.environment_map is not None:
        return scene.environment_map.to_json()
    return {"color": list(scene.environment)} if any(scene.environment) else None


def _stored_meshes(cut: list[dict], z) -> tuple[Mesh, ...]:
    """The meshes of a stored source: ``cut`` says how many rows of each array are whose."""
    out, v0, t0, n0 = [], 0, 0, 0
    a0 = dict.fromkeys((name for name, *_ in VERTEX_ATTRIBUTES), 0)
    for m in cut:
        nv, nt = m["vertices"], m["triangles"]
        normals = None
        if m["smooth"]:
            normals = z["mesh_normals"][n0 : n0 + nv]
            n0 += nv
        attributes = {}
        for name in m.get("attributes", ()):
            attributes[name] = z[f"mesh_{name}"][a0[name] : a0[name] + nv]
            a0[name] += nv
        vertices, triangles = z["mesh_vertices"][v0 : v0 + nv], z["mesh_triangles"][t0 : t0 + nt]
        out.append(Mesh(vertices, triangles, m["material"], normals, **attributes))
        v0, t0 = v0 + nv, t0 + nt
    return tuple(out)


def load_source(source: bytes, camera: Camera) -> SessionScene:
    """The scene a source describes, seen through ``camera``."""
    kind, body = source[:1], source[1:]
    if kind == _RECIPE:
        r = json.loads(body)
        if "museum" in r:
            return museum(**r["museum"]).with_camera(camera)
        return scenario(r["scenario"], r["n"], r["seed"], r["radius"], r.get("sky", False)).with_camera(camera)
    if kind == _ARRAYS:
        with np.load(io.BytesIO(body), allow_pickle=False) as z:
            small = json.loads(z["meta"].tobytes())
            motions = small.pop("motions", [])
            meshes = _stored_meshes(small.pop("meshes", []), z)
            env = small.get("environment", {})
            images = {env["image"]: z["env_texels"]} if "env_texels" in z.files and "image" in env else None
            samplers = small.pop("textures", [])
            textures = tuple(Texture(z[f"texture_{i}"], **s) for i, s in enumerate(samplers))
            # (the materials read apart: their texture indices are checked against the textures below)
            stand_ins: list[dict[str, Any]] = [{}] * len(small["materials"])
            base = Scene.from_json({**small, "materials": stand_ins, "camera": camera.to_json()}, images)
            materials = tuple(material_from_json(m, f"materials[{i}]") for i, m in enumerate(small["materials"]))
            shapes = (
                Shapes(z["shape_kind"], z["shape_params"], z["shape_materials"])
                if "shape_kind" in z.files
                else Shapes.empty()
            )
            scene = Scene(
                camera,
                base.lights,
                materials,
                z["centers"],
                z["radii"],
                z["materials"],
                base.planes,
                meshes,
                base.environment,
                base.environment_map,
                shapes,
                textures,
            )
            return with_motions(scene, motions)
    raise ValueError("unknown scene source")


def _rows_json(rows: np.ndarray, per_chunk: int) -> Iterator[str]:
    """A JSON list of rows (``[[…],[…]]``, compact) in pieces of ``per_chunk`` rows."""
    yield "["
    for start in range(0, len(rows), per_chunk):
        text = json.dumps(rows[start : start + per_chunk].tolist(), separators=(",", ":"), allow_nan=False)[1:-1]
        yield text if start == 0 else "," + text
    yield "]"


def scene_json_chunks(scene: SessionScene, spheres_per_chunk: int = 20000) -> Iterator[bytes]:
    """The scene JSON (docs/FORMATS.md) of ``scene`` (exactly ``json.dumps(scene.to_json())``, compact) in
    pieces, so that a scene of 2^21 spheres (or 2^20 triangles) is sent without building it in memory.
    An animated scene is its rest pose plus ``motions``."""

    def dumps(obj: Any) -> str:
        return json.dumps(obj, separators=(",", ":"), allow_nan=False)

    tail = ""
    if isinstance(scene, AnimatedScene):
        tail = ',"motions":' + dumps([motion_to_json(m) for m in scene.motions])
        scene = scene.scene
    small = {
        "camera": scene.camera.to_json(),
        "lights": [x.to_json() for x in scene.lights],
        "materials": [m.to_json() for m in scene.materials],
    }
    yield (dumps(small)[:-1] + ',"spheres":[').encode()
    n = scene.n_spheres
    for start in range(0, n, spheres_per_chunk):
        stop = min(n, start + spheres_per_chunk)
        part = [
            {"center": c, "radius": r, "material": m}
            for c, r, m in zip(
                scene.sphere_centers[start:stop].tolist(),
                scene.sphere_radii[start:stop].tolist(),
                scene.sphere_materials[start:stop].tolist(),
                strict=True,
            )
        ]
        text = dumps(part)[1:-1]
        yield (text if start == 0 else "," + text).encode()
    yield ('],"planes":' + dumps([p.to_json() for p in scene.planes])).encode()
    if scene.meshes:  # as Mesh.to_json: vertices, triangles, material, normals
        rows = max(1, spheres_per_chunk * 2)
        yield b',"meshes":['
        for i, m in enumerate(scene.meshes):
            yield (("," if i else "") + '{"vertices":').encode()
            yield from (x.encode() for x in _rows_json(m.vertices, rows))
            yield b',"triangles":'
            yield from (x.encode() for x in _rows_json(m.triangles, rows))
            yield f',"material":{m.material}'.encode()
            if m.normals is not None:
                yield b',"normals":'
                yield from (x.encode() for x in _rows_json(m.normals, rows))
            for name, values in m.attributes.items():
                yield f',"{name}":'.encode()
                yield from (x.encode() for x in _rows_json(values, rows))
            yield b"}"
        yield b"]"
    if scene.textures:  # each a PNG in base64, as Scene.to_json
        yield b',"textures":['
        for i, t in enumerate(scene.textures):
            yield (("," if i else "") + dumps(t.to_json())).encode()
        yield b"]"
    for key, records in scene.shapes.to_json().items():  # each kind only when it has shapes, as Scene.to_json
        yield (f',"{key}":' + dumps(records)).encode()
    env = environment_json(scene)
    if env is not None:
        yield (',"environment":' + dumps(env)).encode()
    yield (tail + "}").encode()


def tree_primitives(info: dict[str, Any]) -> int:
    """:attr:`renderer.geometry.scene.Scene.n_tree_primitives` of the scene a session's ``scene_info`` describes
    (spheres, triangles and analytic shapes at rest; a kind the info leaves out has none): what
    ``method=auto`` chooses by without loading the scene."""
    return info.get("n_spheres", 0) + info.get("n_triangles", 0) + info.get("n_shapes", 0)


def scene_info(scene: SessionScene, recipe: dict[str, Any] | None = None) -> dict[str, Any]:
    rest = scene.scene if isinstance(scene, AnimatedScene) else scene
    info: dict[str, Any] = {"n_spheres": rest.n_spheres, "n_planes": len(rest.planes)}
    if rest.meshes:  # (absent for a sphere scene: the stored state stays as it was)
        info.update(
            n_meshes=len(rest.meshes),
            n_triangles=rest.n_triangles,
            n_unique_triangles=rest.n_triangles,  # (the service counts a model's instanced meshes once)
            n_degenerate_triangles=rest.n_degenerate_triangles,
        )
    if rest.n_shapes:  # (absent without: as the meshes')
        info["n_shapes"] = rest.n_shapes
    if rest.textures:  # the GPU bytes of its textures (every mip level, the array's padding) and attributes
        info.update(
            n_textures=len(rest.textures),
            texture_bytes=texture_layout.array_bytes(rest.textures),
            attribute_bytes=texture_layout.attribute_bytes(rest),
        )
    if isinstance(scene, AnimatedScene):
        info.update(animated=True, n_moving=int(scene.moving.sum()))
        if rest.meshes:
            info["n_moving_meshes"] = int(scene.moving_meshes.sum())
        if rest.n_shapes:
            info["n_moving_shapes"] = int(scene.moving_shapes.sum())
    if recipe:
        info.update(recipe)
    return info


# What a scene holds in memory, bytes: a sphere its centre, radius and material and the tree's
# share; a triangle its mesh's arrays and the flattened corners (and its vertex attributes as they
# are); an analytic shape its record and box; a texture its texels; an environment image everything
# it holds once drawn (EnvironmentMap.held_bytes).
SPHERE_BYTES = 36
TRIANGLE_BYTES = 144
SHAPE_BYTES = 144


def scene_bytes(scene: SessionScene) -> int:
    """The bytes ``scene`` holds (the :class:`SceneCache`'s weight)."""
    rest = scene.scene if isinstance(scene, AnimatedScene) else scene
    env = rest.environment_map
    geometry = SPHERE_BYTES * rest.n_spheres + TRIANGLE_BYTES * rest.n_triangles + SHAPE_BYTES * rest.n_shapes
    attributes = sum(a.nbytes for m in rest.meshes for a in m.attributes.values())
    texels = sum(t.nbytes for t in rest.textures)
    return geometry + attributes + texels + (env.held_bytes if env is not None and env.ref != SKY_REF else 0)


class SceneCache:
    """Least-recently-used scenes of this process, keyed by (session id, scene revision); one
    revision per session (a new one replaces the old, which is freed with everything its image
    holds once no frame uses it).

    Bounded by the bytes the scenes hold (:func:`scene_bytes`: geometry and environment images);
    the scene used last stays however large it is.
    """

    def __init__(self, max_bytes: int = 1 << 30):
        self.max_bytes = max_bytes
        self._items: OrderedDict[tuple[str, str], tuple[SessionScene, int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    @property
    def bytes_held(self) -> int:
        """The bytes of the scenes held now."""
        return self._bytes

    def get(self, key: tuple[str, str]) -> SessionScene | None:
        with self._lock:
            got = self._items.get(key)
            if got is None:
                return None
            self._items.move_to_end(key)
            return got[0]

    def put(self, key: tuple[str, str], scene: SessionScene) -> None:
        weight = scene_bytes(scene)
        with self._lock:
            for old in [k for k in self._items if k[0] == key[0]]:  # the session's other revisions
                self._bytes -= self._items.pop(old)[1]
            self._items[key] = (scene, weight)
            self._bytes += weight
            while len(self._items) > 1 and self._bytes > self.max_bytes:
                self._bytes -= self._items.popitem(last=False)[1][1]

    def drop_session(self, session_id: str) -> None:
        with self._lock:
            for key in [k for k in self._items if k[0] == session_id]:
                self._bytes -= self._items.pop(key)[1]


# ---- uploaded models: where they land -------------------------------------------------------
# A model's own material until model files' materials are read: a neutral clay, unlike any demo
# scene's, so that the model reads as added (Whitted: ambient, diffuse and a soft highlight;
# the path integrator: a light grey Lambertian).
CLAY = Material(
    color=(0.72, 0.72, 0.75),
    ambient=0.25,
    diffuse=0.75,
    specular=0.15,
    shininess=20.0,
    reflective=0.0,
    transmissive=0.0,
    ior=1.0,
)
PLACEMENT_GAP = 0.1  # of the model's longest side (at least 0.5 world units): free floor around it
PLACEMENT_RINGS = 16  # rings of candidate places searched around the scene's centre
PLACEMENT_SHRINK = (1.0, 0.6, 0.35, 0.2)  # scales tried, in order, where walls leave less room than the model


def _column_meets(lo: np.ndarray, hi: np.ndarray, footprints: np.ndarray) -> bool:
    """Whether the floor's rectangle ``lo``…``hi`` (x, z) meets any of ``footprints`` ((4, N):
    x and z lows, then highs): what stands on or hangs over it."""
    x0, z0, x1, z1 = footprints
    return bool(np.any((x0 < hi[0]) & (lo[0] < x1) & (z0 < hi[1]) & (lo[1] < z1)))


def free_floor_spot(scene: Scene, extent: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Where a model of box ``extent`` (x, y, z, world units) stands beside ``scene``'s objects:
    its box's bottom centre and the scale it gets, or None when no free floor is found.

    The floor is the highest upward facing plane under the scene (else its content's bottom);
    candidates lie on rings around the content's centre, nearest first, each box kept off every
    object's box by a gap (and nothing over it: a model under a table top is out of sight), in
    front of every other plane (a Cornell box's walls, its ceiling) and inside a room the camera
    is in. Between walls a place inside the content's footprint is sought
    first, at full size and then smaller; then one anywhere at full size (the rings reach past the
    content, so without walls a place is always found)."""
    box = content_box(scene)
    boxes = object_boxes(scene)
    if box.enclosure is not None:  # the room itself is no obstacle: its inside is the floor
        keep = ~np.all(np.isclose(boxes, box.enclosure), axis=(1, 2))
        boxes = boxes[keep]
    ups = [p.point[1] for p in scene.planes if p.normal[1] > 0.999 and p.point[1] <= box.lo[1] + 1e-9]
    floor = max(ups) if ups else (box.enclosure[0][1] if box.enclosure is not None else float(box.lo[1]))
    standing = boxes[boxes[:, 1, 1] > floor]  # (what lies under the floor is no obstacle)
    footprints = np.concatenate([standing[:, 0][:, [0, 2]], standing[:, 1][:, [0, 2]]], axis=1).T.copy()
    walls = [p for p in scene.planes if not (p.normal[1] > 0.999 and p.point[1] == floor)]
    centre = (box.lo + box.hi) / 2.0
    content_reach = float(np.max((box.hi - box.lo)[[0, 2]])) / 2.0
    right, _, forward = scene.camera.basis()
    ahead = forward[[0, 2]] / (np.hypot(*forward[[0, 2]]) or 1.0)
    # Between walls (or in a room) the model is first sought a place among them, shrunk if need be;
    # then, at its size, anywhere (the open side of a Cornell box).
    region = (box.enclosure if box.enclosure is not None else np.stack([box.lo, box.hi]))[:, [0, 2]]
    tries = [(k, True) for k in PLACEMENT_SHRINK] if (walls or box.enclosure is not None) else []
    for scale, within in [*tries, (1.0, False)]:
        size = extent * scale
        gap = max(0.5, PLACEMENT_GAP * float(size.max()))
        half = np.array([size[0] / 2.0 + gap, 0.0, size[2] / 2.0 + gap])
        step = max(float(max(size[0], size[2])) / 2.0, 0.5, content_reach / PLACEMENT_RINGS)
        rings = PLACEMENT_RINGS + int(content_reach / step) + 2
        spots = [np.array([centre[0], floor, centre[2]])]
        for k in range(1, rings + 1):
            for a in np.linspace(0.0, 2.0 * np.pi, 8 * k, endpoint=False):
                spots.append(np.array([centre[0] + k * step * np.cos(a), floor, centre[2] + k * step * np.sin(a)]))

        # nearest the centre first, the camera's sides counting nearer than its front and back (beside
        # the scene, neither hiding it nor hidden by it); at one distance, its right hand side first
        def order(p: np.ndarray) -> tuple[float, float]:
            away = (p - centre)[[0, 2]]
            dist = float(np.hypot(*away))
            along = abs(float(away @ ahead)) / dist if dist > 0 else 0.0
            return round(dist * (1.0 + 0.5 * along), 6), -float((p - centre) @ right)

        spots.sort(key=order)
        for spot in spots:
            cand = np.stack([spot - half, spot + half + np.array([0.0, size[1], 0.0])])
            cand[0, 1] = floor + 1e-6  # standing on the floor touches nothing else
            if within and not (np.all(cand[0][[0, 2]] >= region[0]) and np.all(cand[1][[0, 2]] <= region[1])):
                continue
            # free floor: nothing stands on it or hangs over it (a table top); every object stands
            # within the content's footprint, so a place outside it is free at once
            lo2, hi2 = cand[0][[0, 2]], cand[1][[0, 2]]
            inside = np.all(lo2 < box.hi[[0, 2]]) and np.all(box.lo[[0, 2]] < hi2)
            if inside and _column_meets(lo2, hi2, footprints):
                continue
            if box.enclosure is not None and not (
                np.all(cand[0] >= box.enclosure[0]) and np.all(cand[1] <= box.enclosure[1])
            ):
                continue
            corners = np.array([[cand[i, 0], cand[j, 1], cand[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
            if all(np.all((corners - p.point) @ np.asarray(p.normal) >= 0.0) for p in walls):
                return spot, scale
    return None


def placed_meshes(scene: Scene, meshes: Sequence[Mesh]) -> tuple[list[Mesh], np.ndarray]:
    """``meshes`` (a model's parts) moved together (and, where walls leave no room, shrunk) onto
    free floor beside ``scene``'s objects (:func:`free_floor_spot`); else to the right of
    everything, on the floor. Returns the meshes and their box's bottom centre."""
    lo = np.min([m.vertices.min(axis=0) for m in meshes], axis=0)
    hi = np.max([m.vertices.max(axis=0) for m in meshes], axis=0)
    bottom = np.array([(lo[0] + hi[0]) / 2.0, lo[1], (lo[2] + hi[2]) / 2.0])
    found = free_floor_spot(scene, hi - lo)
    if found is None:
        box = content_box(scene)
        spot, scale = np.array([box.hi[0] + (hi[0] - lo[0]) / 2.0 + 1.0, box.lo[1], bottom[2]]), 1.0
    else:
        spot, scale = found
    # a uniform scale and a shift: normals and tangents keep their directions
    moved = [
        Mesh((m.vertices - bottom) * scale + spot, m.triangles, m.material, m.normals, **m.attributes) for m in meshes
    ]
    return moved, spot
