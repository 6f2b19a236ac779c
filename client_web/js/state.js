// The client's state: one object that the session, the transport, the display and the panel
// read and write (tests see it as window.pocketray.state).

import { DEFAULT_SCENE, FALLBACK_METHODS, loadClientSettings, readUrlParams } from './settings.js';

// search: the page's query string → {url: its parameters (readUrlParams), state}.
export function createState(search, clientSettings = loadClientSettings()) {
  const url = readUrlParams(search);
  const state = {
    sessionId: null,
    session: null,                // the adopted SessionOut (to go back to when a new scene is refused)
    scene: { ...DEFAULT_SCENE },
    render: null,                 // the session's full settings (from the server)
    client: { dragMode: 'pan', ...clientSettings, ...url.client },
    methods: [...FALLBACK_METHODS],
    profiles: null,
    // An animated scene's clock (clock.js): frames are posed at `time`.
    anim: { animated: false, playing: false, time: 0, time0: 0, clock0: 0 },
  };
  return { url, state };
}
