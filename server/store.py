"""State backends behind one interface: SQLite (embedded, default) and Redis (shared).

A session is two records:

- its *state* (small JSON: version, camera, home camera, render defaults, scene
  info, the scene's revision token) — rewritten by every change;
- its *scene source* (bytes, see :mod:`server.scenes`) — written only when the
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

Faults (issue #17) are reported, never papered over: every failure is a
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
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Protocol


log = logging.getLogger("pocketray.store")


class StoreUnavailable(Exception):
    """The store cannot serve a request (its message says why, without paths; the log has them)."""

    retry_after_s = 1


class StoreCorrupt(StoreUnavailable):
    """The SQLite file is not a readable database (at start-up: moved aside or refused)."""


@dataclass(frozen=True)
class SessionState:
    """What the Model keeps of one session (JSON-able; units as in the API)."""
    id: str
    version: int
    camera: dict[str, Any]
    home_camera: dict[str, Any]
    settings: dict[str, Any]
    scene_info: dict[str, Any]
    scene_rev: str
    created_at: float = field(default_factory=time.time)
    accessed_at: float = field(default_factory=time.time)

    def to_json(self) -> str:
        return json.dumps(asdict(self), separators=(",", ":"))

    @staticmethod
    def from_json(text: str | bytes) -> "SessionState":
        try:
            return SessionState(**json.loads(text))
        except (ValueError, TypeError) as e:      # a record someone else wrote, or a torn one
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
"""
SQLITE_HEADER = b"SQLite format 3\x00"


class StoreStartupError(RuntimeError):
    """The store cannot be opened at start-up (the message says what to do)."""


class SQLiteStore:
    """Sessions in one SQLite file (WAL, ``synchronous=FULL``: a committed change
    survives a crash of the process or the machine).

    ``on_corrupt`` — what to do when the file at start-up is not a readable database:
    ``"refuse"`` (raise :class:`StoreStartupError`) or ``"move_aside"`` (rename it, with its
    ``-wal``/``-shm``, to ``<file>.corrupt-<unix time>`` and start with an empty store).
    """

    def __init__(self, path: Path | str, ttl_s: float, touch_interval_s: float | None = None,
                 on_corrupt: str = "refuse"):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.ttl_s = float(ttl_s)
        self.touch_interval_s = min(60.0, self.ttl_s / 10.0) if touch_interval_s is None else touch_interval_s
        self._lock = threading.Lock()
        self._lost: str | None = None          # why the file is no longer the one opened
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
                    "POCKETRAY_SQLITE_ON_CORRUPT=move_aside to have that done at start-up") from None
            aside = self.path.with_name(f"{self.path.name}.corrupt-{int(time.time())}")
            for suffix in ("", "-wal", "-shm"):
                part = Path(str(self.path) + suffix)
                if part.exists():
                    part.rename(Path(str(aside) + suffix))
            log.error("the session store %s was not a readable SQLite database (%s): moved it to %s and started "
                      "with an empty store (POCKETRAY_SQLITE_ON_CORRUPT=move_aside)", self.path, e, aside)
            self._db = self._open()
        self._identity = self._file_identity()
        self._fd = os.open(self.path, os.O_RDONLY)      # to read the header of the file opened

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
            log.error("session store %s was %s while the service ran: every request now answers 503; restart "
                      "the service (it opens the file found then; docs/API.md, 'Store faults')",
                      self.path, self._lost)
        if self._lost is not None:
            raise StoreUnavailable(f"unavailable: its file was {self._lost} while the service ran; the operator "
                                   "must restart the service")

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
                    pass            # the transaction is gone with the error that ended it
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

    def create(self, state: SessionState, source: bytes) -> None:
        now = time.time()
        state = replace(state, accessed_at=now)

        def tx(db: sqlite3.Connection) -> None:
            self._purge(db, now)
            db.execute("INSERT INTO sessions (id, state, accessed_at) VALUES (?, ?, ?)",
                       (state.id, state.to_json(), now))
            db.execute("INSERT OR REPLACE INTO scenes (id, rev, source) VALUES (?, ?, ?)",
                       (state.id, state.scene_rev, source))
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
            db.execute("UPDATE sessions SET state = ?, accessed_at = ? WHERE id = ?",
                       (new.to_json(), now, session_id))
            if source is not None:
                db.execute("INSERT OR REPLACE INTO scenes (id, rev, source) VALUES (?, ?, ?)",
                           (session_id, new.scene_rev, source))
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
        except (sqlite3.Error, OSError) as e:    # the log has the message (it may name paths)
            log.error("session store probe failed: %s: %s", type(e).__name__, e)
            return f"sqlite: {type(e).__name__}"
        return None

    def count(self) -> int:
        """Sessions not yet expired (the /metrics gauge)."""
        with self._lock:
            return self._db.execute("SELECT COUNT(*) FROM sessions WHERE accessed_at >= ?",
                                    (time.time() - self.ttl_s,)).fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._db.close()
            os.close(self._fd)


# ---- Redis --------------------------------------------------------------------------
class RedisStore:
    """Sessions in Redis, shared by any number of server processes.

    Keys ``<prefix>state:<id>`` (JSON) and ``<prefix>scene:<id>`` (``rev`` + source
    in a hash), both with the idle TTL; changes are optimistic transactions.
    """

    # Sessions whose scene key this process refreshed lately (bounded; an entry only saves a PEXPIRE).
    SCENE_TOUCHES = 4096

    def __init__(self, url: str, ttl_s: float, prefix: str = "pocketray:",
                 touch_interval_s: float | None = None, max_retries: int = 16, timeout_s: float = 5.0):
        import redis

        self._redis_module = redis
        self.client = redis.Redis.from_url(url, socket_timeout=timeout_s, socket_connect_timeout=timeout_s)
        self.ttl_ms = max(1, int(round(ttl_s * 1000)))
        self.touch_interval_s = min(60.0, ttl_s / 10.0) if touch_interval_s is None else touch_interval_s
        self.prefix = prefix
        self.max_retries = max_retries
        self._scene_touched: OrderedDict[str, float] = OrderedDict()
        self._touch_lock = threading.Lock()

    def _keys(self, session_id: str) -> tuple[str, str]:
        return f"{self.prefix}state:{session_id}", f"{self.prefix}scene:{session_id}"

    def create(self, state: SessionState, source: bytes) -> None:
        state = replace(state, accessed_at=time.time())
        k_state, k_scene = self._keys(state.id)
        with self.client.pipeline(transaction=True) as p:
            p.set(k_state, state.to_json(), px=self.ttl_ms)
            p.delete(k_scene)
            p.hset(k_scene, mapping={"rev": state.scene_rev, "source": source})
            p.pexpire(k_scene, self.ttl_ms)
            p.execute()

    def get(self, session_id: str) -> SessionState | None:
        k_state, k_scene = self._keys(session_id)
        raw = self.client.getex(k_state, px=self.ttl_ms)     # the read refreshes the idle TTL itself
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
        if due:      # the scene key lives as long as its state: refreshed at most every touch interval
            self.client.pexpire(k_scene, self.ttl_ms)
        return st

    def get_source(self, session_id: str) -> tuple[str, bytes] | None:
        _, k_scene = self._keys(session_id)
        rev, source = self.client.hmget(k_scene, ["rev", "source"])
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
                    p.set(k_state, new.to_json(), px=self.ttl_ms)
                    if source is not None:
                        p.hset(k_scene, mapping={"rev": new.scene_rev, "source": source})
                    p.pexpire(k_scene, self.ttl_ms)
                    p.execute()
                    return new
                except self._redis_module.WatchError:
                    continue  # someone else changed it first: read again and redo
        raise StoreUnavailable(f"busy: this session was changed by others {self.max_retries + 1} times while "
                               "this change was computed")

    def delete(self, session_id: str) -> bool:
        return self.client.delete(*self._keys(session_id)) > 0

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
        except self._redis_module.RedisError as e:   # the log has the message (it names the server)
            log.error("session store probe failed: %s: %s", type(e).__name__, e)
            return f"redis: {type(e).__name__}"
        return None if got is not None and got.decode() == token else "redis: the probe key read back differs"

    def count(self) -> int:
        """Sessions not yet expired (the /metrics gauge; a SCAN, so /metrics caches it)."""
        return sum(1 for _ in self.client.scan_iter(match=f"{self.prefix}state:*", count=1000))

    def close(self) -> None:
        self.client.close()


def open_store(config) -> SessionStore:
    """The backend ``config.state_backend`` names (see :class:`server.config.ServerConfig`)."""
    if config.state_backend == "redis":
        return RedisStore(config.redis_url, config.session_ttl_s, config.redis_prefix,
                          max_retries=config.redis_max_retries, timeout_s=config.redis_timeout_s)
    return SQLiteStore(config.sqlite_path, config.session_ttl_s, on_corrupt=config.sqlite_on_corrupt)
