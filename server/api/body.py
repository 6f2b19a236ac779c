"""JSON request bodies: read strictly, and the large ones parsed and validated off the event loop.

FastAPI reads a JSON body with ``json.loads`` and validates it with pydantic on the event loop: a
16 MiB scene stalled every other request (``/api/health`` included) for seconds, and six of them
for 15 s. Routes with a JSON body use :class:`JSONBodyRoute`, which

- refuses what ``json.loads`` lets through: bytes that are not UTF-8 (it guesses UTF-16/32), a
  byte-order mark, duplicate keys (it keeps the last silently), nesting deeper than
  ``POCKETRAY_MAX_JSON_DEPTH`` (it reported 1,000 levels as "not valid UTF-8 JSON"), integers of
  more digits than Python converts — each a 422 with ``loc`` ``["body"]`` that says which;
- parses and validates bodies over :data:`INLINE_BODY_BYTES` on a pool of
  ``POCKETRAY_PARSE_WORKERS`` threads, at most ``POCKETRAY_QUEUE_SIZE`` such bodies per process at
  once (503 + ``Retry-After`` beyond, answered before the body is read), so their memory is
  bounded and the event loop only moves bytes;
- reads a large body, which holds one of those slots while it arrives, at a minimum rate: after
  ``POCKETRAY_BODY_GRACE_S`` it must keep up with ``POCKETRAY_BODY_MIN_RATE_BYTES_S`` (else 408,
  the connection closed, the slot freed), and one client address holds at most
  ``POCKETRAY_BODY_SLOTS_PER_CLIENT`` of the slots (429 + ``Retry-After`` beyond): eight
  connections trickling a byte every 4 s into 1 MB bodies held every slot for as long as they
  liked (each byte restarted the idle timer), and every honest body over 64 KiB got 503;
- hands FastAPI the validated model, which it takes as it is (no second validation of the
  spheres). When the body is invalid FastAPI still validates the query and the path, and the
  body's errors take the place of its own, in FastAPI's order (query first).

The WebSocket reads its messages with :func:`parse_json` too (``server.api.routes.ws``).
"""

from __future__ import annotations

import asyncio
import gc
import json
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.requests import ClientDisconnect, Request
from starlette.responses import Response

from ..config import ServerConfig
from ..faults import Busy

# Bodies up to this size are read on the event loop: a gesture or a settings patch is a few
# hundred bytes (parsed in microseconds) and must not wait behind a large scene in the pool;
# 64 KiB of scene JSON (~1,500 spheres) parses and validates in ~3 ms.
INLINE_BODY_BYTES = 64 * 1024
BODY_RETRY_AFTER_S = 1

_NOT_STRUCTURE = bytes(b for b in range(256) if b not in b'"[]{}')


class BodyError(ValueError):
    """A body that is not strict JSON: ``kind`` is the 422's ``type``."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind

    def validation_error(self) -> RequestValidationError:
        return RequestValidationError([{"type": self.kind, "loc": ("body",), "msg": str(self), "input": None}])


class BodiesBusy(Busy):
    """As many large bodies as the process admits are being read: 503 + Retry-After."""

    def __init__(self, admitted: int):
        super().__init__(
            f"busy: {admitted} large request bodies are being read (POCKETRAY_QUEUE_SIZE); "
            f"retry after {BODY_RETRY_AFTER_S} s",
            BODY_RETRY_AFTER_S,
        )


def body_too_slow(got: int, declared: str | None, seconds: float, config: ServerConfig) -> StarletteHTTPException:
    """408 for a large body that fell behind the minimum rate; the connection is closed with it
    (the rest of the body is never read)."""
    of = f" of {declared}" if declared and declared.isdigit() else ""
    return StarletteHTTPException(
        408,
        f"body: {got} bytes{of} arrived in {seconds:.1f} s, slower than {config.body_min_rate_bytes_s} bytes/s "
        f"after the first {config.body_grace_s:g} s (POCKETRAY_BODY_MIN_RATE_BYTES_S, POCKETRAY_BODY_GRACE_S); "
        "send the body faster, or a smaller one",
        {"Connection": "close"},
    )


def client_share_taken(host: str | None, held: int, config: ServerConfig) -> StarletteHTTPException:
    """429 for an address that already holds its share of the large-body slots."""
    return StarletteHTTPException(
        429,
        f"busy: this client address ({host}) already sends {held} large request bodies, its share of the "
        f"{config.queue_size} slots (POCKETRAY_BODY_SLOTS_PER_CLIENT); retry after {BODY_RETRY_AFTER_S} s, "
        "once one of them is read",
        {"Retry-After": str(BODY_RETRY_AFTER_S), "Connection": "close"},
    )


async def read_steadily(request: Request, config: ServerConfig) -> bytes:
    """The request's body, read while it keeps up with the minimum rate: by ``t`` seconds after
    the start, ``min_rate · (t − grace)`` bytes must have come. The wait for the next chunk is
    bounded by when the bytes so far stop being enough, so a silent body and a trickling one are
    both cut there (408), whatever the idle timer of the connection allows."""
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    rate, grace = float(config.body_min_rate_bytes_s), float(config.body_grace_s)
    chunks: list[bytes] = []
    got = 0
    while True:
        left = t0 + grace + got / rate - loop.time()
        try:
            if left <= 0:
                raise TimeoutError
            message = await asyncio.wait_for(request.receive(), left)
        except TimeoutError:
            raise body_too_slow(got, request.headers.get("content-length"), loop.time() - t0, config) from None
        if message["type"] == "http.disconnect":
            raise ClientDisconnect()
        chunk = message.get("body", b"")
        if chunk:
            chunks.append(chunk)
            got += len(chunk)
        if not message.get("more_body", False):
            break
    body = b"".join(chunks)
    request._body = body  # what Request.body() returns from now on (FastAPI's handler reads it)
    return body


class _DuplicateKey(Exception):
    def __init__(self, key: str):
        self.key = key


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        for k, _ in pairs:  # the first key given twice
            if k in seen:
                raise _DuplicateKey(k)
            seen.add(k)
    return out


def json_depth(raw: bytes) -> int:
    """Nesting depth of well-formed JSON, without a regex (``re`` holds the GIL through all 16 MiB:
    it stalled the event loop ~0.5 s). The escapes go first (an escaped backslash, then an escaped
    quote: what is left of ``"`` are the strings' own quotes), then everything but quotes and
    brackets; a bracket counts when an even number of quotes precede it."""
    structure = raw.replace(b"\\\\", b"").replace(b'\\"', b"").translate(None, _NOT_STRUCTURE)
    if not structure:
        return 0
    a = np.frombuffer(structure, np.uint8)
    in_string = (np.cumsum(a == ord('"'), dtype=np.int32) & 1).astype(bool)
    step = np.zeros(len(a), np.int32)
    step[(a == ord("[")) | (a == ord("{"))] = 1
    step[(a == ord("]")) | (a == ord("}"))] = -1
    step[in_string] = 0
    return int(np.cumsum(step).max())


def parse_json(raw: bytes | str, max_depth: int) -> Any:
    """``raw`` as strict JSON (RFC 8259: UTF-8, no byte-order mark; and here: each key once, at
    most ``max_depth`` levels), or :class:`BodyError`. ``NaN``/``Infinity`` literals are read, so that
    the field's validation names them (``allow_inf_nan=False`` everywhere)."""
    if isinstance(raw, bytes):
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise BodyError(
                "json_not_utf8",
                f"not UTF-8 (byte 0x{raw[e.start]:02x} at offset {e.start}); send JSON encoded as UTF-8",
            ) from None
    else:
        text, raw = raw, raw.encode("utf-8", "surrogatepass")
    if text.startswith("\ufeff"):
        raise BodyError("json_invalid", "starts with a byte-order mark; send UTF-8 JSON without one")
    too_deep = BodyError(
        "json_too_deep",
        f"JSON nested deeper than {max_depth} levels (POCKETRAY_MAX_JSON_DEPTH); no request needs more than 6",
    )
    try:
        value = json.loads(text, object_pairs_hook=_unique_keys)
    except _DuplicateKey as e:
        raise BodyError(
            "json_duplicate_key", f"duplicate key {json.dumps(e.key)} in an object; give each key once"
        ) from None
    except json.JSONDecodeError as e:
        raise BodyError(
            "json_invalid", f"not valid JSON: {e.msg} at line {e.lineno} column {e.colno} (offset {e.pos})"
        ) from None
    except RecursionError:
        raise too_deep from None
    except ValueError as e:  # e.g. an integer of more than sys.get_int_max_str_digits() digits
        raise BodyError("json_invalid", f"not a JSON value this service reads ({e})") from None
    if json_depth(raw) > max_depth:
        raise too_deep
    return value


class _NoFullCollections:
    """While large bodies are parsed, the garbage collector makes no full (generation 2) collection.

    A 16 MiB scene is ~1.6 million tracked objects (the JSON's dicts and lists, then the models);
    the collections their creation sets off traverse every live object, the GIL held, and stalled
    the event loop for up to 0.5 s per body (measured). Young collections go on (cyclic garbage is
    still found), the objects themselves are freed by their reference counts, and the threshold is
    restored when the last large body is done."""

    def __init__(self):
        self._lock = threading.Lock()
        self._holders = 0
        self._saved: tuple[int, int, int] | None = None

    def __enter__(self) -> None:
        with self._lock:
            if self._holders == 0:
                self._saved = gc.get_threshold()
                gc.set_threshold(self._saved[0], self._saved[1], 1 << 30)
            self._holders += 1

    def __exit__(self, *exc: Any) -> None:
        with self._lock:
            self._holders -= 1
            if self._holders == 0 and self._saved is not None:
                gc.set_threshold(*self._saved)


NO_FULL_COLLECTIONS = _NoFullCollections()
FREE_CHUNK = 2048


def release_gradually(value: Any, depth: int = 4) -> None:
    """Empty the long lists in ``value`` a chunk at a time: freeing 300,000 spheres at once holds the
    GIL ~60 ms; in chunks the other threads (the event loop) get their turns in between."""
    if depth <= 0:
        return
    if isinstance(value, dict):
        for item in value.values():
            release_gradually(item, depth - 1)
    elif isinstance(value, list) and len(value) > FREE_CHUNK:
        for stop in range(len(value) - FREE_CHUNK, -FREE_CHUNK, -FREE_CHUNK):
            del value[max(stop, 0) :]


def validate_body(field: Any, raw: bytes, max_depth: int) -> tuple[Any, Sequence[Any] | None]:
    """(the validated model, None) or (None, errors located under ``body``). ``field`` is the route's
    ``body_field``: validated exactly as FastAPI validates it (same adapter, same errors)."""
    try:
        parsed = parse_json(raw, max_depth)
    except BodyError as e:
        return None, e.validation_error().errors()
    value, errors = field.validate(parsed, {}, loc=("body",))
    release_gradually(parsed)  # the models hold copies: the JSON's tree goes, a chunk at a time
    return (value, None) if not errors else (None, errors)


def validate_large_body(field: Any, raw: bytes, max_depth: int) -> tuple[Any, Sequence[Any] | None]:
    """:func:`validate_body` for the pool's threads, without full collections meanwhile."""
    with NO_FULL_COLLECTIONS:
        return validate_body(field, raw, max_depth)


class BodyParsers:
    """The process's pool for large bodies: ``workers`` threads, ``admitted`` bodies at once."""

    def __init__(self, workers: int, admitted: int, per_client: int = 0):
        self.pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pocketray-body")
        self.admitted = admitted
        self.per_client = per_client  # slots one client address may hold (0: any number)
        self._in_flight = 0
        self._by_client: dict[str, int] = {}
        self._lock = threading.Lock()

    @classmethod
    def of(cls, request: Request) -> BodyParsers:
        """The app's parsers (made on first use from its config; ``app.state`` lives with the app)."""
        state = request.app.state
        parsers = getattr(state, "body_parsers", None)
        if parsers is None:
            config: ServerConfig = state.config
            parsers = state.body_parsers = cls(config.parse_workers, config.queue_size, config.body_slots_per_client)
        return parsers

    def try_admit(self, client: str | None = None) -> str | None:
        """Take a slot for a body from address ``client``: None when taken, else why not —
        ``"client"`` (the address holds its share) or ``"full"`` (every slot is held)."""
        with self._lock:
            held = self._by_client.get(client, 0) if client is not None else 0
            if client is not None and self.per_client and held >= self.per_client:
                return "client"
            if self._in_flight >= self.admitted:
                return "full"
            self._in_flight += 1
            if client is not None:
                self._by_client[client] = held + 1
            return None

    def release(self, client: str | None = None) -> None:
        with self._lock:
            self._in_flight -= 1
            if client is not None:
                held = self._by_client.get(client, 0) - 1
                if held > 0:
                    self._by_client[client] = held
                else:
                    self._by_client.pop(client, None)

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        return await asyncio.get_running_loop().run_in_executor(self.pool, fn, *args)


class _ParsedRequest(Request):
    """The request as FastAPI's handler sees it: the body already read, its JSON already validated."""

    def __init__(self, request: Request, raw: bytes, value: Any):
        super().__init__(request.scope, request.receive)
        self._raw, self._value = raw, value

    async def body(self) -> bytes:
        return self._raw

    async def json(self) -> Any:
        return self._value


def _is_json(request: Request) -> bool:
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    return kind == "application/json" or (kind.startswith("application/") and kind.endswith("+json"))


class JSONBodyRoute(APIRoute):
    """An APIRoute whose JSON body is read as described in the module docstring."""

    def get_route_handler(self) -> Callable[[Request], Any]:
        handler = super().get_route_handler()
        body_params = self.dependant.body_params
        if self.body_field is None or len(body_params) != 1:
            return handler  # no body, or an embedded one: FastAPI's own reading
        field = self.body_field

        async def route(request: Request) -> Response:
            if not _is_json(request):
                return await handler(request)  # FastAPI refuses it (a JSON object is expected)
            config: ServerConfig = request.app.state.config
            declared = request.headers.get("content-length")
            large = declared is None or not declared.isdigit() or int(declared) > INLINE_BODY_BYTES
            parsers = BodyParsers.of(request) if large else None
            client = request.client.host if request.client is not None else None
            if parsers is not None:
                refused = parsers.try_admit(client)
                if refused == "client":
                    raise client_share_taken(client, parsers.per_client, config)
                if refused == "full":
                    raise BodiesBusy(parsers.admitted)
            try:
                raw = await (read_steadily(request, config) if parsers is not None else request.body())
                if not raw:
                    return await handler(request)
                if parsers is not None and len(raw) > INLINE_BODY_BYTES:
                    value, errors = await parsers.run(validate_large_body, field, raw, config.max_json_depth)
                else:
                    value, errors = validate_body(field, raw, config.max_json_depth)
                parsed = _ParsedRequest(request, raw, value)
                del raw
                if errors is None:
                    return await handler(parsed)
                try:  # FastAPI validates the rest (query, path) and finds the body missing
                    return await handler(parsed)
                except RequestValidationError as e:
                    others = [err for err in e.errors() if not (err.get("loc") or ("",))[0] == "body"]
                    raise RequestValidationError([*others, *errors]) from None
            finally:
                if parsers is not None:
                    parsers.release(client)

        return route


__all__ = ["JSONBodyRoute", "BodyError", "BodiesBusy", "parse_json", "json_depth", "INLINE_BODY_BYTES"]
