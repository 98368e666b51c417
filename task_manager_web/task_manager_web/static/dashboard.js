// The Task Manager dashboard: plain JavaScript, no build step, nothing from outside the gateway.
// Live state comes from /api/events (read with fetch, so the token travels in a header);
// on every (re)connection the active tasks and the history are read again.
'use strict';

const ENDED_VISIBLE_MS = 4000;       // an ended task stays in the active table this long
const RECONNECT_MIN_MS = 500;
const RECONNECT_MAX_MS = 5000;
const MISSIONS_KEPT = 5;
const HISTORY_ROWS = 100;
// Other tasks' queue positions move without an event of theirs: the active list is read again
// this long after an event that may have moved them (one read for a burst of events).
const QUEUE_REREAD_MS = 150;

const state = {
  token: '',
  tasks: new Map(),      // task id -> Task document (active, or ended moments ago)
  missions: new Map(),   // mission id -> Task document of the mission
  declared: [],
  nodeConnected: false,
  streamOpen: false,
  queueReread: null,     // the pending timer of rereadQueue, or null
  priorityTaskId: '',    // the task whose priority the dialog changes
};

const $ = (selector) => document.querySelector(selector);

function element(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) {
    if (name === 'class') node.className = value;
    else if (name === 'text') node.textContent = value;
    else if (name.startsWith('on')) node.addEventListener(name.slice(2), value);
    else node.setAttribute(name, value);
  }
  for (const child of children) node.append(child);
  return node;
}

// ---- token and requests --------------------------------------------------------------------

function takeToken() {
  const url = new URL(window.location.href);
  const fromUrl = url.searchParams.get('token');
  if (fromUrl) {
    sessionStorage.setItem('task_manager_token', fromUrl);
    url.searchParams.delete('token');
    history.replaceState(null, '', url.pathname + url.search + url.hash);
  }
  state.token = sessionStorage.getItem('task_manager_token') || '';
}

class ApiError extends Error {
  constructor(status, body) {
    super(body?.error?.message || `HTTP ${status}`);
    this.status = status;
    this.code = body?.error?.code || '';
  }
}

async function api(path, options = {}) {
  const headers = { Authorization: `Bearer ${state.token}`, ...(options.headers || {}) };
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

function askForToken() {
  $('#token-form').hidden = false;
}

function say(text, isError = false) {
  const message = $('#message');
  message.textContent = text;
  message.classList.toggle('error', isError);
}

// ---- the live stream -----------------------------------------------------------------------

async function followEvents() {
  let delay = RECONNECT_MIN_MS;
  for (;;) {
    try {
      const response = await fetch('/api/events', { headers: { Authorization: `Bearer ${state.token}` } });
      if (response.status === 401) { askForToken(); throw new Error('unauthorized'); }
      if (!response.ok) throw new Error(`HTTP ${response.status}`);
      state.streamOpen = true;
      delay = RECONNECT_MIN_MS;
      await readEvents(response.body.getReader());
    } catch (error) {
      console.debug('event stream:', error);
    }
    state.streamOpen = false;
    showConnection();
    await new Promise((resolve) => setTimeout(resolve, delay));
    delay = Math.min(delay * 2, RECONNECT_MAX_MS);
  }
}

async function readEvents(reader) {
  const decoder = new TextDecoder();
  let buffer = '';
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buffer += decoder.decode(value, { stream: true });
    let end;
    while ((end = buffer.indexOf('\n\n')) >= 0) {
      dispatch(buffer.slice(0, end));
      buffer = buffer.slice(end + 2);
    }
  }
}

function dispatch(block) {
  let kind = 'message';
  let data = '';
  for (const line of block.split('\n')) {
    if (line.startsWith('event: ')) kind = line.slice(7);
    else if (line.startsWith('data: ')) data += line.slice(6);
  }
  if (!data) return;
  const payload = JSON.parse(data);
  if (kind === 'hello' || kind === 'connection') onConnection(payload.connected);
  else if (kind === 'task') onTaskEvent(payload);
}

function onConnection(connected) {
  state.nodeConnected = connected;
  showConnection();
  if (connected) refreshAll();
}

function showConnection() {
  const badge = $('#connection');
  const banner = $('#banner');
  const live = state.streamOpen && state.nodeConnected;
  document.body.classList.toggle('stale', !live);
  badge.className = `badge ${live ? 'connected' : 'unreachable'}`;
  if (!state.streamOpen) {
    badge.textContent = 'gateway not reachable';
    banner.textContent = 'The web gateway is not reachable: retrying. Tasks shown are stale.';
  } else if (!state.nodeConnected) {
    badge.textContent = 'Task Manager not reachable';
    banner.textContent = 'Task Manager not reachable: the tasks shown are stale, not running.';
  } else {
    badge.textContent = 'connected';
  }
  banner.hidden = live;
  renderActive();
}

function onTaskEvent(event) {
  const task = event.task;
  if (task.task_name === 'system/mission') rememberMission(task);
  if (event.event === 'ENDED') {
    state.tasks.set(task.task_id, { ...task, endedAt: Date.now() });
    setTimeout(() => { dropEnded(task.task_id); }, ENDED_VISIBLE_MS);
    addHistoryRow(task, true);
  } else {
    // a paused task's clock stops at its PAUSED event
    const pausedAt = event.event === 'PAUSED' ? Date.parse(event.stamp) : state.tasks.get(task.task_id)?.pausedAt;
    state.tasks.set(task.task_id, task.status === 'PAUSED' ? { ...task, pausedAt } : task);
  }
  if (event.event !== 'FEEDBACK' && [...state.tasks.values()].some((each) => each.status === 'QUEUED')) {
    rereadQueueSoon();
  }
  renderActive();
}

function rereadQueueSoon() {
  if (state.queueReread !== null) return;
  state.queueReread = setTimeout(rereadQueue, QUEUE_REREAD_MS);
}

// Takes the queue positions and priorities of the tasks still queued from a fresh active list;
// anything else an event may have changed since the list was read is left as the events say.
async function rereadQueue() {
  state.queueReread = null;
  try {
    for (const fresh of await api('/api/active')) {
      const shown = state.tasks.get(fresh.task_id);
      if (shown?.status === 'QUEUED' && fresh.status === 'QUEUED') {
        state.tasks.set(fresh.task_id, { ...shown, queue_position: fresh.queue_position, priority: fresh.priority });
      }
    }
    renderActive();
  } catch (error) {
    console.debug('queue positions:', error);
  }
}

function dropEnded(taskId) {
  const task = state.tasks.get(taskId);
  if (task && task.endedAt) {
    state.tasks.delete(taskId);
    renderActive();
  }
}

async function refreshAll() {
  try {
    const active = await api('/api/active');
    const fresh = new Map(active.map((task) => [task.task_id, task]));
    for (const [id, task] of state.tasks) if (task.endedAt) fresh.set(id, task);
    state.tasks = fresh;
    for (const task of active) if (task.task_name === 'system/mission') rememberMission(task);
    renderActive();
    if (!state.declared.length) await loadDeclared();
    await loadHistory();
  } catch (error) {
    say(`Could not read the state: ${error.message}`, true);
  }
}

// ---- active tasks and missions -------------------------------------------------------------

// Running time: time paused (paused_sec) does not count. A queued task: its time waiting.
function elapsed(task) {
  if (task.duration_sec != null) return formatSeconds(task.duration_sec);
  if (task.status === 'QUEUED' && task.received) {
    return `waiting ${formatSeconds(Math.max(0, (Date.now() - Date.parse(task.received)) / 1000))}`;
  }
  if (!task.started) return '';
  if (task.status === 'PAUSED' && !task.pausedAt) return 'paused';
  const end = task.status === 'PAUSED' ? task.pausedAt : (task.ended ? Date.parse(task.ended) : Date.now());
  return formatSeconds(Math.max(0, (end - Date.parse(task.started)) / 1000 - (task.paused_sec || 0)));
}

function formatSeconds(seconds) {
  if (seconds < 60) return `${seconds.toFixed(1)} s`;
  const minutes = Math.floor(seconds / 60);
  if (minutes < 60) return `${minutes} min ${Math.floor(seconds % 60)} s`;
  return `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
}

function feedbackText(task) {
  const feedback = task.feedback;
  if (!feedback) return '';
  if (task.task_name === 'system/mission' && Array.isArray(feedback.subtasks)) {
    const index = feedback.current_index;
    const current = feedback.subtasks[index];
    return current ? `step ${index + 1} of ${feedback.subtasks.length}: ${current.task_name}` : '';
  }
  return compactJson(feedback);
}

// JSON with numbers to 3 decimals, cut at `limit` characters (the whole text is the title).
function compactJson(value, limit = 160) {
  const text = JSON.stringify(value, (_, each) => (typeof each === 'number' && !Number.isInteger(each) ? Number(each.toFixed(3)) : each));
  return text.length > limit ? `${text.slice(0, limit - 1)}…` : text;
}

function statusBadge(status) {
  return element('span', { class: `badge status-${status}`, text: status });
}

// The latest decision about a task ("queued behind drive-1 (priority 5), which holds base").
function latestReason(task) {
  const decisions = Array.isArray(task.decisions) ? task.decisions : [];
  return decisions.length ? String(decisions.at(-1).reason || '') : '';
}

function decisionTrail(task) {
  const decisions = Array.isArray(task.decisions) ? task.decisions : [];
  return decisions.map((each) => `${each.decision}: ${each.reason}`).join('\n');
}

// Running and paused tasks first, as they came; then the queue, in its order.
function activeOrder(tasks) {
  const queued = tasks.filter((task) => task.status === 'QUEUED' && !task.endedAt);
  queued.sort((a, b) => (a.queue_position || Infinity) - (b.queue_position || Infinity));
  return [...tasks.filter((task) => !queued.includes(task)), ...queued];
}

function statusCell(task, shown) {
  const cell = element('td', { class: 'status' }, statusBadge(shown));
  if (task.status === 'QUEUED' && !task.endedAt && task.queue_position) {
    cell.append(' ', element('span', {
      class: 'queue-position', text: `#${task.queue_position}`, title: `position ${task.queue_position} in the queue`,
    }));
  }
  if (task.attempt > 1) cell.append(' ', element('span', { class: 'attempt', text: `attempt ${task.attempt}` }));
  return cell;
}

function priorityCell(task) {
  const cell = element('td', { class: 'priority' }, element('span', { class: 'priority-value', text: String(task.priority ?? 0) }));
  if (!task.endedAt) {
    cell.append(' ', element('button', {
      class: 'reprioritize', type: 'button', text: 'change', title: `change the priority of ${task.task_id}`,
      onclick: () => askPriority(task),
    }));
  }
  return cell;
}

function renderActive() {
  const body = $('#active tbody');
  const live = state.streamOpen && state.nodeConnected;
  const rows = activeOrder([...state.tasks.values()]).map((task) => {
    const shown = live || task.endedAt ? task.status : 'STALE';
    const cancel = task.endedAt ? '' : element('button', {
      class: 'cancel', type: 'button', text: 'Cancel', onclick: () => cancelTask(task.task_id),
    });
    const queued = task.status === 'QUEUED' && !task.endedAt;
    const classes = [task.endedAt ? 'ended' : '', queued ? 'queued' : ''].filter(Boolean).join(' ');
    const feedback = feedbackText(task);
    return element('tr', { class: classes, 'data-task-id': task.task_id, 'data-status': task.status },
      element('td', { text: task.task_name }),
      element('td', { class: 'id', text: task.task_id, title: task.task_id }),
      element('td', { text: task.source }),
      statusCell(task, shown),
      priorityCell(task),
      element('td', { class: 'elapsed', text: elapsed(task) }),
      element('td', {
        class: feedback ? 'feedback' : 'feedback reason', text: feedback || latestReason(task), title: decisionTrail(task),
      }),
      element('td', {}, cancel));
  });
  body.replaceChildren(...rows);
  $('#active-empty').hidden = rows.length > 0;
}

function rememberMission(task) {
  state.missions.set(task.task_id, task);
  const ids = [...state.missions.keys()];
  for (const id of ids.slice(0, Math.max(0, ids.length - MISSIONS_KEPT))) state.missions.delete(id);
  renderMissions();
}

function stepClass(subtask) {
  if (subtask.skipped) return 'skipped';
  return {
    DONE: 'done', IN_PROGRESS: 'running', PAUSED: 'paused', ERROR: 'failed', CANCELED: 'canceled',
  }[subtask.task_status] || 'pending';
}

function renderMissions() {
  const missions = [...state.missions.values()].reverse().map((mission) => {
    const subtasks = mission.feedback?.subtasks || [];
    const steps = subtasks.map((subtask, index) => {
      const kind = stepClass(subtask);
      return element('div', {
        class: `step ${kind}`, 'data-step': String(index), 'data-state': kind, title: subtask.task_id,
      }, element('span', { class: 'name', text: subtask.task_name }), element('span', { text: kind }));
    });
    return element('div', { class: 'mission', 'data-mission-id': mission.task_id },
      element('div', { class: 'mission-title' },
        element('span', { text: `Mission ${mission.task_id.slice(0, 8)}` }),
        statusBadge(mission.status),
        element('span', { class: 'hint', text: `from ${mission.source}` })),
      element('div', { class: 'steps' }, ...steps));
  });
  $('#missions').replaceChildren(...missions);
  $('#missions-empty').hidden = missions.length > 0;
}

async function cancelTask(taskId) {
  try {
    const result = await api('/api/tasks/cancel', { method: 'POST', json: { task_ids: [taskId] } });
    say(`Cancel of ${taskId}: ${result.status}${result.error_message ? ` (${result.error_message})` : ''}`);
  } catch (error) {
    say(`Cancel failed: ${error.message}`, true);
  }
}

// The dialog is outside the table, which is drawn again at every event: what the operator
// types there survives the updates.
function askPriority(task) {
  state.priorityTaskId = task.task_id;
  $('#priority-task').textContent = task.task_id;
  $('#priority-input').value = String(task.priority ?? 0);
  $('#priority-dialog').showModal();
  $('#priority-input').select();
}

async function setPriority(event) {
  event.preventDefault();
  const taskId = state.priorityTaskId;
  const priority = Number($('#priority-input').value);
  $('#priority-dialog').close();
  try {
    const result = await api('/api/tasks/reprioritize', { method: 'POST', json: { task_ids: [taskId], priority } });
    const failed = result.status !== 'DONE';
    say(`Priority of ${taskId}: ${failed ? result.status : priority}${result.error_message ? ` (${result.error_message})` : ''}`, failed);
  } catch (error) {
    say(`Priority change failed: ${error.message}`, true);
  }
}

async function stopAll() {
  try {
    const result = await api('/api/stop', { method: 'POST' });
    say(`STOP: ${result.status}`);
  } catch (error) {
    say(`STOP failed: ${error.message}`, true);
  }
}

// ---- start form, generated from each task's JSON Schema ------------------------------------

async function loadDeclared() {
  state.declared = await api('/api/tasks');
  const select = $('#task-select');
  const chosen = select.value;
  select.replaceChildren(...state.declared.map((task) => element('option', { value: task.task_name, text: task.task_name })));
  $('#task-names').replaceChildren(...state.declared.map((task) => element('option', { value: task.task_name })));
  if (chosen) select.value = chosen;
  renderFields();
}

function renderFields() {
  const task = state.declared.find((each) => each.task_name === $('#task-select').value);
  const fields = $('#task-fields');
  if (!task) { fields.replaceChildren(); return; }
  const schema = task.goal_schema || {};
  fields.replaceChildren(schema.properties ? objectFields(schema, '') : jsonField('', {}, 'task_data (JSON)'));
}

function objectFields(schema, path) {
  const children = Object.entries(schema.properties || {}).map(([name, property]) => {
    const fieldPath = path ? `${path}.${name}` : name;
    if (property.type === 'object' && property.properties) {
      return element('fieldset', { 'data-object': fieldPath },
        element('legend', { text: `${name} (${property['x-ros-type'] || 'object'})` }),
        objectFields(property, fieldPath));
    }
    return valueField(name, fieldPath, property);
  });
  const group = element('div', {});
  group.append(...children);
  return group;
}

function valueField(name, path, property) {
  const type = property.type;
  const label = element('label', {}, name, element('small', { text: property['x-ros-type'] || type || '' }), ' ');
  let input;
  if (type === 'boolean') {
    input = element('input', { type: 'checkbox' });
    input.checked = Boolean(property.default);
  } else if (type === 'number' || type === 'integer') {
    input = element('input', { type: 'number', step: type === 'integer' ? '1' : 'any' });
    input.value = property.default ?? 0;
  } else if (type === 'string') {
    input = element('input', { type: 'text' });
    if (property.maxLength) input.maxLength = property.maxLength;
    input.value = property.default ?? '';
  } else {
    return jsonField(path, property.default ?? (type === 'array' ? [] : {}), `${name} (${property['x-ros-type'] || 'JSON'})`);
  }
  input.dataset.field = path;
  input.dataset.kind = type;
  input.name = path;
  label.append(input);
  return label;
}

function jsonField(path, value, title) {
  const area = element('textarea', { 'data-field': path, 'data-kind': 'json', name: path || 'task_data' });
  area.value = JSON.stringify(value, null, 1);
  return element('label', {}, title, area);
}

function collectTaskData() {
  let data = {};
  for (const input of $('#task-fields').querySelectorAll('[data-field]')) {
    const kind = input.dataset.kind;
    let value;
    if (kind === 'boolean') value = input.checked;
    else if (kind === 'number' || kind === 'integer') value = Number(input.value);
    else if (kind === 'json') {
      try { value = JSON.parse(input.value || 'null'); } catch (error) {
        throw new Error(`${input.name}: not valid JSON (${error.message})`);
      }
    } else value = input.value;
    if (!input.dataset.field) { data = value; continue; }
    const parts = input.dataset.field.split('.');
    let target = data;
    for (const part of parts.slice(0, -1)) target = (target[part] ??= {});
    target[parts.at(-1)] = value;
  }
  return data;
}

// The start's options the operator gave; each left empty takes the task's declaration.
function startOptions() {
  const options = {};
  const priority = $('#start-priority').value.trim();
  if (priority !== '') options.priority = Number(priority);
  if ($('#start-on-conflict').value) options.on_conflict = $('#start-on-conflict').value;
  const timeout = $('#start-timeout').value.trim();
  if (timeout !== '' && Number(timeout) > 0) options.timeout_sec = Number(timeout);
  return options;
}

async function startTask(event) {
  event.preventDefault();
  const taskName = $('#task-select').value;
  try {
    const request = { task_name: taskName, task_data: collectTaskData(), ...startOptions() };
    const started = await api('/api/tasks/start', { method: 'POST', json: request });
    say(`Started ${taskName}: ${started.task_id}`);
  } catch (error) {
    say(`Could not start ${taskName}: ${error.message}`, true);
  }
}

// ---- history -------------------------------------------------------------------------------

function historyQuery(extra = {}) {
  const form = new FormData($('#history-filters'));
  const query = new URLSearchParams({ limit: String(HISTORY_ROWS), ...extra });
  for (const name of ['task_name', 'status', 'source']) if (form.get(name)) query.set(name, form.get(name));
  const since = form.get('since');
  if (since) query.set('since', new Date(Date.now() - Number(since) * 1000).toISOString());
  return query;
}

async function loadHistory() {
  const tasks = await api(`/api/history?${historyQuery()}`);
  $('#history tbody').replaceChildren(...tasks.map((task) => historyRow(task)));
}

function historyRow(task) {
  return element('tr', { 'data-task-id': task.task_id },
    element('td', { text: task.sequence ? String(task.sequence) : '' }),
    element('td', { text: task.task_name }),
    element('td', { class: 'id', text: task.task_id }),
    element('td', { text: task.source }),
    statusCell(task, task.status),
    element('td', { text: task.ended ? new Date(task.ended).toLocaleString() : '' }),
    element('td', { text: task.duration_sec == null ? '' : formatSeconds(task.duration_sec) }),
    element('td', { class: 'result', text: task.error_message || compactJson(task.result ?? {}), title: JSON.stringify(task.result ?? {}) }));
}

function matchesFilters(task) {
  const form = new FormData($('#history-filters'));
  return ['task_name', 'status', 'source'].every((name) => !form.get(name) || form.get(name) === task[name]);
}

function addHistoryRow(task) {
  if (!matchesFilters(task)) return;
  const body = $('#history tbody');
  body.prepend(historyRow(task));
  while (body.children.length > HISTORY_ROWS) body.lastElementChild.remove();
}

async function exportCsv() {
  try {
    const response = await api(`/api/history?${historyQuery({ limit: '10000', format: 'csv' })}`, { raw: true });
    const link = element('a', { href: URL.createObjectURL(await response.blob()), download: 'task_history.csv' });
    link.click();
    URL.revokeObjectURL(link.href);
  } catch (error) {
    say(`Export failed: ${error.message}`, true);
  }
}

// ---- wiring --------------------------------------------------------------------------------

function main() {
  takeToken();
  if (!state.token) askForToken();
  $('#token-form').addEventListener('submit', (event) => {
    event.preventDefault();
    sessionStorage.setItem('task_manager_token', $('#token-input').value.trim());
    window.location.reload();
  });
  $('#stop').addEventListener('click', stopAll);
  $('#priority-form').addEventListener('submit', setPriority);
  $('#priority-cancel').addEventListener('click', () => $('#priority-dialog').close());
  $('#task-select').addEventListener('change', renderFields);
  $('#start-form').addEventListener('submit', startTask);
  $('#history-filters').addEventListener('submit', (event) => { event.preventDefault(); loadHistory().catch((error) => say(error.message, true)); });
  $('#export-csv').addEventListener('click', exportCsv);
  setInterval(() => {
    for (const row of document.querySelectorAll('#active tbody tr')) {
      const task = state.tasks.get(row.dataset.taskId);
      if (task) row.querySelector('.elapsed').textContent = elapsed(task);
    }
  }, 1000);
  showConnection();
  followEvents();
}

main();
