// The key to the false-colour modes (docs/SHADING.md, renderer/modes.py): what the colours
// of the frame on screen mean. Shown for `recursion` (Fig. 4.2f) and `heat` (Fig. 4.3).

// renderer.modes.RECURSION_COLORS, index = level (0: the primary ray missed).
export const RECURSION_KEY = Object.freeze([
  { level: 1, css: 'rgb(255, 0, 0)', name: 'red' }, { level: 2, css: 'rgb(0, 255, 0)', name: 'green' },
  { level: 3, css: 'rgb(0, 0, 255)', name: 'blue' }, { level: 4, css: 'rgb(255, 255, 0)', name: 'yellow' },
  { level: 5, css: 'rgb(255, 0, 255)', name: 'magenta' }, { level: 6, css: 'rgb(0, 255, 255)', name: 'cyan' },
  { level: 7, css: 'rgb(255, 255, 255)', name: 'white' }, { level: 8, css: 'rgb(255, 128, 0)', name: 'orange' },
]);
// renderer.modes.HEAT_SCALE: each channel adds this much per event along the ray, clamped at 1.
export const HEAT_KEY = Object.freeze([
  { css: 'rgb(255, 0, 0)', text: 'red: 0.05 per sphere test' },
  { css: 'rgb(0, 255, 0)', text: 'green: 0.2 per gap' },
  { css: 'rgb(0, 0, 255)', text: 'blue: 0.2 per node' },
]);

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
  }

  // The mode of the frame on screen (null: none shown).
  show(mode) {
    if (mode === this.mode) return;
    this.mode = mode;
    const ul = document.createElement('ul');
    const title = document.createElement('span');
    title.className = 'title';
    if (mode === 'recursion') {
      title.textContent = 'Deepest ray level:';
      for (const k of RECURSION_KEY) ul.append(item(k.css, String(k.level), `level ${k.level}: ${k.name}`));
      ul.append(item('rgb(0, 0, 0)', 'miss', 'black: the primary ray hit nothing'));
    } else if (mode === 'heat') {
      title.textContent = 'Traversal work, added per ray:';
      for (const k of HEAT_KEY) ul.append(item(k.css, k.text));
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
