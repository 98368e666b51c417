// The live stream, /api/events, read with fetch (so the token travels in a header) and
// reopened with a growing delay when it drops or the server ends it (`overflow`: this page fell
// behind; `bye`: the server stops). Each event's JSON goes to the handler of its kind. Shared by
// the robot dashboard and the fleet console's page (which loads it from /web-static/).

import { askForToken, authorization } from './api.js';

const RECONNECT_MIN_MS = 500;
const RECONNECT_MAX_MS = 5000;

// handlers: opened(), closed(), and one per kind of event, given its document: the robot
// dashboard's hello, connection and task; the console's hello, robot and result
export async function followEvents(handlers) {
  let delay = RECONNECT_MIN_MS;
  for (;;) {
    try {
      const response = await fetch('/api/events', { headers: authorization() });
      if (response.status === 401) { askForToken(); throw new Error('unauthorized'); }
      if (!response.ok) throw new Error(`HTTP ${response.status}`);
      handlers.opened();
      delay = RECONNECT_MIN_MS;
      await readEvents(response.body.getReader(), handlers);
    } catch (error) {
      console.debug('event stream:', error);
    }
    handlers.closed();
    await new Promise((resolve) => setTimeout(resolve, delay));
    delay = Math.min(delay * 2, RECONNECT_MAX_MS);
  }
}

async function readEvents(reader, handlers) {
  const decoder = new TextDecoder();
  let buffer = '';
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buffer += decoder.decode(value, { stream: true });
    let end;
    while ((end = buffer.indexOf('\n\n')) >= 0) {
      const block = buffer.slice(0, end);
      buffer = buffer.slice(end + 2);
      if (dispatch(block, handlers) === 'again') { reader.cancel(); return; }
    }
  }
}

function dispatch(block, handlers) {
  let kind = 'message';
  let data = '';
  for (const line of block.split('\n')) {
    if (line.startsWith('event: ')) kind = line.slice(7);
    else if (line.startsWith('data: ')) data += line.slice(6);
  }
  if (!data) return '';
  if (kind === 'overflow' || kind === 'bye') return 'again';
  const handler = handlers[kind];
  if (handler) handler(JSON.parse(data));
  return '';
}
