// The active tasks' table: status, queue place, priority, running time, latest feedback or
// decision, and the operator's buttons (pause or resume, cancel, change the priority).

import { api } from './api.js';
import { $, compactJson, element, formatSeconds, say, statusBadge } from './dom.js';
import { canPause, isLive, state } from './state.js';

const ENDED_VISIBLE_MS = 4000;       // an ended task stays in the active table this long
// Other tasks' queue positions move without an event of theirs: the active list is read again
// this long after an event that may have moved them (one read for a burst of events).
const QUEUE_REREAD_MS = 150;

let queueReread = null;    // the pending timer of rereadQueue, or null
let priorityTaskId = '';   // the task whose priority the dialog changes
// One set per read of the active list in flight: the ids of the tasks an event changed since
// the read began. The answer may predate those events; for those tasks the events win.
const changedDuringReads = new Set();

// Keeps an event's task; an ended one is shown a moment, then dropped.
export function applyTaskEvent(event) {
  const task = event.task;
  for (const changed of changedDuringReads) changed.add(task.task_id);
  if (event.event === 'ENDED') {
    state.tasks.set(task.task_id, { ...task, endedAt: Date.now() });
    setTimeout(() => { dropEnded(task.task_id); }, ENDED_VISIBLE_MS);
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

// GET /api/active, and the ids of the tasks an event changed while it was read.
async function readActive() {
  const changed = new Set();
  changedDuringReads.add(changed);
  try {
    return { active: await api('/api/active'), changed };
  } finally {
    changedDuringReads.delete(changed);
  }
}

// The active list read again (after a (re)connection): the page's tasks become the answer's,
// except a task ended moments ago (still shown) or one an event changed during the read (as
// the event left it, or gone). Returns the active tasks now shown.
export async function loadActive() {
  const { active, changed } = await readActive();
  const fresh = new Map(active.map((task) => [task.task_id, task]));
  for (const [id, task] of state.tasks) if (task.endedAt || changed.has(id)) fresh.set(id, task);
  for (const id of changed) if (!state.tasks.has(id)) fresh.delete(id);
  state.tasks = fresh;
  renderActive();
  return [...fresh.values()].filter((task) => !task.endedAt);
}

function rereadQueueSoon() {
  if (queueReread !== null) return;
  queueReread = setTimeout(rereadQueue, QUEUE_REREAD_MS);
}

// Takes the queue positions and priorities of the tasks still queued from a fresh active list;
// anything else, and any task an event changed during the read, is left as the events say.
async function rereadQueue() {
  queueReread = null;
  try {
    const { active, changed } = await readActive();
    for (const fresh of active) {
      const shown = state.tasks.get(fresh.task_id);
      if (shown?.status === 'QUEUED' && fresh.status === 'QUEUED' && !changed.has(fresh.task_id)) {
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

// Running time: time paused (paused_sec) does not count. A queued task: its time waiting.
export function elapsed(task) {
  if (task.duration_sec != null) return formatSeconds(task.duration_sec);
  if (task.status === 'QUEUED' && task.received) {
    return `waiting ${formatSeconds(Math.max(0, (Date.now() - Date.parse(task.received)) / 1000))}`;
  }
  if (!task.started) return '';
  if (task.status === 'PAUSED' && !task.pausedAt) return 'paused';
  const end = task.status === 'PAUSED' ? task.pausedAt : (task.ended ? Date.parse(task.ended) : Date.now());
  return formatSeconds(Math.max(0, (end - Date.parse(task.started)) / 1000 - (task.paused_sec || 0)));
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

export function statusCell(task, shown) {
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
      'data-needs': 'admin', onclick: () => askPriority(task),
    }));
  }
  return cell;
}

// Pause for a running task that can pause, Resume for a paused one; nothing otherwise.
export function pauseButton(task) {
  if (!canPause(task)) return '';
  if (task.status === 'PAUSED') {
    return element('button', {
      class: 'resume', type: 'button', text: 'Resume', 'data-needs': 'operator', onclick: () => pauseOrResume(task.task_id, 'resume'),
    });
  }
  if (task.status !== 'IN_PROGRESS') return '';
  return element('button', {
    class: 'pause', type: 'button', text: 'Pause', 'data-needs': 'operator', onclick: () => pauseOrResume(task.task_id, 'pause'),
  });
}

function actionsCell(task) {
  if (task.endedAt) return element('td', { class: 'actions' });
  const cancel = element('button', {
    class: 'cancel', type: 'button', text: 'Cancel', 'data-needs': 'operator', onclick: () => cancelTask(task.task_id),
  });
  return element('td', { class: 'actions' }, pauseButton(task), ' ', cancel);
}

export function renderActive() {
  const body = $('#active tbody');
  const live = isLive();
  const rows = activeOrder([...state.tasks.values()]).map((task) => {
    const shown = live || task.endedAt ? task.status : 'STALE';
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
      actionsCell(task));
  });
  body.replaceChildren(...rows);
  $('#active-empty').hidden = rows.length > 0;
}

export function tickElapsed() {
  for (const row of document.querySelectorAll('#active tbody tr')) {
    const task = state.tasks.get(row.dataset.taskId);
    if (task) row.querySelector('.elapsed').textContent = elapsed(task);
  }
}

// system/pause or system/resume of one task; the row changes with the task's own event.
async function pauseOrResume(taskId, verb) {
  const done = verb === 'pause' ? 'paused' : 'resumed';
  try {
    const answer = await api(`/api/tasks/${verb}`, { method: 'POST', json: { task_ids: [taskId] } });
    if (answer[done].includes(taskId)) say(`${taskId} ${done}`);
    else say(`Could not ${verb} ${taskId}: ${answer.errors.join('; ')}`, true);
  } catch (error) {
    say(`${verb === 'pause' ? 'Pause' : 'Resume'} failed: ${error.message}`, true);
  }
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
  priorityTaskId = task.task_id;
  $('#priority-task').textContent = task.task_id;
  $('#priority-input').value = String(task.priority ?? 0);
  $('#priority-dialog').showModal();
  $('#priority-input').select();
}

async function setPriority(event) {
  event.preventDefault();
  const taskId = priorityTaskId;
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

export function wireTasks() {
  $('#priority-form').addEventListener('submit', setPriority);
  $('#priority-cancel').addEventListener('click', () => $('#priority-dialog').close());
}
