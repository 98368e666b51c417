// What the token's holder may do (GET /api/whoami: {role, name}). The controls beyond its role
// (marked data-needs="operator" or "admin") are hidden by the style sheet; the gateway refuses
// them anyway (403). Unknown (a gateway without roles): every control is shown.

import { api } from './api.js';
import { $ } from './dom.js';

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
