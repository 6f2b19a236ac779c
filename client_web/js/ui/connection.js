// The connection to the service, as api.js reports it: offline or busy shows the banner (with
// its countdown and "Retry now"); back online hides it and says so. The test hook's `status`
// follows: starting | ready | offline | busy (| failed, set by the app).

// banner (notices.js's Banner), notice(text), hook, state → api.js's onStatus(s).
export function connectionStatus({ banner, notice, hook, state }) {
  return (s) => {
    if (s.state === 'online') {
      if (banner.shown && hook.status === 'offline') notice('Connected to the render service again.');
      banner.hide();
      hook.status = state.render ? 'ready' : 'starting';
      return;
    }
    hook.status = s.state;  // 'offline' | 'busy'
    banner.show(s);
  };
}
