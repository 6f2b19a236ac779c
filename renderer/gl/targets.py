"""Render targets of the tracer, reused between frames and bounded in bytes.

A target is a framebuffer with two RGBA32F attachments (the mode image with the primary
id, and the primary normal with t) — four for a path frame that writes the denoiser's guides
(their albedo and normal sums) — or, for a frame that needs only its 8-bit image (png
and jpeg at one sample per pixel), one RGBA8 attachment: its read-back costs
0.4 ms at 320 × 544 against 4.7 ms for the two float ones. Frames in flight each hold their own (frames of the
same size may be traced in turns, slice by slice), so the pool hands out a free one of
the size asked for or makes one. Free targets are kept for reuse as long as all targets
together stay within ``max_bytes``; beyond it the least recently released free ones are
released. Targets in use are never taken away: how many frames are in flight at once is
bounded by the service's admission (POCKETRAY_QUEUE_SIZE), so the memory of busy targets
is bounded by that times the largest accepted frame.
"""

from __future__ import annotations

from collections import OrderedDict

import moderngl

BYTES_PER_PIXEL = 2 * 4 * 4  # two RGBA32F attachments
GUIDE_BYTES_PER_PIXEL = 2 * 4 * 4  # … and two more for the denoiser's guides
BYTES_PER_PIXEL_RGBA8 = 4  # one RGBA8 attachment


class TargetPool:
    """Framebuffers by size. ``acquire`` → use → ``release``."""

    def __init__(self, ctx: moderngl.Context, max_bytes: int):
        self.ctx = ctx
        self.max_bytes = int(max_bytes)
        # glo → ((width, height, image_only, guides), framebuffer)
        self._free: OrderedDict[int, tuple[tuple[int, int, bool, bool], moderngl.Framebuffer]] = OrderedDict()
        self._busy: dict[int, tuple[tuple[int, int, bool, bool], moderngl.Framebuffer]] = {}

    @staticmethod
    def nbytes_of(width: int, height: int, image_only: bool = False, guides: bool = False) -> int:
        per_pixel = BYTES_PER_PIXEL_RGBA8 if image_only else BYTES_PER_PIXEL + (GUIDE_BYTES_PER_PIXEL if guides else 0)
        return int(width) * int(height) * per_pixel

    @property
    def nbytes(self) -> int:
        """GPU memory of every target this pool holds (free and busy)."""
        return sum(self.nbytes_of(*kind) for kind, _ in (*self._free.values(), *self._busy.values()))

    @property
    def sizes(self) -> list[tuple[int, int]]:
        return [kind[:2] for kind, _ in (*self._free.values(), *self._busy.values())]

    def acquire(self, width: int, height: int, image_only: bool = False, guides: bool = False) -> moderngl.Framebuffer:
        """A target of that size: two RGBA32F attachments (four with ``guides``), or one RGBA8 with
        ``image_only``."""
        kind = (int(width), int(height), bool(image_only), bool(guides) and not image_only)
        for key, (k, fbo) in self._free.items():
            if k == kind:
                del self._free[key]
                self._busy[key] = (k, fbo)
                return fbo
        self._trim(extra=self.nbytes_of(*kind))
        if image_only:
            attachments = [self.ctx.texture(kind[:2], 4, dtype="f1")]
        else:
            attachments = [self.ctx.texture(kind[:2], 4, dtype="f4") for _ in range(4 if kind[3] else 2)]
        fbo = self.ctx.framebuffer(color_attachments=attachments)
        self._busy[fbo.glo] = (kind, fbo)
        return fbo

    def release(self, fbo: moderngl.Framebuffer) -> None:
        entry = self._busy.pop(fbo.glo, None)
        if entry is None:
            return
        self._free[fbo.glo] = entry
        self._trim()

    def _trim(self, extra: int = 0) -> None:
        """Release free targets, least recently used first, until the pool (plus ``extra``
        bytes about to be made) fits ``max_bytes`` or nothing free is left."""
        while self._free and self.nbytes + extra > self.max_bytes:
            _, (_, fbo) = self._free.popitem(last=False)
            _release(fbo)

    def clear(self) -> None:
        for _, fbo in (*self._free.values(), *self._busy.values()):
            _release(fbo)
        self._free.clear()
        self._busy.clear()


def _release(fbo: moderngl.Framebuffer) -> None:
    for att in fbo.color_attachments:
        att.release()
    fbo.release()
