// The gateway's API: the token (taken from the address once, then kept for the session),
// requests with it, their errors, and what the token's holder may do.

import { $, element } from './dom.js';

const TOKEN_KEY = 'task_manager_token';
let token = '';

function takeToken() {
  const url = new URL(window.location.href);
  const fromUrl = url.searchParams.get('token');
  if (fromUrl) {
    sessionStorage.setItem(TOKEN_KEY, fromUrl);
    url.searchParams.delete('token');
    history.replaceState(null, '', url.pathname + url.search + url.hash);
  }
  token = sessionStorage.getItem(TOKEN_KEY) || '';
  return token;
}

export function authorization() {
  return { Authorization: `Bearer ${token}` };
}

export class ApiError extends Error {
  constructor(status, body) {
    super(body?.error?.message || `HTTP ${status}`);
    this.status = status;
    this.code = body?.error?.code || '';
  }
}

export async function api(path, options = {}) {
  const headers = { ...authorization(), ...(options.headers || {}) };
  if (options.json !== undefined) headers['Content-Type'] = 'application/json';
  const response = await fetch(path, {
    method: options.method || 'GET',
    headers,
    body: options.json !== undefined ? JSON.stringify(options.json) : undefined,
  });
  if (response.status === 401) askForToken();
  if (!response.ok) {
    let body = null;
    try { body = await response.json(); } catch { /* not JSON */ }
    throw new ApiError(response.status, body);
  }
  return options.raw ? response : response.json();
}

export function askForToken() {
  $('#token-form').hidden = false;
}

// The token taken from the address, else asked for with the token form (built here, naming
// the program its data-program says prints the token), whose token is kept for the session
// and the page loaded again with it.
export function wireToken() {
  const form = $('#token-form');
  form.replaceChildren(
    element('label', { text: 'Token ' },
      element('input', { id: 'token-input', type: 'password', autocomplete: 'current-password', required: '' })),
    element('button', { type: 'submit', text: 'Use' }),
    element('span', { class: 'hint' }, 'printed by ', element('code', { text: form.dataset.program }),
      ' at start (the ', element('code', { text: '?token=' }), ' of its dashboard line)'));
  if (!takeToken()) askForToken();
  form.addEventListener('submit', (event) => {
    event.preventDefault();
    sessionStorage.setItem(TOKEN_KEY, $('#token-input').value.trim());
    window.location.reload();
  });
}

// The path of an id inside a route (`/api/schedules/{id}`): every character kept as it is.
export function idPath(id) {
  return encodeURIComponent(id);
}

// The token's role (GET /api/whoami: {role, name}) on the page's body: the controls beyond it
// (data-needs="operator" or "admin") are hidden by the style sheet; the gateway refuses them
// anyway (403). Unknown (a gateway without roles): every control is shown.
export async function loadRole() {
  try {
    const who = await api('/api/whoami');
    document.body.dataset.role = who.role;
    $('#who').textContent = who.name ? `${who.name} (${who.role})` : who.role;
    $('#who').hidden = false;
  } catch (error) {
    console.debug('role:', error);
  }
}
