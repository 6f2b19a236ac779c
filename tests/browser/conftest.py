"""Browser tests of client_web/: the real service in a subprocess, Debian's Chromium.

- ``server``: ``python -m server`` on a free port with a temporary SQLite file; waits
  for ``GET /api/ready`` = 200. ``server.stop()`` / ``server.start()`` restart it on
  the same port and state (sessions survive).
- ``browser``: Playwright driving the system Chromium (never a downloaded one); ``gl_browser``
  a second one of the same Playwright with WebGL2 on SwiftShader (device mode).
- ``open_client``: a page on the client with console errors collected; helpers
  to wait for frames and read the session's camera from the API.

When Chromium or the server cannot start, the tests fail (in CI and everywhere
else): nothing here skips.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from browser_support import ARTIFACTS, CHROMIUM, CHROMIUM_ARGS, FAST_QUERY, GL_ARGS, MOBILE, PROFILES, Client, Server


@pytest.fixture(scope="session")
def server(tmp_path_factory):
    srv = Server(tmp_path_factory.mktemp("pocketray-server"))
    srv.start()
    yield srv
    srv.stop()


@pytest.fixture(scope="session")
def browser():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as e:  # a failure, never a skip
        pytest.fail(f"the Python playwright package is required for the browser tests: {e}")
    pw = sync_playwright().start()
    try:
        b = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
    except Exception as e:
        pw.stop()
        pytest.fail(f"Chromium could not start from {CHROMIUM}: {e}")
    yield b
    b.close()
    pw.stop()


@pytest.fixture(scope="session")
def gl_browser(browser):
    """A second Chromium of the same Playwright (one sync Playwright per process), with the GL flags."""
    try:
        b = browser.browser_type.launch(executable_path=CHROMIUM, args=GL_ARGS, headless=True)
    except Exception as e:
        pytest.fail(f"Chromium could not start from {CHROMIUM} with {GL_ARGS}: {e}")
    yield b
    b.close()


@pytest.fixture(scope="module")
def webgl_page(gl_browser):
    """A blank page on the WebGL2 Chromium: the GLSL tests compile and run their own programs in it."""
    ctx = gl_browser.new_context()
    page = ctx.new_page()
    yield page
    ctx.close()


@pytest.fixture(scope="module")
def device_page(gl_browser, server):
    """A client page (server mode, phone-sized) on a WebGL2 Chromium, whose device renderer renders any
    session by id (window.pocketray.device.renderOnce): the device-mode tests' page."""
    ctx = gl_browser.new_context(**MOBILE)
    c = Client(server, ctx, ctx.new_page())
    c.open("scenario=1&n=64&seed=1&radius=1&width=32&height=32&max_recursion_depth=1")
    probe = c.page.evaluate("() => window.pocketray.device.probe()")
    assert probe["ok"], f"no WebGL2 for the tracer in this Chromium ({GL_ARGS}): {probe}"
    yield c
    ctx.close()


@pytest.fixture
def open_client(browser, server):
    contexts = []

    def make(kind: str = "mobile", query: str | None = FAST_QUERY) -> Client:
        ctx = browser.new_context(**PROFILES[kind])
        contexts.append(ctx)
        c = Client(server, ctx, ctx.new_page())
        if query is not None:
            c.open(query)
        return c

    yield make
    for ctx in contexts:
        ctx.close()


@pytest.fixture(scope="session")
def artifacts() -> Path:
    ARTIFACTS.mkdir(exist_ok=True)
    return ARTIFACTS
