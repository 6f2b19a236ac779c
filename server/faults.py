"""What the service's parts raise for the API to answer (server/api/errors.py maps each to its status):
a rejected input (:class:`InputError`, 422 naming where), a missing session, a full stage, a late or
superseded frame."""

from __future__ import annotations

import re
from collections.abc import Iterable
from enum import StrEnum

from renderer.geometry.scene import SceneError

_PATH_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def field_path(field: str) -> list[str | int]:
    """``"scene.spheres[3].radius"`` → ``["scene", "spheres", 3, "radius"]``."""
    return [int(i) if i else name for name, i in _PATH_TOKEN.findall(field)]


class Where(StrEnum):
    """The part of a request an input came in: the first item of FastAPI's ``loc``."""

    BODY = "body"
    QUERY = "query"
    PATH = "path"


class InputError(SceneError):
    """A rejected input. ``loc`` is as FastAPI's errors (``("query", "width")``) once it starts with
    the part of the request (:class:`Where`); the service's parts raise it relative to the part the
    route names (``("width",)``) and the route places it (:meth:`at`, :func:`server.api.errors.located`);
    an input whose part the route cannot know (a gesture's field in a request whose settings are its
    query) is raised placed."""

    def __init__(self, loc: Iterable[str | int], message: str):
        loc = tuple(loc)
        inner = loc[1:] if loc and loc[0] in _PARTS else loc
        field = ""
        for part in inner:  # the JSON path as the renderer writes it: scene.meshes[0].triangles[12]
            field += f"[{part}]" if isinstance(part, int) else (f".{part}" if field else str(part))
        super().__init__(field or "body", message)
        self.loc = loc

    @property
    def placed(self) -> bool:
        return bool(self.loc) and self.loc[0] in _PARTS

    def at(self, where: Where) -> InputError:
        """This error in the request's ``where`` (itself when it is placed already)."""
        return self if self.placed else InputError((where, *self.loc), self.message)


_PARTS = frozenset(w.value for w in Where)


class FrameTooLarge(InputError):
    """A frame whose estimated memory alone is over what one frame may hold (POCKETRAY_MAX_FRAME_BYTES):
    no smaller slice of its samples fits better (the size is the pixels'), so a refinement stream
    stops at it."""


def input_error(e: SceneError) -> InputError:
    """A SceneError of the renderer as a rejected input at its field (relative: the route places it)."""
    return e if isinstance(e, InputError) else InputError(field_path(e.field), e.message)


class NotFound(Exception):
    """No such session (never existed, deleted, or expired)."""


class RenderTimeout(Exception):
    """An admitted render did not finish within ``render_timeout_s``."""

    def __init__(self, message: str, retry_after_s: int = 5):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class Busy(Exception):
    """Every slot of a bounded stage is taken (planning frames, reading large bodies): 503 + Retry-After."""

    def __init__(self, message: str, retry_after_s: int = 1):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class Superseded(Exception):
    """A frame stopped because the session asked for a newer one (latest wins), its client
    went away, or the session changed before a gesture's frame could be committed."""
