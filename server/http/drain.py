"""Draining: ``/api/ready`` answers 503 from the moment shutdown begins.

uvicorn stops on SIGTERM (and SIGINT) through its own handlers. :func:`install_drain`, run in
the lifespan's start-up (after uvicorn installed them, in the main thread), wraps both: the
signal first sets ``draining`` — from then on ``/api/ready`` answers 503 ``draining`` — and
then hands over to uvicorn, at once for SIGINT (Ctrl-C) and for SIGTERM after
``POCKETRAY_DRAIN_S`` seconds (default 0), during which the process still serves every
request, so a balancer's health check takes it out of rotation before its port closes
(deploy/haproxy.cfg checks every 0.5 s). A second signal hands over at once.
:func:`uninstall` puts uvicorn's handlers back at the lifespan's end.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Callable
from typing import Any

log = logging.getLogger("pocketray.server")

Handler = Callable[[int, Any], Any]


class Drain:
    """The draining flag of one app, and the signal handlers that set it."""

    def __init__(self, drain_s: float = 0.0):
        self.drain_s = float(drain_s)
        self.draining = threading.Event()
        self._previous: dict[int, Any] = {}
        self._timer: threading.Timer | None = None

    def begin(self, reason: str) -> None:
        if not self.draining.is_set():
            log.info("shutdown begins (%s): /api/ready answers 503 from now on", reason)
        self.draining.set()

    def _handler(self, signum: int, frame: Any) -> None:
        previous = self._previous.get(signum)
        again = self.draining.is_set()
        self.begin(signal.Signals(signum).name)

        def hand_over() -> None:
            if callable(previous):
                previous(signum, frame)
            elif previous == signal.SIG_DFL:  # nobody else handles it: the default action
                signal.signal(signum, signal.SIG_DFL)
                signal.raise_signal(signum)

        if signum == signal.SIGTERM and self.drain_s > 0 and not again:
            log.info("draining for %.1f s before stopping", self.drain_s)
            self._timer = threading.Timer(self.drain_s, hand_over)
            self._timer.daemon = True
            self._timer.start()
        else:
            if self._timer is not None:
                self._timer.cancel()
            hand_over()

    def install(self) -> bool:
        """Wrap the SIGTERM and SIGINT handlers (main thread only; False elsewhere, e.g. in a TestClient)."""
        if threading.current_thread() is not threading.main_thread():
            return False
        for sig in (signal.SIGTERM, signal.SIGINT):
            self._previous[sig] = signal.getsignal(sig)
            signal.signal(sig, self._handler)
        return True

    def uninstall(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for sig, previous in self._previous.items():
            if signal.getsignal(sig) == self._handler and previous is not None:
                signal.signal(sig, previous)
        self._previous.clear()
