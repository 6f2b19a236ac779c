// Notices (short-lived lines) and the connection banner (api.js's onStatus). Both live in
// #messages, above the toolbar and above the open settings sheet (style.css), so that a
// refusal is never drawn under what caused it.

export class Notices {
  constructor(list, onNotice = () => {}) {
    this.list = list;
    this.onNotice = onNotice;
  }

  // kind: 'info' | 'warn' | 'error'. A line already shown with the same words stays, for `ms` more,
  // instead of a second copy (a refusal retried, a setting chosen twice).
  show(text, kind = 'info', ms = 6000) {
    this.onNotice({ text, kind });
    let p = [...this.list.children].find((x) => x.textContent === text && x.className === kind);
    if (!p) {
      p = document.createElement('p');
      p.textContent = text;
      p.className = kind;
      this.list.append(p);
    }
    clearTimeout(p.removal);
    p.removal = setTimeout(() => p.remove(), ms);
    return p;
  }
}

// The banner: offline (retrying with a countdown) or busy (Retry-After); hidden when online.
export class Banner {
  constructor(root, { onRetry }) {
    this.root = root;
    this.msg = root.querySelector('[data-message]');
    this.timer = null;
    root.querySelector('[data-retry]').addEventListener('click', () => onRetry());
  }

  get shown() {
    return !this.root.hidden;
  }

  hide() {
    clearInterval(this.timer);
    this.root.hidden = true;
  }

  // s: {state: 'offline' | 'busy', message, delayMs, attempt}
  show(s) {
    clearInterval(this.timer);
    this.root.hidden = false;
    this.root.classList.toggle('busy', s.state === 'busy');
    const until = performance.now() + s.delayMs;
    const paint = () => {
      const left = Math.max(0, Math.ceil((until - performance.now()) / 1000));
      this.msg.textContent = `${s.message}. Retrying in ${left} s${s.attempt > 1 ? ` (attempt ${s.attempt})` : ''}…`;
    };
    paint();
    this.timer = setInterval(paint, 250);
  }
}
