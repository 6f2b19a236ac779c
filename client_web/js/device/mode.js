// Which tracer draws the frames: the service's, or this browser's (device.js) when the settings
// ask for it. Where the device cannot run the tracer: server mode, with a visible notice.

export class RendererChoice {
  // device (DeviceView); scheduler (frames.js); panel (ui/panel.js); select: the sheet's
  // renderer field; notice(text, kind, ms).
  constructor({ state, hook, device, scheduler, panel, select, notice }) {
    Object.assign(this, { state, hook, device, scheduler, panel, select, notice });
  }

  // redraw: ask for a frame now (not when the failed request asks for its own).
  fallBack(reason, redraw = true) {
    const { state } = this;
    this.device.stop();
    this.hook.deviceFallback = reason;
    state.client = { ...state.client, renderer: 'server' };
    this.notice(`Rendering on the server: this device cannot (${reason}).`, 'warn', 10000);
    this.select.value = 'server';   // also while focused (panel.show leaves focused controls alone)
    this.panel.show(state);
    if (redraw && state.render) this.scheduler.invalidate();
  }

  // which: 'device' | 'server'.
  set(which) {
    if (which === 'device') {
      const p = this.device.probe();
      if (!p.ok) return this.fallBack(p.reason);
    } else {
      this.device.stop();
    }
    if (this.state.render) this.scheduler.invalidate();
  }
}
