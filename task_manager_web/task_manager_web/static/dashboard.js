// The Task Manager dashboard: plain JavaScript modules, no build step, nothing from outside
// the gateway. Live state comes from /api/events; on every (re)connection the active tasks,
// the schedules and the history are read again.

import { api, loadRole, wireToken } from './api.js';
import { renderConfirmations, tickConfirmations } from './confirmations.js';
import { $, say } from './dom.js';
import { followEvents } from './events.js';
import { addHistoryRow, loadHistory, wireHistory } from './history.js';
import { rememberMission, renderMissions } from './missions.js';
import { loadSchedules, onScheduleEvent, tickSchedules, wireSchedules } from './schedules.js';
import { loadDeclared, wireStartForm } from './start_form.js';
import { isLive, state } from './state.js';
import { applyTaskEvent, loadActive, renderActive, tickElapsed, wireTasks } from './tasks.js';

function onConnection(connected) {
  state.nodeConnected = connected;
  showConnection();
  if (connected) refreshAll();
}

function showConnection() {
  const badge = $('#connection');
  const banner = $('#banner');
  const live = isLive();
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
  applyTaskEvent(event);
  if (task.task_name === 'system/mission') rememberMission(task);
  else if (state.missions.has(task.mission_id)) renderMissions();
  if (event.event === 'ENDED') addHistoryRow(task);
  onScheduleEvent(event);
  renderConfirmations();
}

async function refreshAll() {
  try {
    if (!state.declared.length) await loadDeclared();
    const active = await loadActive();
    for (const task of active) if (task.task_name === 'system/mission') rememberMission(task);
    renderMissions();
    renderConfirmations();
    await Promise.all([loadSchedules(), loadHistory()]);
  } catch (error) {
    say(`Could not read the state: ${error.message}`, true);
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

function main() {
  wireToken();
  $('#stop').addEventListener('click', stopAll);
  wireTasks();
  wireStartForm();
  wireSchedules();
  wireHistory();
  setInterval(() => { tickElapsed(); tickConfirmations(); tickSchedules(); }, 1000);
  showConnection();
  loadRole();
  followEvents({
    opened: () => { state.streamOpen = true; },
    closed: () => { state.streamOpen = false; showConnection(); },
    hello: (hello) => onConnection(hello.connected),
    connection: (change) => onConnection(change.connected),
    task: onTaskEvent,
  });
}

main();
