"""Newell's teapot as published (renderer.geometry.teapot_data): 32 bicubic patches over 306 points."""

from __future__ import annotations

import numpy as np

from renderer.geometry import teapot_data


def test_the_teapot_data_is_newells_32_patches_of_306_points():
    assert len(teapot_data.PATCHES) == 32 and len(teapot_data.VERTICES) == 306
    assert all(len(p) == 16 for p in teapot_data.PATCHES)
    used = {i for p in teapot_data.PATCHES for i in p}
    assert min(used) == 1 and max(used) == 306  # 1-based, as published
    v = np.array(teapot_data.VERTICES)
    # the lid's top and the bottom's centre are single points on the axis
    assert teapot_data.VERTICES[204 - 1] == (0.0, 0.0, 3.15) and teapot_data.VERTICES[270 - 1] == (0.0, 0.0, 0.0)
    assert v[:, 2].min() == 0.0 and v[:, 2].max() == 3.15
    assert sorted(teapot_data.GROUPS) == sorted(
        ["rim", "upper body", "lower body", "handle", "spout", "lid knob", "lid", "bottom"]
    )
