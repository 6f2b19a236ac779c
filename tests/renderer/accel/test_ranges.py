"""Index ranges of many nodes at once (renderer.accel.ranges), against a loop over the nodes."""

from __future__ import annotations

import numpy as np

from renderer.accel.ranges import expand, positions, segments


def test_expand_lists_every_element_of_every_range_with_its_node_and_position():
    lo = np.array([5, 0, 9, 2])
    count = np.array([2, 0, 3, 1])  # an empty node between
    seg, pos, starts = expand(lo, count)
    np.testing.assert_array_equal(seg, [0, 0, 2, 2, 2, 3])
    np.testing.assert_array_equal(pos, [5, 6, 9, 10, 11, 2])
    np.testing.assert_array_equal(starts, [0, 2, 2, 5])
    assert seg.dtype == pos.dtype == starts.dtype == np.int64


def test_segments_and_positions_agree_with_a_loop_over_random_ranges():
    rng = np.random.default_rng(1)
    count = rng.integers(0, 6, 50)
    lo = rng.integers(0, 1000, 50)
    starts, seg = segments(count)
    want_seg = [k for k, c in enumerate(count) for _ in range(c)]
    want_pos = [int(lo[k]) + i for k, c in enumerate(count) for i in range(c)]
    np.testing.assert_array_equal(seg, want_seg)
    np.testing.assert_array_equal(positions(lo, starts, seg), want_pos)
    np.testing.assert_array_equal(starts, np.concatenate([[0], np.cumsum(count)[:-1]]))
