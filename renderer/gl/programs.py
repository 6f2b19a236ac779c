"""Compiled programs of one context, bounded: the least recently used goes out first.

Every distinct shader variant a frame asks for (method × mode × depth × features × the host's
choices) is a program, and a program costs its compiled code — GLSL to NIR at link, LLVM's
machine code for each state it is drawn in — about 3 MiB resident each on llvmpipe (measured:
102 programs, +285 MiB; a colour frame's variant comes with its background's). Kept forever, a
client walking the settings grows the process without end; here at most ``max_programs`` are
kept (``renderer.limits.MAX_PROGRAMS``, ``POCKETRAY_MAX_PROGRAMS``).

A program evicted while a frame in flight still draws with it (frames are traced in slices,
other frames' slices in between) cannot be deleted yet: its GL objects are deleted once the
last Python reference to it is gone (a weak reference says when), by :meth:`ProgramCache.sweep`
on the GL thread — the only thread that may call GL. After deleting, ``malloc_trim`` hands the
freed heap back to the system: glibc keeps it otherwise (measured in ``docs/API.md``,
"Shader programs").

``charging(fn)``: while set, ``fn()`` runs before each compile — the service's per-session rate
of new variants raises there, before any GL work, so a refused frame compiled nothing.
"""

from __future__ import annotations

import ctypes
import weakref
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator
from contextlib import contextmanager
from typing import Any

import moderngl

from ..limits import MAX_PROGRAMS


def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim`` (None elsewhere: musl, macOS)."""
    try:
        fn = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn


class CachedProgram:
    """One compiled program and the vertex arrays made for it (by name: ``"quad"``)."""

    __slots__ = ("program", "vaos", "__weakref__")

    def __init__(self, program: moderngl.Program):
        self.program = program
        self.vaos: dict[str, moderngl.VertexArray] = {}

    def vao(self, name: str, make: Callable[[moderngl.Program], moderngl.VertexArray]) -> moderngl.VertexArray:
        """The vertex array ``name`` of this program, made by ``make(program)`` on first use."""
        vao = self.vaos.get(name)
        if vao is None:
            vao = self.vaos[name] = make(self.program)
        return vao


class ProgramCache:
    """Programs by key, at most ``max_programs`` (≥ 1), least recently used out.

    ``compiled`` and ``evicted`` count since creation; ``released`` counts the evicted programs
    whose GL objects are deleted (the others are still held by a frame in flight).
    """

    def __init__(self, max_programs: int = MAX_PROGRAMS, trim: bool = True):
        if max_programs < 1:
            raise ValueError(f"max_programs must be ≥ 1, got {max_programs}")
        self.max_programs = int(max_programs)
        self._entries: OrderedDict[Hashable, CachedProgram] = OrderedDict()
        # Evicted objects still referenced elsewhere: (weak reference to the moderngl object, its GL object).
        self._retired: list[tuple[weakref.ref, Any]] = []
        self._trim = _malloc_trim() if trim else None
        self._charge: Callable[[], None] | None = None
        self.compiled = self.evicted = self.released = 0

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def keys(self) -> list[Hashable]:
        """The keys held, least recently used first."""
        return list(self._entries)

    @property
    def retired(self) -> int:
        """Evicted programs and vertex arrays a frame in flight still holds (deleted by a later sweep)."""
        return len(self._retired)

    @contextmanager
    def charging(self, fn: Callable[[], None] | None) -> Iterator[None]:
        """Run ``fn()`` before every compile inside the block (it may raise to refuse it)."""
        before, self._charge = self._charge, fn
        try:
            yield
        finally:
            self._charge = before

    def get(self, key: Hashable, compile: Callable[[], moderngl.Program]) -> CachedProgram:
        """The entry of ``key``, compiled by ``compile()`` when not held; the most recently used now."""
        entry = self._entries.get(key)
        if entry is not None:
            self._entries.move_to_end(key)
            return entry
        if self._charge is not None:
            self._charge()
        entry = CachedProgram(compile())
        self.compiled += 1
        self._entries[key] = entry
        while len(self._entries) > self.max_programs:
            self._retire(self._entries.popitem(last=False)[1])
        self.sweep()
        return entry

    def peek(self, key: Hashable) -> CachedProgram | None:
        """The entry of ``key`` if held, its place in the order unchanged."""
        return self._entries.get(key)

    def find(self, program: moderngl.Program) -> CachedProgram | None:
        """The entry holding ``program`` (None: evicted, or never cached)."""
        for entry in reversed(self._entries.values()):
            if entry.program is program:
                return entry
        return None

    def _retire(self, entry: CachedProgram) -> None:
        self.evicted += 1
        # Vertex arrays first: each holds its program, which goes only after them.
        objs: list[moderngl.VertexArray | moderngl.Program] = [*entry.vaos.values(), entry.program]
        for obj in objs:
            self._retired.append((weakref.ref(obj), obj.mglo))
        entry.vaos.clear()

    def sweep(self) -> int:
        """Delete the GL objects of evicted programs nothing references any more; the count deleted.
        Call on the context's thread."""
        if not self._retired:
            return 0
        keep: list[tuple[weakref.ref, Any]] = []
        deleted = 0
        for ref, mglo in self._retired:
            if ref() is None:
                mglo.release()
                deleted += 1
            else:
                keep.append((ref, mglo))
        self._retired = keep
        self.released += deleted
        if deleted and self._trim is not None:
            self._trim(0)
        return deleted

    def clear(self) -> None:
        """Evict every program (deleted now where no frame holds it)."""
        while self._entries:
            self._retire(self._entries.popitem(last=False)[1])
        self.sweep()
