"""Token buckets per client address: how many sessions one address may create.

A bucket holds at most ``burst`` tokens and gains ``per_min`` a minute; a creation takes one,
and with none left the request is refused (429) with the seconds until the next one. The
buckets live in this process (with ``--workers N`` an address gets N buckets), bounded in
number: beyond ``max_clients`` addresses the least recently seen is forgotten (a forgotten
address starts again with a full bucket, which is what a new one gets anyway). IPv6
addresses count by their /64, the block one subscriber usually holds.
"""

from __future__ import annotations

import ipaddress
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable


class RateLimited(Exception):
    """No token left for this client address: retry after ``retry_after_s`` seconds."""

    def __init__(self, retry_after_s: int, per_min: float, burst: int):
        super().__init__(f"retry after {retry_after_s} s")
        self.retry_after_s, self.per_min, self.burst = retry_after_s, per_min, burst


def client_key(host: str | None) -> str:
    """The bucket of an address: IPv4 as it is, IPv6 by its /64, anything else as given."""
    if not host:
        return "unknown"
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        return host[:64]
    if isinstance(addr, ipaddress.IPv6Address):
        if addr.ipv4_mapped is not None:
            return str(addr.ipv4_mapped)
        return str(ipaddress.IPv6Network((addr, 64), strict=False))
    return str(addr)


class TokenBuckets:
    """``take(key)`` takes a token of ``key``'s bucket or raises :class:`RateLimited`. ``per_min`` 0: no limit."""

    def __init__(
        self, per_min: float, burst: int, max_clients: int = 65_536, clock: Callable[[], float] = time.monotonic
    ):
        self.per_min, self.burst, self.max_clients = float(per_min), int(burst), int(max_clients)
        self.rate_s = self.per_min / 60.0
        self.clock = clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # key → (tokens, at)
        self._lock = threading.Lock()

    def take(self, key: str) -> None:
        if self.per_min <= 0:
            return
        with self._lock:
            now = self.clock()
            tokens, at = self._buckets.get(key, (float(self.burst), now))
            tokens = min(float(self.burst), tokens + (now - at) * self.rate_s)
            if tokens < 1.0:
                self._buckets[key] = (tokens, now)
                self._buckets.move_to_end(key)
                raise RateLimited(max(1, math.ceil((1.0 - tokens) / self.rate_s)), self.per_min, self.burst)
            self._buckets[key] = (tokens - 1.0, now)
            self._buckets.move_to_end(key)
            while len(self._buckets) > self.max_clients:
                self._buckets.popitem(last=False)

    def __len__(self) -> int:
        return len(self._buckets)
