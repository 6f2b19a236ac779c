"""How a frame's colour is computed, and how the path integrator's radiance is shown: the choices of
the ``integrator``, ``tone_map`` and ``denoise`` settings as types (docs/SHADING.md).

Each is a :class:`enum.StrEnum`: a member *is* its JSON string (``Integrator.PATH == "path"``,
``json.dumps`` writes ``"path"``), so the API, the stored sessions and the client see the same
values as the strings they send, while the code compares members a type checker knows.
"""

from __future__ import annotations

from enum import StrEnum


class Integrator(StrEnum):
    """The thesis's Whitted ray tree (point lights, Phong), or unidirectional path tracing of the
    same scene (one-pass methods only: ``Capabilities.integrators``)."""

    WHITTED = "whitted"
    PATH = "path"


class ToneMap(StrEnum):
    """How the path integrator's radiance becomes a png/jpeg pixel (docs/SHADING.md, "Tone mapping";
    :data:`renderer.image.tonemap.OPERATORS`)."""

    CLAMP = "clamp"
    REINHARD = "reinhard"
    ACES = "aces"


class Denoiser(StrEnum):
    """The path integrator's denoiser (:mod:`renderer.image.denoise`): none, Intel Open Image Denoise, or the
    edge-avoiding à-trous filter (:mod:`renderer.image.atrous`; the one a browser runs in device mode)."""

    OFF = "off"
    OIDN = "oidn"
    ATROUS = "atrous"


def values(choices: type[StrEnum]) -> tuple[str, ...]:
    """The JSON strings of an enumeration's members, in their order."""
    return tuple(m.value for m in choices)
