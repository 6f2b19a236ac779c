"""The client and the offline docs under their Content-Security-Policy (server/http/security.py): the
page loads its modules, traces in device mode (WebGL2) and on the server, and the browser refuses
nothing — while an inline script, which the policy is there to stop, is refused."""

from __future__ import annotations

from browser_support import MOBILE, Client

# ReDoc shows Redocly's logo from its CDN, and hides it when it does not load: the offline docs
# refuse it (img-src 'self'), which is the one violation expected.
REDOC_LOGO = "https://cdn.redoc.ly/"
SMALL = "scenario=1&n=64&seed=1&radius=1&width=96&height=160&max_recursion_depth=2&preview_scale=1&refine_ms=0"

# Every violation the page reports, whatever the console says about it.
RECORD_VIOLATIONS = """
window.__csp = [];
document.addEventListener('securitypolicyviolation',
    e => window.__csp.push(`${e.effectiveDirective} ${e.blockedURI}`));
"""


def test_the_client_traces_under_its_policy(gl_browser, server):
    ctx = gl_browser.new_context(**MOBILE)
    try:
        page = ctx.new_page()
        page.add_init_script(RECORD_VIOLATIONS)
        c = Client(server, ctx, page)
        response = page.goto(f"{server.base}/?{SMALL}&renderer=device&mode=color")
        policy = response.headers["content-security-policy"]
        assert "frame-ancestors 'none'" in policy and "script-src 'self';" in policy
        assert response.headers["x-content-type-options"] == "nosniff"
        c.wait_idle(min_frames=1)
        assert c.hook("lastFrame.renderer") == "device", c.hook("lastFrame")  # WebGL2, the shader fetched

        n = c.frame_count  # and the server's frames (fetch, images) too
        c.page.click("#settings-toggle")
        c.page.select_option("#f-renderer", "server")
        c.wait_idle(min_frames=n + 1)
        assert c.hook("lastFrame.renderer") == "server"

        assert page.evaluate("() => window.__csp") == []
        assert c.errors() == [] and c.hook("errors") == []

        ran = page.evaluate("""() => { const s = document.createElement('script');
            s.textContent = 'window.__inline = true'; document.body.appendChild(s);
            return window.__inline === true; }""")
        assert not ran
        page.wait_for_function("() => window.__csp.length > 0")
        assert page.evaluate("() => window.__csp") == ["script-src-elem inline"]
    finally:
        ctx.close()


def test_the_docs_work_under_their_policy(browser, server):
    ctx = browser.new_context()
    try:
        page = ctx.new_page()
        page.add_init_script(RECORD_VIOLATIONS)
        errors: list[str] = []
        page.on("console", lambda m: m.type == "error" and errors.append(m.text))
        page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))

        response = page.goto(f"{server.base}/docs")
        assert "'sha256-" in response.headers["content-security-policy"]
        page.wait_for_selector(".opblock", timeout=30_000)  # Swagger UI ran and read /openapi.json
        assert page.locator(".opblock").count() > 10

        page.goto(f"{server.base}/redoc")
        page.wait_for_selector("[data-section-id]", timeout=30_000)  # ReDoc rendered the operations
        page.wait_for_timeout(500)  # its search worker starts after the first render
        assert [v for v in page.evaluate("() => window.__csp") if REDOC_LOGO not in v] == []
        assert [e for e in errors if REDOC_LOGO not in e] == []
    finally:
        ctx.close()
