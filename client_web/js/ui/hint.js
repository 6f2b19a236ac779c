// A one-time hint of what the fingers (or the mouse) do. It goes when dismissed or at the
// first gesture, and stays gone (localStorage), so it never covers the frame twice.

const SEEN_KEY = 'pocketray.hintSeen';

export const HINTS = Object.freeze({
  touch: 'Drag: move · pinch: zoom · twist: orbit · double-tap: reset',
  mouse: 'Drag: move · right- or shift-drag: orbit · scroll: zoom · double-click: reset',
});

export class Hint {
  constructor(root, { touch = matchMedia('(pointer: coarse)').matches } = {}) {
    this.root = root;
    root.querySelector('[data-text]').textContent = touch ? HINTS.touch : HINTS.mouse;
    root.querySelector('[data-dismiss]').addEventListener('click', () => this.dismiss());
    let seen = false;
    try {
      seen = localStorage.getItem(SEEN_KEY) === '1';
    } catch { /* private mode: show it once per page */ }
    root.hidden = seen;
  }

  get shown() {
    return !this.root.hidden;
  }

  dismiss() {
    if (this.root.hidden) return;
    this.root.hidden = true;
    try {
      localStorage.setItem(SEEN_KEY, '1');
    } catch { /* ignore */ }
  }
}
