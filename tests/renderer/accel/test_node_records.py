"""The hierarchies' node records (renderer.accel.node_records): declared for every method's
node array, and docs/FORMATS.md's tables are theirs."""

from __future__ import annotations

from pathlib import Path

from renderer.accel.node_records import NODE_RECORDS, formats_markdown
from renderer.config.methods import METHODS
from renderer.gpu import gpu_layout


def test_formats_md_holds_the_tables_made_from_the_declarations():
    text = (Path(__file__).resolve().parents[3] / "docs" / "FORMATS.md").read_text()
    start = text.index("<!-- gpu-records")
    block = text[text.index("\n", start) + 1 : text.index("<!-- /gpu-records -->")].strip()
    assert block == formats_markdown(), "docs/FORMATS.md's GPU records differ; paste:\n" + formats_markdown()


def test_every_methods_node_array_has_a_declared_record():
    # A method's record arrays are its nodes, its leaf-order records and the scene's triangles and shapes.
    scene_arrays = {b.name for b in (gpu_layout.TRIANGLES, gpu_layout.TRI_NORMALS, gpu_layout.SHAPES)}
    nodes = {
        b.name
        for m in METHODS.values()
        for b in m.bindings
        if b.records and b.name not in scene_arrays and not b.name.endswith("_spheres")
    }
    assert nodes == {r.binding.name for r in NODE_RECORDS}


def test_the_shader_header_of_each_tree_declares_its_accessors():
    for name, record in (("bih", NODE_RECORDS[0]), ("bvh", NODE_RECORDS[1]), ("kdtree", NODE_RECORDS[2])):
        defines = METHODS[name].glsl_defines()
        for f in record.fields:
            assert f"#define {record.name}_{f.name}(i) " in defines
    twolevel = METHODS["twolevel"].glsl_defines()
    assert "#define bvh_node_left_min(i) " in twolevel and "#define kd_node_split(i) " in twolevel
