"""Where the engine's run-time files are (renderer.resources)."""

from __future__ import annotations

from renderer.resources import SOURCE_ROOT, package_dir, shader_dir


def test_the_shader_directory_holds_the_tracer_and_the_methods():
    d = shader_dir()
    assert (d / "raytrace.frag").is_file()
    assert list(d.glob("method_*.glsl"))


def test_a_directory_not_in_the_package_is_the_checkouts():
    assert package_dir("renderer", "no-such-dir", "shaders") == SOURCE_ROOT / "shaders"
