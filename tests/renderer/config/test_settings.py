"""Render settings (renderer.config.settings): JSON in and out, and every bad value names its field.

Frame and tree settings, the animation's (time, update scheme, threshold), the knobs
that trade speed for accuracy (supersampling, weight cut-off, specialisation, method)
and the hierarchical ray engine's tile size.
"""

from __future__ import annotations

import pytest

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import SceneError


def test_settings_validation_and_json():
    s = RenderSettings.from_json({"width": 320, "height": 544, "mode": "heat"})
    assert RenderSettings.from_json(s.to_json()) == s
    for kw, field in [
        ({"width": 0}, "width"),
        ({"height": 4097}, "height"),
        ({"mode": "x"}, "mode"),
        ({"format": "gif"}, "format"),
        ({"max_tree_depth": 65}, "max_tree_depth"),
        ({"max_recursion_depth": 9}, "max_recursion_depth"),
        ({"width": True}, "width"),
    ]:
        with pytest.raises(SceneError) as e:
            RenderSettings(**kw)
        assert e.value.field == field
    with pytest.raises(SceneError) as e:
        RenderSettings.from_json({"widht": 3})
    assert e.value.field == "widht"


# animation


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"time": -1.0}, "time"),
        ({"time": float("nan")}, "time"),
        ({"time": 2e6}, "time"),
        ({"update": "sometimes"}, "update"),
        ({"update_threshold": -0.1}, "update_threshold"),
    ],
)
def test_bad_settings_name_the_field(kw, field):
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert e.value.field == field


# knobs


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"samples_per_pixel": 3}, "samples_per_pixel"),
        ({"width": 4096, "samples_per_pixel": 4}, "samples_per_pixel"),
        ({"min_weight": -0.1}, "min_weight"),
        ({"min_weight": float("nan")}, "min_weight"),
        ({"specialize": "yes"}, "specialize"),
        ({"method": "kd"}, "method"),
    ],
)
def test_knob_validation(kw, field):
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert e.value.field == field


# hierarchical ray engine


@pytest.mark.parametrize("bad", [0, 1, -3, 65, 2.5, True, "16"])
def test_bad_tile_size_is_a_clear_error(bad):
    with pytest.raises(SceneError) as e:
        RenderSettings(width=16, height=16, method="hre", tile_size=bad)
    assert e.value.field == "tile_size"


# one declaration per setting (renderer.config.settings.SETTINGS)


def test_render_settings_are_the_declared_engine_settings():
    """RenderSettings' fields, order and defaults are the table's; quality is the service's (the encoder's)."""
    from dataclasses import fields

    from renderer.config.settings import SETTINGS

    engine = [s for s in SETTINGS if s.engine]
    assert [(f.name, f.default) for f in fields(RenderSettings)] == [(s.name, s.default) for s in engine]
    assert RenderSettings.names() == tuple(s.name for s in engine)
    assert [s.name for s in SETTINGS if not s.engine] == ["quality", "refine_samples", "refine_time_ms", "refine_noise"]
    assert RenderSettings().to_json() == {s.name: s.default for s in engine}
    for s in SETTINGS:
        s.check(s.default)  # every default is one of its values
        assert s.label and s.doc and s.methods() and s.metadata()["modes"]


def test_each_setting_names_the_methods_that_read_it():
    """A setting read per method points at Capabilities.settings (the registry line says which)."""
    from renderer.config.methods import capabilities
    from renderer.config.settings import METHOD_NAMES, setting

    assert setting("max_prims").methods() == [
        m for m in METHOD_NAMES if "max_prims" in capabilities(m, 1 << 30).settings
    ]
    assert "bih" in setting("max_prims").methods() and "kdtree" not in setting("max_prims").methods()
    assert setting("tile_size").methods() == ["hre"]
    assert setting("update_threshold").methods() == setting("update").methods()
    assert setting("width").methods() == list(METHOD_NAMES)


def test_a_setting_added_to_the_declaration_is_validated(monkeypatch):
    """One entry in the table and its field is a RenderSettings field with its default, bounds and messages."""
    import dataclasses

    import renderer.config.settings as declared
    from renderer.config.settings import SETTINGS, SettingSpec

    extra = SettingSpec("gain", "number", 1.0, "brightness factor of the image", "Gain", bounds=(0.0, 4.0))
    choice = SettingSpec("tonemap", "string", "none", "tone mapping", "Tone mapping", choices=("none", "reinhard"))
    monkeypatch.setattr(declared, "SETTINGS", (*SETTINGS, extra, choice))
    Settings = dataclasses.make_dataclass(
        "RenderSettings",
        [("gain", float, dataclasses.field(default=1.0)), ("tonemap", str, dataclasses.field(default="none"))],
        bases=(RenderSettings,),
        frozen=True,
    )
    declared.check_declaration(Settings)
    s = Settings(gain=2.5)
    assert (s.gain, s.tonemap, s.width) == (2.5, "none", 640)
    assert Settings.from_json(s.to_json()) == s
    for kw, message in [
        ({"gain": 5.0}, "must be a number in [0, 4], got 5.0"),
        ({"gain": True}, "must be a number in [0, 4], got True"),
        ({"tonemap": "aces"}, "unknown tonemap 'aces'; one of none, reinhard"),
    ]:
        with pytest.raises(SceneError) as e:
            Settings(**kw)
        assert (e.value.field, e.value.message) == (next(iter(kw)), message)
    with pytest.raises(SceneError) as e:
        RenderSettings.from_json({"gain": 2.0})  # the class as it is has no such field
    assert e.value.field == "gain"
    with pytest.raises(TypeError, match="gain"):
        declared.check_declaration(RenderSettings)  # the table has a setting the class lacks
    with pytest.raises(ValueError):
        SettingSpec("bad", "string", "x", "a string without choices", "Bad")


# the class and the table agree: names, order, types, defaults


def test_the_class_and_the_table_agree_and_a_drift_is_caught():
    import dataclasses
    import typing

    from renderer.config.settings import SETTINGS, SettingValues, check_declaration, check_values_type
    from renderer.integrators import Integrator

    check_declaration()  # names, order, types (a StrEnum of the declared choices) and defaults
    check_values_type()
    hints = typing.get_type_hints(RenderSettings)
    engine = {s.name: s for s in SETTINGS if s.engine}
    for f in dataclasses.fields(RenderSettings):
        assert f.default == engine[f.name].default and issubclass(hints[f.name], engine[f.name].python_type)
    assert hints["integrator"] is Integrator
    assert set(typing.get_type_hints(SettingValues)) == {s.name for s in SETTINGS}

    def drifted(name: str, annotation: object, default: object) -> type:
        keep = [(f.name, hints[f.name], f.default) for f in dataclasses.fields(RenderSettings) if f.name != name]
        at = [f.name for f in dataclasses.fields(RenderSettings)].index(name)
        keep.insert(at, (name, annotation, default))
        return dataclasses.make_dataclass("RenderSettings", keep, frozen=True)

    assert check_declaration(drifted("width", int, 640)) is None  # a faithful copy passes
    for name, annotation, default, says in [
        ("width", int, 641, "defaults to 641"),
        ("exposure", int, 0, "declared number"),
        ("specialize", int, 1, "declared boolean"),
        ("integrator", str, "whitted", None),  # a plain string passes: the table's choices still check it
        ("tone_map", Integrator, Integrator.WHITTED, "members"),
    ]:
        cls = drifted(name, annotation, default)
        if says is None:
            check_declaration(cls)
            continue
        with pytest.raises(TypeError, match=says):
            check_declaration(cls)
    missing = dataclasses.make_dataclass(
        "RenderSettings", [(f.name, hints[f.name], f.default) for f in dataclasses.fields(RenderSettings)][:-1]
    )
    with pytest.raises(TypeError, match="update_threshold"):
        check_declaration(missing)


def test_choices_that_are_types_are_their_members_and_their_json_strings():
    import json

    from renderer.integrators import Denoiser, Integrator, ToneMap

    s = RenderSettings(integrator="path", tone_map="aces", denoise="oidn")
    assert s.integrator is Integrator.PATH and s.tone_map is ToneMap.ACES and s.denoise is Denoiser.OIDN
    assert s == RenderSettings(integrator=Integrator.PATH, tone_map=ToneMap.ACES, denoise=Denoiser.OIDN)
    out = s.to_json()
    assert type(out["integrator"]) is str and out["integrator"] == "path"
    assert json.loads(json.dumps(out)) == out
    assert RenderSettings.from_json(out) == s
    with pytest.raises(SceneError) as e:
        RenderSettings(integrator="paths")
    assert e.value.message == "unknown integrator 'paths'; one of whitted, path"


# samples_per_pixel and max_recursion_depth: what each integrator accepts, declared


@pytest.mark.parametrize(
    "kw,message",
    [
        ({"samples_per_pixel": 7}, "must be one of (1, 4, 9, 16), got 7 (any count 1 … 4096 with integrator 'path')"),
        ({"samples_per_pixel": 4097, "integrator": "path"}, "must be in 1 … 4096, got 4097"),
        ({"max_recursion_depth": 9}, "must be in 1 … 8, got 9 (up to 16 with integrator 'path')"),
        (
            {"max_recursion_depth": 9, "integrator": "path", "mode": "recursion"},  # the recursion mode is Whitted's
            "must be in 1 … 8, got 9 (up to 16 with integrator 'path')",
        ),
        ({"width": 2049, "samples_per_pixel": 4}, "2049×1088 at 4 samples needs 4098×2176, over the 4096 limit"),
    ],
)
def test_each_integrator_has_its_own_values(kw, message):
    field = "max_recursion_depth" if "max_recursion_depth" in kw else "samples_per_pixel"
    with pytest.raises(SceneError) as e:
        RenderSettings(**kw)
    assert (e.value.field, e.value.message) == (field, message)


def test_the_path_integrator_takes_any_count_and_whitted_a_grid():
    path = RenderSettings(integrator="path", samples_per_pixel=7, max_recursion_depth=12, width=4096, height=4096)
    assert path.supersampling == 1
    assert RenderSettings(integrator="path", mode="heat", max_recursion_depth=12).max_recursion_depth == 12
    assert [RenderSettings(samples_per_pixel=s, width=64, height=64).supersampling for s in (1, 4, 9, 16)] == [
        1,
        2,
        3,
        4,
    ]


def test_the_two_meanings_of_samples_per_pixel_are_declared_and_described():
    from renderer.config.settings import setting
    from renderer.limits import MAX_PATH_SAMPLES, PATH_SAMPLE_CHOICES, SAMPLES_PER_PIXEL

    spec = setting("samples_per_pixel")
    info = spec.metadata()["integrators"]
    assert info["whitted"]["choices"] == list(SAMPLES_PER_PIXEL) and info["whitted"]["subpixel_grid"]
    assert info["whitted"]["offered"] == list(SAMPLES_PER_PIXEL)
    assert (info["path"]["minimum"], info["path"]["maximum"]) == (1, MAX_PATH_SAMPLES)
    assert info["path"]["choices"] is None and not info["path"]["subpixel_grid"]
    assert info["path"]["offered"] == list(PATH_SAMPLE_CHOICES)
    words = spec.description()
    assert "whitted: a k × k grid of sub-pixels" in words and "one of 1, 4, 9, 16" in words
    assert f"path: paths per pixel, 1 … {MAX_PATH_SAMPLES}" in words
    assert setting("width").metadata()["integrators"] is None and setting("width").description() == setting("width").doc
    with pytest.raises(ValueError, match="leave its bounds"):
        from dataclasses import replace

        replace(spec, bounds=(1, 8))  # Whitted's 16 and path's 4096 outside


def test_a_type_checker_sees_the_fields(tmp_path):
    """mypy refuses a misspelt setting and a field used as the wrong type (the project's settings and cache,
    .mypy_cache/, which tests/test_tools.py's run keeps warm)."""
    import subprocess
    import sys

    from tests.helpers import ROOT

    code = tmp_path / "uses_settings.py"
    code.write_text(
        "from renderer.config.settings import RenderSettings\n"
        "s = RenderSettings()\n"
        "a = s.samples_per_pixl\n"
        "b: str = s.width\n"
        "c: int = s.samples_per_pixel\n"
    )
    out = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-error-summary", str(code)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    errors = [line.split(": error: ", 1)[1] for line in out.stdout.splitlines() if ": error: " in line]
    assert len(errors) == 2, out.stdout + out.stderr
    assert '"RenderSettings" has no attribute "samples_per_pixl"' in errors[0]
    assert 'expression has type "int", variable has type "str"' in errors[1]
