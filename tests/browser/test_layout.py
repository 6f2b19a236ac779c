"""The phone layout: no control can zoom the page, the controls cover little of
the screen and never each other, the sheet leaves half the frame, every button says what
it does, the gestures are hinted once, false-colour modes have a key, settings that do not
apply are hidden. Screenshots of each layout go to test-artifacts/.

Touch is real (CDP Input.dispatchTouchEvent); nothing here measures time.
"""

from __future__ import annotations

import json

import numpy as np
from browser_support import FAST_QUERY, Touch

LAYOUT_QUERY = "scenario=1&n=64&seed=1&radius=1&width=96&height=160&max_recursion_depth=1&preview_scale=1"
# The upright phone's screenshot is the README's figure: a frame worth looking at, still cheap.
FIGURE_QUERY = "scenario=3&n=256&seed=1&radius=1&width=195&height=422&max_recursion_depth=3&preview_scale=1"
MUSEUM_QUERY = "scenario=museum&n=16&motion=rigid&seed=0&width=96&height=128&max_recursion_depth=1&preview_scale=1"

# The union of the controls' boxes (clipped to the screen) over the screen: what the chrome covers.
CHROME_SHARE = """() => {
  const W = innerWidth, H = innerHeight;
  const boxes = ['#toolbar', '#overlay', '#banner'].map((s) => document.querySelector(s))
    .filter((e) => e && e.getClientRects().length)
    .map((e) => e.getBoundingClientRect())
    .map((r) => [Math.max(0, r.left), Math.max(0, r.top), Math.min(W, r.right), Math.min(H, r.bottom)])
    .filter(([l, t, r, b]) => r > l && b > t);
  const xs = [...new Set(boxes.flatMap((b) => [b[0], b[2]]))].sort((a, b) => a - b);
  let area = 0;
  for (let i = 0; i + 1 < xs.length; i++) {
    const spans = boxes.filter((b) => b[0] <= xs[i] && b[2] >= xs[i + 1]).map((b) => [b[1], b[3]])
      .sort((a, b) => a[0] - b[0]);
    let covered = 0, top = -Infinity;
    for (const [t, b] of spans) { if (b > top) { covered += b - Math.max(t, top); top = b; } }
    area += covered * (xs[i + 1] - xs[i]);
  }
  return area / (W * H);
}"""


def box(page, selector: str) -> dict:
    return page.evaluate(
        """(s) => { const r = document.querySelector(s).getBoundingClientRect();
        return {left: r.left, top: r.top, right: r.right, bottom: r.bottom, width: r.width, height: r.height}; }""",
        selector,
    )


def overlaps(a: dict, b: dict) -> bool:
    return a["left"] < b["right"] and b["left"] < a["right"] and a["top"] < b["bottom"] and b["top"] < a["bottom"]


def spread_on(touch: Touch, b: dict, reach: float = 120.0) -> None:
    """Two fingers down 20 px apart inside the box, spread `reach` px each way (a page-zoom gesture)."""
    cx, cy = b["left"] + b["width"] / 2, b["top"] + b["height"] / 2
    touch.path([[(cx - 10 - reach * k / 10, cy), (cx + 10 + reach * k / 10, cy)] for k in range(11)])


def page_zoom(page) -> dict:
    return page.evaluate("() => ({scale: visualViewport.scale, x: scrollX, y: scrollY, top: visualViewport.offsetTop})")


def dismiss_hint(page) -> None:
    page.evaluate(
        "() => { const b = document.querySelector('#hint [data-dismiss]');"
        " if (b && !document.querySelector('#hint').hidden) b.click(); }"
    )


def test_no_control_can_zoom_or_scroll_the_page(open_client):
    # webgl2=0 with the device asked for: a notice (the fallback) is on screen, as is the one-time hint.
    c = open_client("portrait", LAYOUT_QUERY + "&renderer=device&webgl2=0")
    p, touch = c.page, Touch(c.page)
    content = p.get_attribute('meta[name="viewport"]', "content")
    assert "user-scalable=no" in content and "maximum-scale=1" in content, content
    p.wait_for_selector("#notice > p", state="visible")
    targets = ["#notice > p", "#hint", "#toolbar", "#overlay-summary", "#view"]
    for sel in targets:
        assert p.is_visible(sel), sel
        assert p.evaluate("(s) => getComputedStyle(document.querySelector(s)).touchAction", sel) == "none", sel
        spread_on(touch, box(p, sel))
        assert page_zoom(p) == {"scale": 1, "x": 0, "y": 0, "top": 0}, sel
    c.wait_idle()
    dismiss_hint(p)
    b = box(p, "#settings-toggle")
    touch.tap(b["left"] + b["width"] / 2, b["top"] + b["height"] / 2)
    assert p.is_visible("#settings")
    for sel, action in (("#settings header", "none"), ("#settings form", "pan-y"), ("#f-method", "pan-y")):
        assert p.evaluate("(s) => getComputedStyle(document.querySelector(s)).touchAction", sel) == action, sel
        spread_on(touch, box(p, sel), reach=60)
        assert page_zoom(p) == {"scale": 1, "x": 0, "y": 0, "top": 0}, sel
    # The sheet's own list still scrolls under one finger (pan-y): only the page cannot move.
    form = box(p, "#settings form")
    x = form["left"] + 40
    touch.path([[(x, form["bottom"] - 20 - 25 * k)] for k in range(9)])
    p.wait_for_function("() => document.querySelector('#settings form').scrollTop > 0")
    assert page_zoom(p) == {"scale": 1, "x": 0, "y": 0, "top": 0}
    assert c.errors() == []


def test_each_layout_keeps_the_chrome_small_and_apart(open_client, artifacts):
    shares = {}
    for name, kind, query in (
        ("portrait", "portrait", FIGURE_QUERY),
        ("portrait-museum", "portrait", MUSEUM_QUERY),
        ("landscape", "landscape", LAYOUT_QUERY),
        ("desktop", "wide", LAYOUT_QUERY),
    ):
        c = open_client(kind, query)
        p = c.page
        dismiss_hint(p)
        if name == "portrait-museum":
            assert p.is_visible("#play-button")
        p.screenshot(path=str(artifacts / f"layout-{name}.png"))
        shares[name] = p.evaluate(CHROME_SHARE)
        assert shares[name] < 0.08, (name, shares[name])
        toolbar = box(p, "#toolbar")
        assert not overlaps(box(p, "#overlay"), toolbar), name
        p.click("#overlay-summary")  # the details never reach the toolbar either
        assert p.is_visible("#overlay-details")
        assert not overlaps(box(p, "#overlay"), toolbar), name
        assert box(p, "#overlay")["bottom"] <= toolbar["top"], name
        if name == "landscape":
            p.screenshot(path=str(artifacts / "layout-landscape-details.png"))
        p.click("#overlay-summary")
        assert not p.is_visible("#overlay-details")
        # The sheet: half the screen on a phone (the frame shows above it), beside the frame when wide.
        p.click("#settings-toggle")
        sheet, screen = box(p, "#settings"), p.viewport_size
        if kind == "portrait":
            assert sheet["top"] >= screen["height"] / 2 - 1 and sheet["width"] == screen["width"], sheet
        else:
            assert sheet["left"] >= screen["width"] - 381 and sheet["height"] == screen["height"], sheet
        header_bg = p.evaluate("() => getComputedStyle(document.querySelector('#settings header')).backgroundColor")
        assert header_bg.startswith("rgb(") and not header_bg.startswith("rgba("), header_bg  # opaque
        p.screenshot(path=str(artifacts / f"layout-{name}-sheet.png"))
        p.keyboard.press("Escape")
        assert c.errors() == [], name
    (artifacts / "chrome_share.json").write_text(json.dumps(shares, indent=2))


def test_the_overlay_is_one_line_until_tapped(open_client):
    c = open_client("portrait", LAYOUT_QUERY)
    p, touch = c.page, Touch(c.page)
    one_line = """(s) => { const e = document.querySelector(s);
        return e.getBoundingClientRect().height < 1.6 * parseFloat(getComputedStyle(e).lineHeight); }"""
    assert p.is_visible("#overlay-summary") and not p.is_visible("#overlay-details")
    assert p.evaluate(one_line, '#overlay [data-field="summary"]')
    summary = p.text_content('#overlay [data-field="summary"]')
    assert "fps" in summary and summary.endswith(" ms") and "– ms" not in summary, summary
    b = box(p, "#overlay-summary")
    touch.tap(b["left"] + 10, b["top"] + b["height"] / 2)
    p.wait_for_selector("#overlay-details", state="visible")
    assert p.get_attribute("#overlay-summary", "aria-expanded") == "true"
    renderer = '#overlay [data-field="renderer"]'
    assert p.evaluate(one_line, renderer)  # "rendered by" on one line …
    assert p.get_attribute(renderer, "title").startswith("server (")  # … the whole name as its title
    touch.tap(b["left"] + 10, b["top"] + b["height"] / 2)
    p.wait_for_selector("#overlay-details", state="hidden")
    assert c.errors() == []


def test_every_button_says_what_it_does(open_client):
    c = open_client("portrait", MUSEUM_QUERY)
    p = c.page
    buttons = p.evaluate("""() => [...document.querySelectorAll('#toolbar button')].filter((b) => !b.hidden)
      .map((b) => {
        const l = b.querySelector('.label'); const r = l.getBoundingClientRect();
        return {id: b.id, label: l.textContent.trim(),
                shown: r.width > 0 && r.height > 0 && getComputedStyle(l).visibility === 'visible',
                aria: b.getAttribute('aria-label') || '', title: b.title}; })""")
    assert [b["id"] for b in buttons] == [
        "overlay-toggle",
        "play-button",
        "orbit-toggle",
        "reset-button",
        "settings-toggle",
    ]
    for b in buttons:
        assert b["label"] and b["shown"] and b["aria"] and b["title"], b
    assert {b["label"] for b in buttons} == {"Stats", "Play", "Orbit", "Reset", "Settings"}


def test_the_gesture_hint_shows_once(open_client):
    c = open_client("portrait", LAYOUT_QUERY)
    p, touch = c.page, Touch(c.page)
    assert p.is_visible("#hint")
    text = p.text_content("#hint")
    assert all(w in text for w in ("Drag", "pinch", "twist", "double-tap")), text
    touch.gesture([(150, 300)], [(200, 300)])  # the first gesture is enough
    assert not p.is_visible("#hint")
    assert p.evaluate("() => localStorage.getItem('pocketray.hintSeen')") == "1"
    c.wait_idle(min_frames=1)
    p.reload()
    c.wait_idle(min_frames=1)
    assert not p.is_visible("#hint")
    assert c.errors() == []


def legend(page) -> list[tuple[str, str]]:
    return [
        tuple(x)
        for x in page.evaluate("""() => [...document.querySelectorAll('#legend li')].map((li) =>
        [li.textContent.trim(), getComputedStyle(li.querySelector('.swatch')).backgroundColor])""")
    ]


def test_heat_and_recursion_have_a_legend(open_client):
    from renderer.modes import RECURSION_COLORS

    css = [f"rgb({r}, {g}, {b})" for r, g, b in np.floor(255 * RECURSION_COLORS + 0.5).astype(int)]
    c = open_client("portrait", LAYOUT_QUERY + "&mode=recursion")
    p = c.page
    p.wait_for_selector("#legend li")  # the key comes with GET /api/info
    assert p.is_visible("#legend")
    # the colours the shader is assembled with (renderer.modes), as the 8-bit frame shows them
    assert legend(p) == [*((str(level), css[level]) for level in range(1, len(css))), ("miss", css[0])]
    assert legend(p) == [
        ("1", "rgb(255, 0, 0)"),
        ("2", "rgb(0, 255, 0)"),
        ("3", "rgb(0, 0, 255)"),
        ("4", "rgb(255, 255, 0)"),
        ("5", "rgb(255, 0, 255)"),
        ("6", "rgb(0, 255, 255)"),
        ("7", "rgb(255, 255, 255)"),
        ("8", "rgb(255, 128, 0)"),
        ("miss", "rgb(0, 0, 0)"),
    ]
    assert not overlaps(box(p, "#legend"), box(p, "#toolbar"))
    c = open_client("wide", LAYOUT_QUERY + "&mode=heat")
    p = c.page
    p.wait_for_selector("#legend li")
    assert legend(p) == [
        ("red: 0.05 per sphere test", "rgb(255, 0, 0)"),
        ("green: 0.2 per gap", "rgb(0, 255, 0)"),
        ("blue: 0.2 per node", "rgb(0, 0, 255)"),
    ]
    n0 = c.frame_count
    p.click("#settings-toggle")
    p.select_option("#f-mode", "color")  # the key follows the frame on screen
    c.wait_idle(min_frames=n0 + 1)
    assert not p.is_visible("#legend")
    assert c.errors() == []


def test_settings_that_do_not_apply_are_hidden(open_client):
    c = open_client("wide", FAST_QUERY)
    p = c.page
    p.click("#settings-toggle")
    shown = lambda *names: {n: p.is_visible(f"#f-{n}") for n in names}
    names = ("max_prims", "max_tree_depth", "tile_size", "update", "motion", "radius", "samples_per_pixel")
    assert shown(*names) == {
        "max_prims": True,
        "max_tree_depth": True,
        "tile_size": False,
        "update": False,
        "motion": False,
        "radius": True,
        "samples_per_pixel": True,
    }
    n0 = c.frame_count
    p.select_option("#f-method", "kdtree")  # the SAH decides the leaves
    assert shown("max_prims", "max_tree_depth") == {"max_prims": False, "max_tree_depth": True}
    c.wait_idle(min_frames=n0 + 1)
    n1 = c.frame_count
    p.select_option("#f-method", "bruteforce")  # no tree at all
    assert shown("max_prims", "max_tree_depth", "tile_size") == {
        "max_prims": False,
        "max_tree_depth": False,
        "tile_size": False,
    }
    c.wait_idle(min_frames=n1 + 1)
    # Only hre has tiles (checked before its frame: the form decides at once).
    p.select_option("#f-method", "hre")
    assert shown("tile_size", "max_prims") == {"tile_size": True, "max_prims": False}
    disabled = p.evaluate(
        "() => [...document.querySelectorAll('#f-mode option')].filter((o) => o.disabled).map((o) => o.value)"
    )
    assert disabled == []  # hre draws every mode, cones too
    c.wait_idle()
    p.select_option("#f-method", "bih")
    disabled = p.evaluate(
        "() => [...document.querySelectorAll('#f-mode option')].filter((o) => o.disabled).map((o) => o.value)"
    )
    assert disabled == ["cones"]
    c.wait_idle()
    # The museum: its motion, no radius; the update scheme once a method can follow the motion.
    n2 = c.frame_count
    p.select_option("#f-scenario", "museum")
    c.wait_idle(min_frames=n2 + 1)
    assert shown("motion", "radius", "update") == {"motion": True, "radius": False, "update": False}
    n3 = c.frame_count
    p.select_option("#f-method", "bvh")
    assert shown("update")["update"]
    c.wait_idle(min_frames=n3 + 1)
    assert c.errors() == []
