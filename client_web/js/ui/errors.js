// Where a refusal is shown: next to the field it is about when the settings sheet shows that
// field, else as a notice; the test hook's `errors` gets each one, with whether it was inline.

import { explain, explainUpload } from './messages.js';

export class Refusals {
  // panel: ui/panel.js's SettingsPanel; notice(text, kind, ms).
  constructor({ hook, panel, notice }) {
    Object.assign(this, { hook, panel, notice });
  }

  // e: an ApiError (or any error) of `what` ('start', 'frame', 'gesture', …).
  record(e, what) {
    const ex = explain(e);
    const entry = { what, status: ex.status, message: ex.text, field: ex.field };
    this.hook.errors.push(entry);
    entry.inline = this.panel.refused(ex);
    if (!entry.inline) this.notice(ex.text, 'error', 8000);
  }

  // A model file the service refused (413, 422): next to the picker.
  upload(e) {
    const ex = explainUpload(e);
    const entry = { what: 'model', status: ex.status, message: ex.text, field: 'model' };
    this.hook.errors.push(entry);
    entry.inline = this.panel.open && this.panel.mark('model', ex.text);
    if (!entry.inline) this.notice(ex.text, 'error', 8000);
  }
}
