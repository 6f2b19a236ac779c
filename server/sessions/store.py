"""State backends behind one interface: SQLite (embedded, default) and Redis (shared).

A session is two records:

- its *state* (small JSON: version, camera, home camera, render defaults, scene
  info, the scene's revision token) — rewritten by every change;
- its *scene source* (bytes, see :mod:`server.sessions.scenes`) — written only when the
  scene is created or replaced, so a gesture writes a few hundred bytes, not
  the scene.

Every change is a read–modify–write done atomically (SQLite: one ``BEGIN
IMMEDIATE`` transaction; Redis: ``WATCH``/``MULTI``): ``mutate`` gets the
current state and returns the new one; if it raises, nothing is written. The
store bumps ``version`` and the idle clock itself.

Idle expiry: a session not read or written for ``ttl_s`` seconds is gone
(SQLite: checked on access and purged on create; Redis: key TTLs). Reads
refresh the idle clock at most every ``touch_interval_s`` seconds so a stream
of frame requests does not turn into a stream of writes (Redis: the state key's
TTL by the read itself, ``GETEX``; the scene key's at most every interval).

Quota: the bytes of all sessions' scene sources (recipes, uploaded scenes and the model files
added to them) are counted in the store itself, in the same transaction as the writes (SQLite:
triggers on the scenes table keep a counter row; Redis: one Lua script writes a session's scene
and its byte count, and gives back the bytes of sessions whose scene key expired). A create, or a
change that grows a scene, that would take the total over ``max_bytes`` raises
:class:`StoreFull` and writes nothing; existing sessions keep working, and a change that does
not grow its scene is never refused.

Faults are reported, never papered over: every failure is a
:class:`StoreUnavailable` (or the driver's own error), answered 503. The SQLite
store checks before each transaction that its file is still the one it opened (a
file deleted or replaced under the running service would otherwise take writes
that no restart finds); ``probe`` reads and writes a probe record the way requests
do (``/api/ready``); a file that is not a database at start-up is moved aside or
refused (``POCKETRAY_SQLITE_ON_CORRUPT``). Redis retries a change that collides with
another process's at most ``max_retries`` times.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol, cast

from renderer.config.settings import SettingValues

log = logging.getLogger("pocketray.store")


class StoreUnavailable(Exception):
    """The store cannot serve a request (its message says why, without paths; the log has them)."""

    retry_after_s = 1


class StoreFull(Exception):
    """The store's quota (``max_bytes``) would be passed by this write; nothing was written."""

    def __init__(self, used: int, wanted: int, limit: int):
        super().__init__(f"{used} of {limit} bytes used, {wanted} more wanted")
        self.used, self.wanted, self.limit = used, wanted, limit


class StoreCorrupt(StoreUnavailable):
    """The SQLite file is not a readable database (at start-up: moved aside or refused)."""


@dataclass(frozen=True)
class SessionState:
    """What the Model keeps of one session (JSON-able; units as in the API)."""

    id: str
    version: int
    camera: dict[str, Any]
    home_camera: dict[str, Any]
    settings: SettingValues
    scene_info: dict[str, Any]
    scene_rev: str
    created_at: float = field(default_factory=time.time)
    # the canvas's width / height the session's camera is framed for (None: the recipe's own camera)
    aspect: float | None = None
    accessed_at: float = field(default_factory=time.time)

    def to_json(self) -> str:
        return json.dumps(asdict(self), separators=(",", ":"))

    @staticmethod
    def from_json(text: str | bytes) -> SessionState:
        try:
            return SessionState(**json.loads(text))
        except (ValueError, TypeError) as e:  # a record someone else wrote, or a torn one
            raise StoreUnavailable(f"holding a session record that does not decode ({type(e).__name__})") from None


Mutation = Callable[[SessionState], SessionState]


class SessionStore(Protocol):
    """What the service needs of a state backend."""

    def create(self, state: SessionState, source: bytes) -> None:
        """Store a new session (``state.version`` as given)."""

    def get(self, session_id: str) -> SessionState | None:
        """The session, or None when unknown or expired. Refreshes the idle clock."""

    def get_source(self, session_id: str) -> tuple[str, bytes] | None:
        """(scene_rev, scene source bytes), or None when unknown or expired."""

    def update(self, session_id: str, mutate: Mutation, source: bytes | None = None) -> SessionState | None:
        """Atomically apply ``mutate``, bump the version, optionally replace the scene source.

        Returns the new state, or None when the session is unknown or expired.
        An exception from ``mutate`` propagates and nothing is written.
        """

    def delete(self, session_id: str) -> bool:
        """Remove the session; True when it existed."""

    def room(self, session_id: str) -> int | None:
        """The most bytes ``session_id``'s scene source could have now within the quota (what the
        others use subtracted, expired sessions' given back); None without a quota."""

    def ping(self) -> bool:
        """True when the backend answers."""

    def probe(self) -> str | None:
        """None when a read and a write of a probe record succeed as a request's would; else why not."""

    def close(self) -> None:
        """Release connections."""


def _bumped(old: SessionState, new: SessionState, now: float) -> SessionState:
    return replace(new, id=old.id, version=old.version + 1, created_at=old.created_at, accessed_at=now)


# ---- SQLite -------------------------------------------------------------------------
_SCHEMA = """
CREATE TABLE IF NOT EXISTS sessions (
    id          TEXT PRIMARY KEY,
    state       TEXT NOT NULL,
    accessed_at REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS scenes (
    id     TEXT PRIMARY KEY,
    rev    TEXT NOT NULL,
    source BLOB NOT NULL
);
CREATE INDEX IF NOT EXISTS sessions_accessed ON sessions(accessed_at);
CREATE TABLE IF NOT EXISTS probe (
    k TEXT PRIMARY KEY,
    v REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS usage (
    k     TEXT PRIMARY KEY,
    bytes INTEGER NOT NULL
);
CREATE TRIGGER IF NOT EXISTS scenes_bytes_insert AFTER INSERT ON scenes BEGIN
    UPDATE usage SET bytes = bytes + length(NEW.source) WHERE k = 'scenes';
END;
CREATE TRIGGER IF NOT EXISTS scenes_bytes_update AFTER UPDATE OF source ON scenes BEGIN
    UPDATE usage SET bytes = bytes - length(OLD.source) + length(NEW.source) WHERE k = 'scenes';
END;
CREATE TRIGGER IF NOT EXISTS scenes_bytes_delete AFTER DELETE ON scenes BEGIN
    UPDATE usage SET bytes = bytes - length(OLD.source) WHERE k = 'scenes';
END;
"""
# The triggers count every write of the scenes table, whatever statement makes it; scenes are
# written with an upsert (an UPDATE) rather than INSERT OR REPLACE, whose implicit delete fires
# no trigger unless recursive triggers are on. The counter is recounted at every open, so a file
# written by a version without it (or edited by hand) starts right.
_UPSERT_SCENE = (
    "INSERT INTO scenes (id, rev, source) VALUES (?, ?, ?) "
    "ON CONFLICT(id) DO UPDATE SET rev = excluded.rev, source = excluded.source"
)
SQLITE_HEADER = b"SQLite format 3\x00"


class StoreStartupError(RuntimeError):
    """The store cannot be opened at start-up (the message says what to do)."""


class SQLiteStore:
    """Sessions in one SQLite file (WAL, ``synchronous=FULL``: a committed change
    survives a crash of the process or the machine).

    ``on_corrupt`` — what to do when the file at start-up is not a readable database:
    ``"refuse"`` (raise :class:`StoreStartupError`) or ``"move_aside"`` (rename it, with its
    ``-wal``/``-shm``, to ``<file>.corrupt-<unix time>`` and start with an empty store).
    ``max_bytes``: the quota of all scene sources, bytes (0: none).
    """

    def __init__(
        self,
        path: Path | str,
        ttl_s: float,
        touch_interval_s: float | None = None,
        on_corrupt: str = "refuse",
        max_bytes: int = 0,
    ):
        self.path = Path(path)
        self.max_bytes = int(max_bytes)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.ttl_s = float(ttl_s)
        self.touch_interval_s = min(60.0, self.ttl_s / 10.0) if touch_interval_s is None else touch_interval_s
        self._lock = threading.Lock()
        self._lost: str | None = None  # why the file is no longer the one opened
        self._reported = False
        if not self.path.exists():
            log.info("session store %s does not exist: starting with an empty one", self.path)
        try:
            self._db = self._open()
        except StoreCorrupt as e:
            if on_corrupt != "move_aside":
                raise StoreStartupError(
                    f"the session store {self.path} is not a readable SQLite database ({e}). Move it aside "
                    f"(mv {self.path} {self.path}.corrupt) to start with an empty store, or set "
                    "POCKETRAY_SQLITE_ON_CORRUPT=move_aside to have that done at start-up"
                ) from None
            aside = self.path.with_name(f"{self.path.name}.corrupt-{int(time.time())}")
            for suffix in ("", "-wal", "-shm"):
                part = Path(str(self.path) + suffix)
                if part.exists():
                    part.rename(Path(str(aside) + suffix))
            log.error(
                "the session store %s was not a readable SQLite database (%s): moved it to %s and started "
                "with an empty store (POCKETRAY_SQLITE_ON_CORRUPT=move_aside)",
                self.path,
                e,
                aside,
            )
            self._db = self._open()
        self._identity = self._file_identity()
        self._fd = os.open(self.path, os.O_RDONLY)  # to read the header of the file opened

    def _open(self) -> sqlite3.Connection:
        db = sqlite3.connect(str(self.path), isolation_level=None, check_same_thread=False, timeout=10.0)
        try:
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=FULL")
            db.execute("PRAGMA busy_timeout=10000")
            db.executescript(_SCHEMA)
            check = db.execute("PRAGMA quick_check").fetchone()[0]
            if check != "ok":
                raise sqlite3.DatabaseError(f"quick_check: {check}")
            db.execute("BEGIN IMMEDIATE")
            db.execute(
                "INSERT OR REPLACE INTO usage (k, bytes) "
                "VALUES ('scenes', (SELECT COALESCE(SUM(length(source)), 0) FROM scenes))"
            )
            db.execute("COMMIT")
        except sqlite3.DatabaseError as e:
            db.close()
            raise StoreCorrupt(str(e)) from None
        return db

    def _file_identity(self) -> tuple[int, int] | None:
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            return None
        return st.st_dev, st.st_ino

    def _check_file(self) -> None:
        """The file must still be the one opened, and still a database: SQLite acknowledges writes
        to a deleted or replaced file, and (WAL, pages in its cache) to one overwritten with junk —
        all gone at the next start. A stat and a 16-byte read, a few microseconds."""
        if self._lost is None and self._file_identity() != self._identity:
            self._lost = "deleted" if self._file_identity() is None else "replaced"
        if self._lost is None and os.pread(self._fd, len(SQLITE_HEADER), 0) != SQLITE_HEADER:
            self._lost = "overwritten (it is no SQLite database any more)"
        if self._lost is not None and not self._reported:
            self._reported = True
            log.error(
                "session store %s was %s while the service ran: every request now answers 503; restart "
                "the service (it opens the file found then; docs/API.md, 'Store faults')",
                self.path,
                self._lost,
            )
        if self._lost is not None:
            raise StoreUnavailable(
                f"unavailable: its file was {self._lost} while the service ran; the operator must restart the service"
            )

    # One connection, one lock: each method is one short transaction.
    def _tx(self, fn: Callable[[sqlite3.Connection], Any]) -> Any:
        with self._lock:
            self._check_file()
            self._db.execute("BEGIN IMMEDIATE")
            try:
                out = fn(self._db)
            except BaseException:
                try:
                    self._db.execute("ROLLBACK")
                except sqlite3.Error:
                    pass  # the transaction is gone with the error that ended it
                raise
            self._db.execute("COMMIT")
            return out

    def _live_row(self, db: sqlite3.Connection, session_id: str, now: float) -> SessionState | None:
        row = db.execute("SELECT state, accessed_at FROM sessions WHERE id = ?", (session_id,)).fetchone()
        if row is None:
            return None
        if row[1] < now - self.ttl_s:
            db.execute("DELETE FROM sessions WHERE id = ?", (session_id,))
            db.execute("DELETE FROM scenes WHERE id = ?", (session_id,))
            return None
        return replace(SessionState.from_json(row[0]), accessed_at=row[1])

    @staticmethod
    def _used(db: sqlite3.Connection) -> int:
        return db.execute("SELECT bytes FROM usage WHERE k = 'scenes'").fetchone()[0]

    def _check_quota(self, db: sqlite3.Connection, session_id: str, source: bytes, now: float) -> None:
        """StoreFull when writing ``source`` as ``session_id``'s scene grows the total over the quota
        (expired sessions purged first). A scene that does not grow is never refused."""
        if not self.max_bytes:
            return
        row = db.execute("SELECT length(source) FROM scenes WHERE id = ?", (session_id,)).fetchone()
        old = row[0] if row else 0
        if len(source) <= old:
            return
        if self._used(db) - old + len(source) > self.max_bytes:
            self._purge(db, now)
            used = self._used(db)
            if used - old + len(source) > self.max_bytes:
                raise StoreFull(used, len(source) - old, self.max_bytes)

    def create(self, state: SessionState, source: bytes) -> None:
        now = time.time()
        state = replace(state, accessed_at=now)

        def tx(db: sqlite3.Connection) -> None:
            self._purge(db, now)
            self._check_quota(db, state.id, source, now)
            db.execute(
                "INSERT INTO sessions (id, state, accessed_at) VALUES (?, ?, ?)", (state.id, state.to_json(), now)
            )
            db.execute(_UPSERT_SCENE, (state.id, state.scene_rev, source))

        self._tx(tx)

    def get(self, session_id: str) -> SessionState | None:
        now = time.time()

        def tx(db: sqlite3.Connection) -> SessionState | None:
            st = self._live_row(db, session_id, now)
            if st is not None and now - st.accessed_at >= self.touch_interval_s:
                db.execute("UPDATE sessions SET accessed_at = ? WHERE id = ?", (now, session_id))
                st = replace(st, accessed_at=now)
            return st

        return self._tx(tx)

    def get_source(self, session_id: str) -> tuple[str, bytes] | None:
        now = time.time()

        def tx(db: sqlite3.Connection) -> tuple[str, bytes] | None:
            if self._live_row(db, session_id, now) is None:
                return None
            row = db.execute("SELECT rev, source FROM scenes WHERE id = ?", (session_id,)).fetchone()
            return None if row is None else (row[0], bytes(row[1]))

        return self._tx(tx)

    def update(self, session_id: str, mutate: Mutation, source: bytes | None = None) -> SessionState | None:
        now = time.time()

        def tx(db: sqlite3.Connection) -> SessionState | None:
            old = self._live_row(db, session_id, now)
            if old is None:
                return None
            new = _bumped(old, mutate(old), now)
            if source is not None:
                self._check_quota(db, session_id, source, now)
            db.execute("UPDATE sessions SET state = ?, accessed_at = ? WHERE id = ?", (new.to_json(), now, session_id))
            if source is not None:
                db.execute(_UPSERT_SCENE, (session_id, new.scene_rev, source))
            return new

        return self._tx(tx)

    def delete(self, session_id: str) -> bool:
        def tx(db: sqlite3.Connection) -> bool:
            n = db.execute("DELETE FROM sessions WHERE id = ?", (session_id,)).rowcount
            db.execute("DELETE FROM scenes WHERE id = ?", (session_id,))
            return n > 0

        return self._tx(tx)

    def _purge(self, db: sqlite3.Connection, now: float) -> None:
        cutoff = now - self.ttl_s
        db.execute("DELETE FROM scenes WHERE id IN (SELECT id FROM sessions WHERE accessed_at < ?)", (cutoff,))
        db.execute("DELETE FROM sessions WHERE accessed_at < ?", (cutoff,))

    def ping(self) -> bool:
        return self.probe() is None

    def probe(self) -> str | None:
        """A write and a read of the probe record in one transaction, on a file that is still the one
        opened and still starts as a SQLite database."""
        now = time.time()
        try:
            with open(self.path, "rb") as f:
                if f.read(len(SQLITE_HEADER)) != SQLITE_HEADER:
                    raise StoreCorrupt("not a database: its header was overwritten")

            def tx(db: sqlite3.Connection) -> Any:
                db.execute("INSERT OR REPLACE INTO probe (k, v) VALUES ('ready', ?)", (now,))
                return db.execute("SELECT v FROM probe WHERE k = 'ready'").fetchone()

            if self._tx(tx) != (now,):
                return "sqlite: the probe record read back differs from the one written"
        except FileNotFoundError:
            return "sqlite: the store file was deleted while the service ran; restart the service"
        except StoreUnavailable as e:
            return f"sqlite: {e}"
        except (sqlite3.Error, OSError) as e:  # the log has the message (it may name paths)
            log.error("session store probe failed: %s: %s", type(e).__name__, e)
            return f"sqlite: {type(e).__name__}"
        return None

    def count(self) -> int:
        """Sessions not yet expired (the /metrics gauge)."""
        with self._lock:
            return self._db.execute(
                "SELECT COUNT(*) FROM sessions WHERE accessed_at >= ?", (time.time() - self.ttl_s,)
            ).fetchone()[0]

    def used_bytes(self) -> int:
        """Bytes of the stored scene sources, the quota's count (expired sessions not yet purged too)."""
        with self._lock:
            return self._used(self._db)

    def room(self, session_id: str) -> int | None:
        if not self.max_bytes:
            return None
        now = time.time()

        def tx(db: sqlite3.Connection) -> int:
            self._purge(db, now)
            row = db.execute("SELECT length(source) FROM scenes WHERE id = ?", (session_id,)).fetchone()
            return self.max_bytes - self._used(db) + (row[0] if row else 0)

        return self._tx(tx)

    def close(self) -> None:
        with self._lock:
            self._db.close()
            os.close(self._fd)


# ---- Redis --------------------------------------------------------------------------
# Writes a session's state and scene source and counts the scene's bytes, in one step, or refuses
# when the quota would be passed (then nothing is written). The store's bytes are a counter key,
# each session's size a field of a hash and the deadline of its scene key a member of a sorted
# set: a scene key that expired (Redis says nothing when it does) is found there and its bytes
# given back, at most 256 a call; a deadline that passed while the key lives (a read refreshed
# its TTL) is only moved to the key's real one. Time is the caller's (now_ms): a clock that is off
# only makes a key be looked at early or late, never counted wrong.
#   KEYS: state, scene, bytes counter, sizes hash, deadlines zset
#   ARGV: id, state JSON, rev, source, ttl ms, quota bytes (0: none), now ms, scene key prefix,
#         "1" when the scene key is new (dropped first)
#   → {1, bytes used after} written, or {0, bytes used} refused
_REDIS_PUT = """
local id, ttl, quota, now = ARGV[1], tonumber(ARGV[5]), tonumber(ARGV[6]), tonumber(ARGV[7])
local due = redis.call('ZRANGEBYSCORE', KEYS[5], '-inf', now, 'LIMIT', 0, 256)
for _, other in ipairs(due) do
  local left = redis.call('PTTL', ARGV[8] .. other)
  if left == -2 then
    redis.call('DECRBY', KEYS[3], tonumber(redis.call('HGET', KEYS[4], other) or '0'))
    redis.call('HDEL', KEYS[4], other)
    redis.call('ZREM', KEYS[5], other)
  else
    redis.call('ZADD', KEYS[5], now + (left > 0 and left or ttl), other)
  end
end
local old = tonumber(redis.call('HGET', KEYS[4], id) or '0')
local new = string.len(ARGV[4])
local used = tonumber(redis.call('GET', KEYS[3]) or '0')
if quota > 0 and new > old and used - old + new > quota then
  return {0, used}
end
redis.call('SET', KEYS[1], ARGV[2], 'PX', ttl)
if ARGV[9] == '1' then redis.call('DEL', KEYS[2]) end
redis.call('HSET', KEYS[2], 'rev', ARGV[3], 'source', ARGV[4])
redis.call('PEXPIRE', KEYS[2], ttl)
redis.call('HSET', KEYS[4], id, new)
redis.call('INCRBY', KEYS[3], new - old)
redis.call('ZADD', KEYS[5], now + ttl, id)
return {1, used - old + new}
"""
# Deletes a session and gives its bytes back.  KEYS: state, scene, bytes, sizes, deadlines; ARGV: id
_REDIS_DELETE = """
local n = redis.call('DEL', KEYS[1], KEYS[2])
local size = redis.call('HGET', KEYS[4], ARGV[1])
if size then
  redis.call('DECRBY', KEYS[3], tonumber(size))
  redis.call('HDEL', KEYS[4], ARGV[1])
  redis.call('ZREM', KEYS[5], ARGV[1])
end
return n
"""


class RedisStore:
    """Sessions in Redis, shared by any number of server processes.

    Keys ``<prefix>state:<id>`` (JSON) and ``<prefix>scene:<id>`` (``rev`` + source
    in a hash), both with the idle TTL; changes are optimistic transactions. The quota's
    count: ``<prefix>bytes``, ``<prefix>sizes`` and ``<prefix>deadlines`` (see ``_REDIS_PUT``),
    written only by the scripts, which Redis runs one at a time whichever process sends them.
    Sessions written by a version without the count are not in it (until they expire).
    """

    # Sessions whose scene key this process refreshed lately (bounded; an entry only saves a PEXPIRE).
    SCENE_TOUCHES = 4096

    def __init__(
        self,
        url: str,
        ttl_s: float,
        prefix: str = "pocketray:",
        touch_interval_s: float | None = None,
        max_retries: int = 16,
        max_bytes: int = 0,
        timeout_s: float = 5.0,
    ):
        import redis

        self._redis_module = redis
        self.client = redis.Redis.from_url(url, socket_timeout=timeout_s, socket_connect_timeout=timeout_s)
        self.ttl_ms = max(1, int(round(ttl_s * 1000)))
        self.touch_interval_s = min(60.0, ttl_s / 10.0) if touch_interval_s is None else touch_interval_s
        self.prefix = prefix
        self.max_retries = max_retries
        self.max_bytes = int(max_bytes)
        self._usage_keys = (f"{prefix}bytes", f"{prefix}sizes", f"{prefix}deadlines")
        self._scene_touched: OrderedDict[str, float] = OrderedDict()
        self._touch_lock = threading.Lock()

    def _keys(self, session_id: str) -> tuple[str, str]:
        return f"{self.prefix}state:{session_id}", f"{self.prefix}scene:{session_id}"

    def _put_args(self, state: SessionState, source: bytes, new_scene: bool) -> list[Any]:
        return [
            _REDIS_PUT,
            5,
            *self._keys(state.id),
            *self._usage_keys,
            state.id,
            state.to_json(),
            state.scene_rev,
            source,
            self.ttl_ms,
            self.max_bytes,
            int(time.time() * 1000),
            f"{self.prefix}scene:",
            "1" if new_scene else "0",
        ]

    def _written(self, result: Any, wanted: int) -> None:
        """StoreFull when the put script refused (``{0, used}``)."""
        ok, used = int(result[0]), int(result[1])
        if not ok:
            raise StoreFull(used, wanted, self.max_bytes)

    def create(self, state: SessionState, source: bytes) -> None:
        state = replace(state, accessed_at=time.time())
        self._written(self.client.eval(*self._put_args(state, source, True)), len(source))

    def get(self, session_id: str) -> SessionState | None:
        k_state, k_scene = self._keys(session_id)
        raw = self.client.getex(k_state, px=self.ttl_ms)  # the read refreshes the idle TTL itself
        if raw is None:
            return None
        st = SessionState.from_json(raw)
        now = time.monotonic()
        with self._touch_lock:
            due = now - self._scene_touched.get(session_id, -self.touch_interval_s) >= self.touch_interval_s
            if due:
                self._scene_touched[session_id] = now
                self._scene_touched.move_to_end(session_id)
                while len(self._scene_touched) > self.SCENE_TOUCHES:
                    self._scene_touched.popitem(last=False)
        if due:  # the scene key lives as long as its state: refreshed at most every touch interval
            self.client.pexpire(k_scene, self.ttl_ms)
        return st

    def get_source(self, session_id: str) -> tuple[str, bytes] | None:
        _, k_scene = self._keys(session_id)
        # bytes: the client does not decode responses
        rev, source = cast(list[bytes | None], self.client.hmget(k_scene, ["rev", "source"]))
        if rev is None or source is None:
            return None
        return rev.decode(), bytes(source)

    def update(self, session_id: str, mutate: Mutation, source: bytes | None = None) -> SessionState | None:
        k_state, k_scene = self._keys(session_id)
        with self.client.pipeline(transaction=True) as p:
            for _ in range(self.max_retries + 1):
                try:
                    p.watch(k_state)
                    raw = p.get(k_state)
                    if raw is None:
                        p.unwatch()
                        return None
                    now = time.time()
                    old = SessionState.from_json(raw)
                    new = _bumped(old, mutate(old), now)
                    p.multi()
                    if source is not None:  # state, scene and byte count written (or refused) together
                        p.eval(*self._put_args(new, source, False))
                        result = p.execute()[0]
                        self._written(result, len(source))
                        return new
                    p.set(k_state, new.to_json(), px=self.ttl_ms)
                    p.pexpire(k_scene, self.ttl_ms)
                    p.execute()
                    return new
                except self._redis_module.WatchError:
                    continue  # someone else changed it first: read again and redo
        raise StoreUnavailable(
            f"busy: this session was changed by others {self.max_retries + 1} times while this change was computed"
        )

    def delete(self, session_id: str) -> bool:
        return int(self.client.eval(_REDIS_DELETE, 5, *self._keys(session_id), *self._usage_keys, session_id)) > 0

    def ping(self) -> bool:
        return self.probe() is None

    def probe(self) -> str | None:
        """A write and a read of a probe key (expiring by itself), as requests write and read."""
        key, token = f"{self.prefix}probe:{os.getpid()}", f"{time.time():.6f}"
        try:
            with self.client.pipeline(transaction=False) as p:
                p.set(key, token, px=60_000)
                p.get(key)
                _, got = p.execute()
        except self._redis_module.RedisError as e:  # the log has the message (it names the server)
            log.error("session store probe failed: %s: %s", type(e).__name__, e)
            return f"redis: {type(e).__name__}"
        return None if got is not None and got.decode() == token else "redis: the probe key read back differs"

    def count(self) -> int:
        """Sessions not yet expired (the /metrics gauge; a SCAN, so /metrics caches it)."""
        return sum(1 for _ in self.client.scan_iter(match=f"{self.prefix}state:*", count=1000))

    def used_bytes(self) -> int:
        """Bytes of the stored scene sources, the quota's count (scenes expired since the last write too)."""
        return int(self.client.get(self._usage_keys[0]) or 0)

    def room(self, session_id: str) -> int | None:
        if not self.max_bytes:
            return None
        k_bytes, k_sizes, k_deadlines = self._usage_keys
        members = cast(list[bytes], self.client.zrangebyscore(k_deadlines, "-inf", int(time.time() * 1000)))
        due = [x.decode() for x in members]
        with self.client.pipeline(transaction=False) as p:
            p.get(k_bytes)
            p.hget(k_sizes, session_id)
            for other in due:  # as the put script does: a scene key that is gone gives its bytes back
                p.exists(f"{self.prefix}scene:{other}")
                p.hget(k_sizes, other)
            got = p.execute()
        used, own = int(got[0] or 0), int(got[1] or 0)
        gone = sum(int(size or 0) for alive, size in zip(got[2::2], got[3::2], strict=True) if not alive)
        return self.max_bytes - used + gone + own

    def close(self) -> None:
        self.client.close()


def open_store(config) -> SessionStore:
    """The backend ``config.state_backend`` names (see :class:`server.config.ServerConfig`)."""
    if config.state_backend == "redis":
        return RedisStore(
            config.redis_url,
            config.session_ttl_s,
            config.redis_prefix,
            max_retries=config.redis_max_retries,
            max_bytes=config.max_store_bytes,
            timeout_s=config.redis_timeout_s,
        )
    return SQLiteStore(
        config.sqlite_path, config.session_ttl_s, on_corrupt=config.sqlite_on_corrupt, max_bytes=config.max_store_bytes
    )
