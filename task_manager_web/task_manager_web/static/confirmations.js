// Confirmations waiting for an operator (system/confirm, alone or as a mission's step): a
// banner at the top of the page for each, with its prompt, the time left, Confirm and Reject;
// the page's title counts them too, for a page in a background tab.

import { api, idPath } from './api.js';
import { $, element, formatSeconds, say } from './dom.js';
import { state } from './state.js';

const CONFIRM_TASK = 'system/confirm';
const PAGE_TITLE = document.title;

// key: task id, value: {remaining, deadline}: the latest remaining_sec and when it runs out
const deadlines = new Map();

function waiting() {
  return [...state.tasks.values()].filter((task) => task.task_name === CONFIRM_TASK && task.status === 'IN_PROGRESS' && !task.endedAt);
}

// The deadline moves only when the feedback says another remaining time.
function deadlineOf(task) {
  const remaining = task.feedback?.remaining_sec;
  if (typeof remaining !== 'number') return null;
  const known = deadlines.get(task.task_id);
  if (known && known.remaining === remaining) return known.deadline;
  const deadline = Date.now() + remaining * 1000;
  deadlines.set(task.task_id, { remaining, deadline });
  return deadline;
}

function countdownText(deadline) {
  if (deadline === null) return '';
  return `${formatSeconds(Math.max(0, (deadline - Date.now()) / 1000))} left`;
}

// "step 2 of mission 5f0e…", or the task's own id.
function whereText(task) {
  if (!task.mission_id) return `task ${task.task_id}`;
  const steps = state.missions.get(task.mission_id)?.feedback?.subtasks || [];
  const index = steps.findIndex((step) => step.task_id === task.task_id);
  const step = index >= 0 ? `step ${index + 1} of ${steps.length} of ` : 'a step of ';
  return `${step}mission ${task.mission_id}`;
}

function newItem(task) {
  const comment = element('input', { class: 'confirm-comment', type: 'text', maxlength: '1000', placeholder: 'comment (optional)', 'aria-label': 'comment' });
  const buttons = [
    element('button', { class: 'confirm', type: 'button', 'data-needs': 'operator', text: 'Confirm' }),
    element('button', { class: 'reject', type: 'button', 'data-needs': 'operator', text: 'Reject' }),
  ];
  buttons[0].addEventListener('click', () => answer(task.task_id, false, comment, buttons));
  buttons[1].addEventListener('click', () => answer(task.task_id, true, comment, buttons));
  return element('div', { class: 'confirmation', role: 'alert', 'data-task-id': task.task_id },
    element('div', { class: 'confirm-text' },
      element('div', { class: 'confirm-title' }, element('strong', { text: 'Waiting for an operator' }), ' ',
        element('span', { class: 'confirm-where' })),
      element('p', { class: 'confirm-prompt' })),
    element('span', { class: 'countdown' }),
    comment, ...buttons);
}

function updateItem(item, task) {
  const prompt = task.feedback?.prompt;
  item.querySelector('.confirm-prompt').textContent = typeof prompt === 'string' && prompt ? prompt : '(its prompt comes with its first feedback)';
  item.querySelector('.confirm-where').textContent = whereText(task);
  item.querySelector('.countdown').textContent = countdownText(deadlineOf(task));
}

// Items are kept between events, so that a comment being typed survives them.
export function renderConfirmations() {
  const banner = $('#confirmations');
  const tasks = waiting();
  const ids = new Set(tasks.map((task) => task.task_id));
  for (const item of [...banner.children]) {
    if (!ids.has(item.dataset.taskId)) item.remove();
  }
  for (const id of deadlines.keys()) if (!ids.has(id)) deadlines.delete(id);
  for (const task of tasks) {
    let item = banner.querySelector(`[data-task-id="${CSS.escape(task.task_id)}"]`);
    if (!item) banner.append(item = newItem(task));
    updateItem(item, task);
  }
  banner.hidden = tasks.length === 0;
  document.title = tasks.length ? `(${tasks.length}) waiting for confirmation · ${PAGE_TITLE}` : PAGE_TITLE;
}

export function tickConfirmations() {
  for (const item of $('#confirmations').children) {
    const known = deadlines.get(item.dataset.taskId);
    if (known) item.querySelector('.countdown').textContent = countdownText(known.deadline);
  }
}

// The banner goes with the task's end (its ENDED event), not with this answer.
async function answer(taskId, reject, comment, buttons) {
  for (const button of buttons) button.disabled = true;
  const body = { reject, ...(comment.value.trim() ? { comment: comment.value.trim() } : {}) };
  try {
    const answered = await api(`/api/tasks/${idPath(taskId)}/confirm`, { method: 'POST', json: body });
    say(`${reject ? 'Rejected' : 'Confirmed'} ${taskId} (by ${answered.by})`);
  } catch (error) {
    for (const button of buttons) button.disabled = false;
    say(`Could not ${reject ? 'reject' : 'confirm'} ${taskId}: ${error.message}`, true);
  }
}
