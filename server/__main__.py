"""``python -m server``: run the service with uvicorn on POCKETRAY_HOST:POCKETRAY_PORT."""

from __future__ import annotations

import logging

import uvicorn

from .config import ServerConfig


def main() -> None:
    config = ServerConfig()
    level = logging.getLevelName(config.log_level.upper())
    logging.basicConfig(level=level if isinstance(level, int) else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
    from .app import create_app
    from .wire import uvicorn_options

    # One process owns one GL context; scale out with more processes and the redis backend.
    uvicorn.run(create_app(config), host=config.host, port=config.port, log_level=config.log_level,
                **uvicorn_options(config))   # 408 for stalled requests, connections per client (server/wire.py)


if __name__ == "__main__":
    main()
