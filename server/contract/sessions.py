"""What a session is made and moved with: the scene recipes and the creation body, the gestures of
the Controller, and the query of a model upload."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    Field,
)

from renderer.io.mesh_io import UPLOAD_FORMATS
from renderer.limits import (
    ASPECT_RANGE,
    MAX_ABSENT,
    MAX_MUSEUM_MOVING,
    MAX_SPHERES,
)
from renderer.scenes.scenarios import CUBE_HALF, MAX_MESH_DETAIL, MESH_SCENES

from .fields import MAX_SEED, Integral, ModelFormat, MuseumKind, QueryModel, Strict
from .scene import MaterialIndex, SceneModel
from .settings import SettingsPatch


# ---- sessions -------------------------------------------------------------------
class MuseumRecipe(Strict):
    """Reiter's BART-Museum analogue (renderer.scenes.animation.museum): ``n`` moving spheres in a
    static room of 576 spheres and the floor."""

    n: Annotated[int, Integral] = Field(ge=0, le=MAX_MUSEUM_MOVING, description="moving spheres")
    kind: MuseumKind = Field("deformable", description="rigid, deformable, incoherent or mixed (a third each)")
    seed: Annotated[int, Integral] = Field(0, ge=0, le=MAX_SEED)
    absent: float = Field(0.2, ge=0.0, le=MAX_ABSENT, description="incoherent spheres: fraction of a lifetime gone")


class MeshSceneRecipe(Strict):
    """A demo scene (renderer.scenes.scenarios.mesh_scene): ``spheres`` (scenario 1's 512 spheres in
    colour under the sky: the default scene), ``teapot`` (the closed Utah teapot on the
    floor), ``mixed`` (27 spheres, a glass icosphere and a torus), ``room`` (a box room seen from
    inside with a teapot, an icosphere and four spheres), ``cornell`` (a Cornell box lit by an
    emitting ceiling panel, with a mirror and a glass sphere and a teapot: for ``integrator=path``),
    ``table`` (analytic shapes only: a table with a torus, a can, a glass lens and a lamp whose
    shade holds an emitting disk; Whitted or ``integrator=path``), ``materials`` (glTF
    metallic-roughness materials on the project's own textures: a checkerboard, a wooden plank,
    a brushed metal ball, a wall of normal-mapped tiles, a tinted glass ball, under the sky)."""

    kind: Literal[MESH_SCENES] = Field("teapot", description=", ".join(MESH_SCENES))
    detail: Annotated[int, Integral] = Field(
        2,
        ge=0,
        le=MAX_MESH_DETAIL,
        description="tessellation: teapot 2 + 2·detail segments per patch, "
        "icosphere subdivisions, torus 12 (detail + 1) segments",
    )
    smooth: bool = Field(True, description="vertex normals (smooth shading); false: flat")
    sky: bool = Field(False, description="under the procedural daylight sky (environment 'sky')")


class SessionCreate(Strict):
    """Either a thesis scenario (``scenario`` and ``n``; ``seed``, ``radius`` optional),
    an animated ``museum``, a ``mesh_scene`` or a full ``scene``; optionally the session's
    first render settings."""

    scenario: Annotated[Literal[1, 2, 3], Integral] | None = Field(None, description="thesis scenario 1, 2 or 3")
    # The bounds inside the Annotated: on an optional field pydantic would write them to the schema
    # as "ge"/"le", which JSON Schema does not know (the schema said nothing of n's range).
    n: Annotated[int, Field(ge=0, le=MAX_SPHERES), Integral] | None = Field(None, description="number of spheres")
    seed: Annotated[int, Field(ge=0, le=MAX_SEED), Integral] | None = Field(
        None, description="random placement seed (default 0)"
    )
    radius: float | None = Field(None, gt=0.0, le=CUBE_HALF, description="sphere radius, world units (default 1)")
    sky: bool | None = Field(None, description="a scenario under the procedural daylight sky (default false)")
    museum: MuseumRecipe | None = None
    mesh_scene: MeshSceneRecipe | None = None
    scene: SceneModel | None = None
    settings: SettingsPatch | None = Field(
        None, description="render settings; a demo scene's recommended ones (GET /api/info's scenes) lie under them"
    )
    aspect: float | None = Field(
        None,
        ge=ASPECT_RANGE[0],
        le=ASPECT_RANGE[1],
        description=f"the client's canvas width / height ({ASPECT_RANGE[0]:g} … {ASPECT_RANGE[1]:g}): a recipe's "
        "camera is framed for it (its content's bounds inside the frame); a reset gesture frames again for it",
    )


# ---- gestures (the Controller) ------------------------------------------------------
class PanGesture(Strict):
    """One finger dragged by (dx, dy) screen pixels, right/down positive: the scene
    follows the finger at the target's distance."""

    type: Literal["pan"]
    dx: float = Field(ge=-1e6, le=1e6, description="pixels, right positive")
    dy: float = Field(ge=-1e6, le=1e6, description="pixels, down positive")
    viewport_height: float | None = Field(
        None,
        gt=0.0,
        le=1e5,
        description="height in the same pixels as dx/dy of the view showing the frame; default: the frame's height",
    )


class PinchGesture(Strict):
    """Two fingers: ``scale`` = new distance / old distance. > 1 (spread) moves the camera
    forward to distance / scale, < 1 back; it never reaches the target."""

    type: Literal["pinch"]
    scale: float = Field(ge=1e-3, le=1e3, description="finger distance ratio")


MAX_ORBIT_DEG = 360.0


class OrbitGesture(Strict):
    """Turn the camera about its target (the distance stays): ``yaw`` degrees about the
    camera's ``up`` vector, ``pitch`` degrees about its ``right`` vector (right-handed: yaw > 0
    moves the camera to its right, pitch > 0 moves it down). Pitch is clamped so that the
    view never passes over the up vector."""

    type: Literal["orbit"]
    yaw: float = Field(0.0, ge=-MAX_ORBIT_DEG, le=MAX_ORBIT_DEG, description="degrees about up, −360 … 360")
    pitch: float = Field(
        0.0,
        ge=-MAX_ORBIT_DEG,
        le=MAX_ORBIT_DEG,
        description="degrees about right, −360 … 360 (clamped short of the poles)",
    )


class ResetGesture(Strict):
    """Back to the camera the scene was created (or last replaced) with; for a session made with
    an ``aspect`` (or a reset that names one), that camera fitted to the whole scene (added models
    too) for the aspect."""

    type: Literal["reset"]
    aspect: float | None = Field(
        None,
        ge=ASPECT_RANGE[0],
        le=ASPECT_RANGE[1],
        description=f"the canvas's width / height ({ASPECT_RANGE[0]:g} … {ASPECT_RANGE[1]:g}); default: the session's",
    )


Gesture = Annotated[PanGesture | PinchGesture | OrbitGesture | ResetGesture, Field(discriminator="type")]


class MeshUploadQuery(QueryModel):
    """How an uploaded model file (the request body, bytes) becomes a mesh."""

    format: ModelFormat = Field(
        description="the file's format: " + ", ".join(UPLOAD_FORMATS) + " (zip: a model's folder, one model file "
        "with its .bin, .mtl and images)"
    )
    material: MaterialIndex | None = Field(
        None, description="index into the scene's materials (default: a neutral clay of its own, added to them)"
    )
    smooth: bool | None = Field(
        None,
        description="shading: the file's normals (default), true: smooth (the file's "
        "or area-weighted normals), false: flat",
    )
    size: float | None = Field(
        None,
        gt=0.0,
        le=2 * CUBE_HALF,
        description="scale the model so that its longest side is this many world units, "
        "centred on the y axis, standing on the floor y = −20 (default: as is)",
    )
