// The key to the false-colour modes (docs/SHADING.md, renderer/modes.py): what the colours
// of the frame on screen mean. Shown for `recursion` (Fig. 4.2f) and `heat` (Fig. 4.3).
// The numbers are the service's (GET /api/info: recursion_colors, heat_scale, from
// renderer/modes.py, which the shader is assembled with); until it answers, no key is shown.

// A colour in [0, 1]³ as CSS, rounded as the frame's 8-bit image is.
export function cssColor(rgb) {
  const c = rgb.map((x) => Math.round(255 * Math.min(Math.max(x, 0), 1)));
  return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
}

// The recursion key (level ≥ 1, then the miss) and the heat key from GET /api/info, or null.
export function keysOf(info) {
  const rec = info && Array.isArray(info.recursion_colors) ? info.recursion_colors : null;
  const heat = info && info.heat_scale && typeof info.heat_scale === 'object' ? info.heat_scale : null;
  return {
    recursion: rec && rec.length > 1 ? rec.map((c, level) => ({ level, css: cssColor(c.rgb), name: c.name })) : null,
    heat: heat ? [
      { css: 'rgb(255, 0, 0)', text: `red: ${heat.tests} per sphere test` },
      { css: 'rgb(0, 255, 0)', text: `green: ${heat.gaps} per gap` },
      { css: 'rgb(0, 0, 255)', text: `blue: ${heat.nodes} per node` },
    ] : null,
  };
}

function item(css, text, title) {
  const li = document.createElement('li');
  const sw = document.createElement('span');
  sw.className = 'swatch';
  sw.style.background = css;
  if (title) li.title = title;
  li.append(sw, document.createTextNode(text));
  return li;
}

export class Legend {
  constructor(root) {
    this.root = root;
    this.mode = null;
    this.keys = keysOf(null);
  }

  // GET /api/info's answer (null: none): the colours the keys show.
  setInfo(info) {
    this.keys = keysOf(info);
    const mode = this.mode;
    this.mode = undefined;
    this.show(mode);
  }

  // The mode of the frame on screen (null: none shown).
  show(mode) {
    if (mode === this.mode) return;
    this.mode = mode;
    const ul = document.createElement('ul');
    const title = document.createElement('span');
    title.className = 'title';
    const { recursion, heat } = this.keys;
    if (mode === 'recursion' && recursion) {
      title.textContent = 'Deepest ray level:';
      for (const k of recursion.slice(1)) ul.append(item(k.css, String(k.level), `level ${k.level}: ${k.name}`));
      ul.append(item(recursion[0].css, 'miss', `${recursion[0].name}: the primary ray hit nothing`));
    } else if (mode === 'heat' && heat) {
      title.textContent = 'Traversal work, added per ray:';
      for (const k of heat) ul.append(item(k.css, k.text));
    } else {
      this.root.hidden = true;
      this.root.replaceChildren();
      return;
    }
    this.root.replaceChildren(title, ul);
    this.root.dataset.mode = mode;
    this.root.hidden = false;
  }
}
