"""A stand-in for a render process behind HAProxy (tests/deploy/test_balancer.py): no GL, no
state, one process to ``kill -9``. ``python fake_render.py PORT MODE LOG``: ``/api/ready`` is
200; any other request is written to LOG (``METHOD PATH BODY``, one a line) and then, by MODE,
answered 200 ``{"served": PORT, "forwarded_for": X-Forwarded-For}`` (``ok``) or left without an answer, its
connection closed (``drop``: a process that died while it worked on the request)."""

from __future__ import annotations

import json
import socket
import sys
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer


def main() -> None:
    port, mode, log_path = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    log = open(log_path, "a", buffering=1)

    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, *args: object) -> None:
            pass

        def answer(self) -> None:
            n = int(self.headers.get("content-length") or 0)
            body = self.rfile.read(n).decode() if n else ""
            if self.path != "/api/ready":
                log.write(f"{self.command} {self.path} {body}\n")
                if mode == "drop":
                    self.close_connection = True
                    self.connection.shutdown(socket.SHUT_RDWR)
                    return
            data = json.dumps({"served": port, "forwarded_for": self.headers.get("x-forwarded-for")}).encode()
            self.send_response(200)
            self.send_header("content-type", "application/json")
            self.send_header("content-length", str(len(data)))
            self.end_headers()
            try:
                self.wfile.write(data)
            except OSError:  # a health check that hung up after the status line
                self.close_connection = True

        do_GET = do_POST = do_PATCH = answer

    class Server(ThreadingHTTPServer):
        daemon_threads = True

        def handle_error(self, request: object, client_address: object) -> None:
            pass  # a health check or HAProxy hanging up: nothing to report

    Server(("127.0.0.1", port), Handler).serve_forever()


if __name__ == "__main__":
    main()
