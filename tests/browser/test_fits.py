"""Nothing is cut off on a narrow phone, and the progress of a resting view is in sight: at 360 × 740
CSS px every visible text of the statistics and of the settings sheet fits its box (a select's chosen
option included), and the refinement counter is the topmost element at its centre (never under the
toolbar)."""

from __future__ import annotations

NARROW = dict(viewport={"width": 360, "height": 740}, device_scale_factor=2, is_mobile=True, has_touch=True)
# The Cornell box path-traced, small: its sheet shows the path integrator's fields (denoiser, targets).
QUERY = (
    "scenario=mesh:cornell&width=48&height=96&preview_scale=0.5&integrator=path&samples_per_pixel=1"
    "&max_recursion_depth=3&refine_samples=65536&refine_time_ms=600000"
)

# Visible elements under `root` whose own text (or a select's chosen option) is wider than their box.
CUT_OFF = """(root) => {
  const out = [], ctx = document.createElement('canvas').getContext('2d');
  for (const el of document.querySelector(root).querySelectorAll('*')) {
    if (!el.getClientRects().length || getComputedStyle(el).visibility === 'hidden') continue;
    if (el.tagName === 'SELECT') {
      const cs = getComputedStyle(el), opt = el.options[el.selectedIndex];
      if (!opt) continue;
      ctx.font = `${cs.fontWeight} ${cs.fontSize} ${cs.fontFamily}`;
      // the text's room: the box less its padding and the drop-down arrow (about 1.5 em)
      const pad = parseFloat(cs.paddingLeft) + parseFloat(cs.paddingRight);
      const room = el.clientWidth - pad - 1.5 * parseFloat(cs.fontSize);
      const need = ctx.measureText(opt.textContent).width;
      if (need > room + 0.5) out.push({ what: `select#${el.id}`, text: opt.textContent, need, room });
      continue;
    }
    const own = [...el.childNodes].some((n) => n.nodeType === 3 && n.textContent.trim());
    if (!own) continue;
    if (el.scrollWidth > el.clientWidth + 0.5 && el.clientWidth > 0) {
      const what = el.tagName + (el.id ? '#' + el.id : '');
      out.push({ what, text: el.textContent.trim(), need: el.scrollWidth, room: el.clientWidth });
    }
  }
  return out;
}"""


def open_narrow(browser, server):
    from browser_support import Client

    ctx = browser.new_context(**NARROW)
    return ctx, Client(server, ctx, ctx.new_page())


def test_no_text_is_cut_off_at_360_css_px(browser, server):
    ctx, c = open_narrow(browser, server)
    try:
        c.open(QUERY)
        c.wait_idle(min_frames=1, timeout=60_000)
        c.page.click("#overlay-summary")
        c.page.wait_for_function("() => !document.querySelector('#overlay-details').hidden")
        assert c.page.evaluate(CUT_OFF, "#overlay") == []
        c.page.click("#settings-toggle")
        c.page.wait_for_function("() => !document.querySelector('#settings').hidden")
        assert c.page.evaluate(CUT_OFF, "#settings") == []
        c.page.select_option("#f-integrator", "whitted")
        c.page.wait_for_function("() => window.pocketray.state.render.integrator === 'whitted'")
        assert c.page.evaluate(CUT_OFF, "#settings") == []
    finally:
        ctx.close()


def test_the_sample_counter_is_above_the_toolbar(browser, server):
    ctx, c = open_narrow(browser, server)
    try:
        c.open(QUERY)
        c.page.wait_for_function("() => window.pocketray.refinement.parts.length >= 1", timeout=90_000)
        # The counter lets touches through (pointer-events: none); hit-tested as if it took them, the
        # topmost element at its centre is what is painted there.
        # (set through the CSSOM: the page's Content-Security-Policy refuses an inline style sheet)
        c.page.evaluate(
            "() => document.querySelector('#refine').style.setProperty('pointer-events', 'auto', 'important')"
        )
        top = c.page.evaluate(
            """() => { const r = document.querySelector('#refine').getBoundingClientRect();
            const e = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
            return e && (e.closest('#refine') ? 'refine' : e.id || e.tagName); }"""
        )
        assert top == "refine"
        assert c.page.evaluate(
            """() => { const a = document.querySelector('#refine').getBoundingClientRect();
            const b = document.querySelector('#toolbar').getBoundingClientRect(); return a.bottom <= b.top; }"""
        )
    finally:
        ctx.close()


def test_the_colour_mode_is_named_with_its_integrator(browser, server):
    ctx, c = open_narrow(browser, server)
    try:
        c.open(QUERY)
        c.wait_idle(min_frames=1, timeout=60_000)
        label = "() => document.querySelector('#f-mode option[value=color]').textContent"
        assert c.page.evaluate(label) == "Colour (path traced)"
        c.page.click("#settings-toggle")
        c.page.select_option("#f-integrator", "whitted")
        c.page.wait_for_function("() => window.pocketray.state.render.integrator === 'whitted'")
        assert c.page.evaluate(label) == "Colour (Whitted)"
        assert c.page.text_content("label[for=f-refine_samples]") == "Refine to (samples)"
    finally:
        ctx.close()
