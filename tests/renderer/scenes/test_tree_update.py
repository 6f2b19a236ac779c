"""A frame's tree-update request (renderer.scenes.tree_update)."""

from __future__ import annotations

import dataclasses

import pytest

from renderer.scenes.tree_update import DEFAULT_THRESHOLD, REBUILD, UPDATE_SCHEMES, TreeUpdate


def test_the_default_request_rebuilds_with_nothing_moving():
    assert REBUILD == TreeUpdate() and REBUILD.scheme == "rebuild" == UPDATE_SCHEMES[0]
    assert REBUILD.threshold == DEFAULT_THRESHOLD and REBUILD.key is None and REBUILD.moving is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        REBUILD.scheme = "refit"  # type: ignore[misc]  # the default is shared: it must not change


@pytest.mark.parametrize("scheme", UPDATE_SCHEMES)
def test_every_scheme_is_accepted(scheme):
    assert TreeUpdate(scheme, key=("session", 1)).scheme == scheme


def test_an_unknown_scheme_is_refused_naming_the_schemes():
    with pytest.raises(ValueError, match="rebiuld.*rebuild, refit, selective"):
        TreeUpdate("rebiuld")
