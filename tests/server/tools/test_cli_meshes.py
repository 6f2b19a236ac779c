"""``pocketray render MODEL`` and ``pocketray scene --mesh`` (server/tools/cli.py): a model file
rendered directly (fitted, on the floor, framed) agrees with the float64 reference tracer
on the same scene; the scene JSON of model files passes the service's validation, renders
with ``render scene.json``, and places each model where its transform says; bad files and
flags are refused naming them, writing nothing."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh
from pocketray_server_support import pocketray_batch

from renderer.geometry.meshes import box, icosphere, torus
from renderer.geometry.scene import Scene
from renderer.io.mesh_io import export_mesh, load_mesh, load_model, model_scene
from renderer.oracle.reference import primary_rays, trace_rays

pytestmark = pytest.mark.gl  # render runs GLRenderer

W, H = 48, 40
# and a glTF with its buffers beside it (side files read from its folder), the same folder zipped
MODELS = ["ball.obj", "box.stl", "ring.ply", "ball.glb", "split/model.gltf", "split.zip"]
# The commands run several to a process (pocketray_batch: server.tools.cli.main as ``python -m server``
# calls it; tests/server/tools/test_cli.py runs the command as a process of its own).
COMMON = ("--width", str(W), "--height", str(H), "--spp", "1", "--quiet")


def reference_ids(scene: Scene, width: int = W, height: int = H) -> np.ndarray:
    o, d = primary_rays(scene.camera, width, height)
    _, ids = trace_rays(scene, o, d)
    return ids.reshape(height, width)


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> Path:
    """The model files, in a directory the module's commands share (each writes its own outputs)."""
    tmp = tmp_path_factory.mktemp("models")
    (tmp / "ball.obj").write_bytes(export_mesh(icosphere(2), "obj"))
    (tmp / "box.stl").write_bytes(export_mesh(box((0, 0, 0), (2, 1, 1)), "stl"))
    (tmp / "ring.ply").write_bytes(export_mesh(torus(1.0, 0.35, 16, 8), "ply"))
    (tmp / "ball.glb").write_bytes(export_mesh(icosphere(1), "glb"))
    m = icosphere(2)
    files = trimesh.Trimesh(m.vertices, m.triangles, process=False).export(file_type="gltf")
    assert len(files) > 1  # the model and its .bin side files
    (tmp / "split").mkdir()
    with zipfile.ZipFile(tmp / "split.zip", "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in files.items():
            (tmp / "split" / name).write_bytes(data)
            z.writestr(f"split/{name}", data)
    return tmp


@pytest.fixture(scope="module")
def renders(models) -> dict[str, object]:
    """Every ``render MODEL`` of the tests below, in one process: the primid frame of each model
    (``p-NAME.npy``), and of the ball at --size 10, its normals --flat and --smooth."""
    commands = {
        f"p-{name}.npy": ("render", name, "-o", f"p-{name.replace('/', '-')}.npy", "--mode", "primid", *COMMON)
        for name in MODELS
    }
    commands["small.npy"] = ("render", "ball.obj", "-o", "small.npy", "--size", "10", "--mode", "primid", *COMMON)
    commands["n.npy"] = ("render", "ball.obj", "-o", "n.npy", "--flat", "--mode", "normal", *COMMON)
    commands["s.npy"] = ("render", "ball.obj", "-o", "s.npy", "--smooth", "--mode", "normal", *COMMON)
    return dict(zip(commands, pocketray_batch(list(commands.values()), cwd=models), strict=True))


@pytest.mark.parametrize("name", MODELS)
def test_render_model_file_agrees_with_the_reference_on_the_fitted_scene(models, renders, name):
    r = renders[f"p-{name}.npy"]
    assert r.returncode == 0 and r.stderr == "", r.stderr
    got = np.load(models / f"p-{name.replace('/', '-')}.npy")
    scene = model_scene(models / name)
    want = reference_ids(scene)
    n_tri = load_mesh(models / name).n_triangles
    first = scene.triangle_id_base
    assert first == 1  # no sphere, one floor plane (id 0)
    on_mesh = (got >= first) & (got < first + n_tri)
    assert on_mesh.sum() > 0.03 * W * H  # the model fills a part of the frame (a torus edge-on too)
    assert (got == 0).any()  # and stands on the floor, which is seen
    # The frame's border rows and columns never hold the model: the camera frames it whole.
    border = np.concatenate([got[0], got[-1], got[:, 0], got[:, -1]])
    assert not ((border >= first) & (border < first + n_tri)).any()
    # Which kind of primitive each pixel sees agrees with float64, up to pixels on silhouettes.
    kind = lambda ids: np.where(ids >= first, 2, np.where(ids >= 0, 1, 0))
    assert (kind(got) != kind(want)).mean() < 0.03


def test_render_model_flags_shading_and_size(models, renders):
    # the ball at the default size: the same command as its fitted-scene frame above
    assert renders["p-ball.obj.npy"].returncode == 0 and renders["small.npy"].returncode == 0
    big, small = np.load(models / "p-ball.obj.npy"), np.load(models / "small.npy")
    assert 0 < (small >= 1).sum() < 0.5 * (big >= 1).sum()
    assert (small != reference_ids(model_scene(models / "ball.obj", size=10))).mean() < 0.03
    assert renders["n.npy"].returncode == 0 and renders["s.npy"].returncode == 0
    assert not np.array_equal(np.load(models / "n.npy"), np.load(models / "s.npy"))


def test_render_model_refuses_bad_files_and_flags_naming_them(models):
    (models / "bad.ply").write_text("this is not a ply file\n")
    cases = [
        (("render", "bad.ply", "-o", "x.png"), "model:"),
        (("render", "gone.obj", "-o", "x.png"), "model:"),
        (("render", "ball.obj", "-o", "x.png", "--size", "0"), "size:"),
        (("render", "ball.obj", "-o", "x.png", "--width", "0"), "width"),
        (("render", "ball.obj", "-o", "x.gif"), "output:"),
        (("scene", "--mesh", "bad.ply", "-o", "x.json"), "mesh:"),
        (("scene", "--mesh", "ball.obj", "--mesh", "gone.stl", "-o", "x.json"), "mesh:"),
    ]
    for (args, words), r in zip(cases, pocketray_batch([args for args, _ in cases], cwd=models), strict=True):
        assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
    assert not (models / "x.png").exists() and not (models / "x.json").exists()


def test_scene_of_meshes_validates_renders_and_places_each_model(models, client):
    r, out, as_is, std = pocketray_batch(
        [
            ("scene", "--mesh", "ball.obj", "--mesh", "box.stl", "--mesh", "ring.ply", "-o", "s.json"),
            (
                "render",
                "s.json",
                "-o",
                "p.npy",
                "--mode",
                "primid",
                "--width",
                "128",
                "--height",
                "64",
                "--spp",
                "1",
                "--quiet",
            ),
            ("scene", "--mesh", "box.stl", "--as-is", "-o", "raw.json"),
            ("scene", "--mesh", "ring.ply"),
        ],
        cwd=models,
    )
    assert r.returncode == 0, r.stderr
    doc = json.loads((models / "s.json").read_text())
    counts = [load_mesh(models / n).n_triangles for n in ("ball.obj", "box.stl", "ring.ply")]
    assert [len(m["triangles"]) for m in doc["meshes"]] == counts
    # The file's own coordinates, with a transform (editable); the service takes the scene as it is.
    assert np.allclose(doc["meshes"][0]["vertices"], load_model(models / "ball.obj").parts[0].vertices)
    sid = client.post("/api/sessions", json={"scene": doc, "settings": {"width": W, "height": H}})
    assert sid.status_code == 201, sid.text
    info = sid.json()["scene_info"]
    assert info["n_meshes"] == 3 and info["n_triangles"] == sum(counts) and info["n_planes"] == 1
    # Side by side along x, on the floor, each within its third of the 30-unit row.
    served = client.get(f"/api/sessions/{sid.json()['id']}/scene").json()
    for i, m in enumerate(served["meshes"]):
        v = np.asarray(m["vertices"])
        assert v[:, 1].min() == pytest.approx(-20.0)
        assert -15 + 10 * i - 1e-9 <= v[:, 0].min() and v[:, 0].max() <= -15 + 10 * (i + 1) + 1e-9
    # render scene.json: the triangles where the float64 reference sees them
    assert out.returncode == 0, out.stderr
    got = np.load(models / "p.npy")
    from server.api.schemas import SceneModel
    from server.sessions.scenes import scene_from_model

    want = reference_ids(scene_from_model(SceneModel.model_validate(doc)), 128, 64)
    first = 1
    for i, n in enumerate(counts):  # every mesh is seen, mostly where the reference sees it
        lo = first + sum(counts[:i])
        seen, ref = (got >= lo) & (got < lo + n), (want >= lo) & (want < lo + n)
        assert seen.sum() > 10 and (seen != ref).sum() < 0.15 * ref.sum(), i
    # --as-is: no transform, the file's coordinates
    assert as_is.returncode == 0, as_is.stderr
    raw = json.loads((models / "raw.json").read_text())
    assert "transform" not in raw["meshes"][0]
    assert np.asarray(raw["meshes"][0]["vertices"]).max(axis=0).tolist() == [2.0, 1.0, 1.0]
    # standard output by default
    assert std.returncode == 0 and len(json.loads(std.stdout)["meshes"][0]["triangles"]) == counts[2]
