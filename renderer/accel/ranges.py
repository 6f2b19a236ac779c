"""Index ranges of many nodes at once, as the NumPy builds (bih, bvh) walk them.

A round of a build holds ``k`` nodes whose primitives are ranges ``[lo, lo + count)`` of
the index array. Concatenated, element ``i`` belongs to node ``seg[i]``, the node's
elements begin at ``starts[seg[i]]``, and it sits at position ``pos[i]`` of the array.
"""

from __future__ import annotations

import numpy as np


def segments(count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For nodes of ``count`` elements, concatenated: each node's first element, each element's node."""
    starts = np.zeros(len(count), dtype=np.int64)
    np.cumsum(count[:-1], out=starts[1:])
    return starts, np.repeat(np.arange(len(count), dtype=np.int64), count)


def positions(lo: np.ndarray, starts: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Each concatenated element's position in the index array (its node's range starts at ``lo``)."""
    return np.arange(len(seg), dtype=np.int64) + (lo - starts)[seg]


def expand(lo: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ranges ``[lo, lo + count)`` → (each element's node, its position, each node's first element)."""
    starts, seg = segments(count)
    return seg, positions(lo, starts, seg), starts
