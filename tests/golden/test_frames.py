"""The frame catalogue (``tests/golden/frames.py``): what the service renders does not change by accident.

Every one-pass method × mode (Whitted), the path integrator and the generic variant, on spheres,
spheres under the sky, triangles, analytic shapes and the Cornell box, at 24 × 16, rendered now,
equals bit for bit — float image, depth and primary ids — the frame that the code of
``frames.BASE_COMMIT`` rendered: the shader assembled from marks and sections, before the shaders
were made of whole chunks switched by ``FEATURE_*`` defines. ``frames.npz`` came from that
commit's checkout (``python -m tests.golden.frames --write <its worktree>``), never from the code
under test. It is a regression oracle; the correctness oracles remain the float64 reference
tracer's and Mitsuba's tests.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer.config.settings import RenderSettings
from tests.golden import frames as F

EXPECTED = np.load(F.FRAMES)
SCENES = F.scenes()
CASES = F.cases()


def test_the_catalogue_is_the_recorded_one():
    """Every case has its frame in the record, and the record nothing more (a case added needs
    its frame made from the base commit, not from the code under test)."""
    recorded = {k.rsplit("/", 1)[0] for k in EXPECTED.files}
    assert recorded == {key for key, _, _ in CASES}


@pytest.mark.parametrize("scene", list(SCENES))
def test_frames_equal_the_base_commits(gl_renderer, scene):
    differ = []
    for key, name, kw in CASES:
        if name != scene:
            continue
        res = gl_renderer.render(SCENES[name], RenderSettings(width=F.W, height=F.H, **kw))
        got = {"image": res.image, "depth": res.depth, "primid": res.primid}
        for array, value in got.items():
            want = EXPECTED[f"{key}/{array}"]
            if not np.array_equal(np.asarray(value), want, equal_nan=True):
                differ.append(f"{key}/{array}")
    assert not differ, f"{len(differ)} arrays differ from the base commit's, e.g. {differ[:6]}"
