// The live stream, /api/events, read with fetch (so the token travels in a header) and
// reopened with a growing delay when it drops.

import { askForToken, authorization } from './api.js';

const RECONNECT_MIN_MS = 500;
const RECONNECT_MAX_MS = 5000;

// handlers: opened(), closed(), connection(connected), task(event)
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
      dispatch(buffer.slice(0, end), handlers);
      buffer = buffer.slice(end + 2);
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
  if (!data) return;
  const payload = JSON.parse(data);
  if (kind === 'hello' || kind === 'connection') handlers.connection(payload.connected);
  else if (kind === 'task') handlers.task(payload);
}
