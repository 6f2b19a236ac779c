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
of frame requests does not turn into a stream of writes.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Protocol


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
        return SessionState(**json.loads(text))


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
"""


class SQLiteStore:
    """Sessions in one SQLite file (WAL, ``synchronous=FULL``: a committed change
    survives a crash of the process or the machine)."""

    def __init__(self, path: Path | str, ttl_s: float, touch_interval_s: float | None = None):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.ttl_s = float(ttl_s)
        self.touch_interval_s = min(60.0, self.ttl_s / 10.0) if touch_interval_s is None else touch_interval_s
        self._lock = threading.Lock()
        self._db = sqlite3.connect(str(self.path), isolation_level=None, check_same_thread=False, timeout=10.0)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.execute("PRAGMA busy_timeout=10000")
        self._db.executescript(_SCHEMA)

    # One connection, one lock: each method is one short transaction.
    def _tx(self, fn: Callable[[sqlite3.Connection], Any]) -> Any:
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                out = fn(self._db)
            except BaseException:
                self._db.execute("ROLLBACK")
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
        with self._lock:
            return self._db.execute("SELECT 1").fetchone() == (1,)

    def count(self) -> int:
        """Sessions not yet expired (the /metrics gauge)."""
        with self._lock:
            return self._db.execute("SELECT COUNT(*) FROM sessions WHERE accessed_at >= ?",
                                    (time.time() - self.ttl_s,)).fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._db.close()


# ---- Redis --------------------------------------------------------------------------
class RedisStore:
    """Sessions in Redis, shared by any number of server processes.

    Keys ``<prefix>state:<id>`` (JSON) and ``<prefix>scene:<id>`` (``rev`` + source
    in a hash), both with the idle TTL; changes are optimistic transactions.
    """

    def __init__(self, url: str, ttl_s: float, prefix: str = "pocketray:",
                 touch_interval_s: float | None = None):
        import redis

        self._redis_module = redis
        self.client = redis.Redis.from_url(url, socket_timeout=10.0, socket_connect_timeout=5.0)
        self.ttl_ms = max(1, int(round(ttl_s * 1000)))
        self.touch_interval_s = min(60.0, ttl_s / 10.0) if touch_interval_s is None else touch_interval_s
        self.prefix = prefix

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
        raw = self.client.get(k_state)
        if raw is None:
            return None
        st = SessionState.from_json(raw)
        now = time.time()
        if now - st.accessed_at >= self.touch_interval_s:
            # Refresh the TTLs only; the state's accessed_at is rewritten by the next change.
            with self.client.pipeline(transaction=True) as p:
                p.pexpire(k_state, self.ttl_ms)
                p.pexpire(k_scene, self.ttl_ms)
                p.execute()
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
            while True:
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

    def delete(self, session_id: str) -> bool:
        return self.client.delete(*self._keys(session_id)) > 0

    def ping(self) -> bool:
        try:
            return bool(self.client.ping())
        except Exception:
            return False

    def count(self) -> int:
        """Sessions not yet expired (the /metrics gauge; a SCAN, so /metrics caches it)."""
        return sum(1 for _ in self.client.scan_iter(match=f"{self.prefix}state:*", count=1000))

    def close(self) -> None:
        self.client.close()


def open_store(config) -> SessionStore:
    """The backend ``config.state_backend`` names (see :class:`server.config.ServerConfig`)."""
    if config.state_backend == "redis":
        return RedisStore(config.redis_url, config.session_ttl_s, config.redis_prefix)
    return SQLiteStore(config.sqlite_path, config.session_ttl_s)
