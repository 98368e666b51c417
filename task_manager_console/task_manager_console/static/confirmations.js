// The fleet's confirmations waiting for an operator (system/confirm on any robot, alone or as a
// mission's step): a banner at the top of the page for each, with its robot, its prompt, the
// time left, Confirm and Reject; the page's title counts them too.

import { api, idPath } from '/web-static/api.js';
import { $, element, formatSeconds, say } from '/web-static/dom.js';
import { sortedRobots } from './state.js';

const CONFIRM_TASK = 'system/confirm';
const PAGE_TITLE = document.title;

// key: robot id and task id, value: {remaining, deadline}: the latest remaining_sec and when it
// runs out
const deadlines = new Map();

function keyOf(robotId, taskId) {
  return JSON.stringify([robotId, taskId]);
}

function waiting() {
  return sortedRobots().flatMap((robot) => (robot.active || [])
    .filter((task) => task.task_name === CONFIRM_TASK && task.status === 'IN_PROGRESS')
    .map((task) => ({ robot, task, key: keyOf(robot.robot_id, task.task_id) })));
}

// The deadline moves only when the feedback says another remaining time.
function deadlineOf(key, task) {
  const remaining = task.feedback?.remaining_sec;
  if (typeof remaining !== 'number') return null;
  const known = deadlines.get(key);
  if (known && known.remaining === remaining) return known.deadline;
  const deadline = Date.now() + remaining * 1000;
  deadlines.set(key, { remaining, deadline });
  return deadline;
}

function countdownText(deadline) {
  if (deadline === null || deadline === undefined) return '';
  return `${formatSeconds(Math.max(0, (deadline - Date.now()) / 1000))} left`;
}

function newItem({ robot, task, key }) {
  const comment = element('input', { class: 'confirm-comment', type: 'text', maxlength: '1000', placeholder: 'comment (optional)', 'aria-label': 'comment' });
  const buttons = [
    element('button', { class: 'confirm', type: 'button', 'data-needs': 'operator', text: 'Confirm' }),
    element('button', { class: 'reject', type: 'button', 'data-needs': 'operator', text: 'Reject' }),
  ];
  buttons[0].addEventListener('click', () => answer(robot.robot_id, task.task_id, false, comment, buttons));
  buttons[1].addEventListener('click', () => answer(robot.robot_id, task.task_id, true, comment, buttons));
  const where = task.mission_id ? `a step of mission ${task.mission_id}` : `task ${task.task_id}`;
  return element('div', { class: 'confirmation', role: 'alert', 'data-key': key, 'data-robot-id': robot.robot_id, 'data-task-id': task.task_id },
    element('div', { class: 'confirm-text' },
      element('div', { class: 'confirm-title' },
        element('span', { class: 'confirm-robot', text: robot.robot_id }), ' is waiting for an operator ',
        element('span', { class: 'confirm-where', text: where })),
      element('p', { class: 'confirm-prompt' })),
    element('span', { class: 'countdown' }),
    comment, ...buttons);
}

// Items are kept between changes, so that a comment being typed survives them.
export function renderConfirmations() {
  const banner = $('#confirmations');
  const items = waiting();
  const keys = new Set(items.map((item) => item.key));
  for (const node of [...banner.children]) if (!keys.has(node.dataset.key)) node.remove();
  for (const key of deadlines.keys()) if (!keys.has(key)) deadlines.delete(key);
  for (const item of items) {
    let node = [...banner.children].find((each) => each.dataset.key === item.key);
    if (!node) banner.append(node = newItem(item));
    const prompt = item.task.feedback?.prompt;
    node.querySelector('.confirm-prompt').textContent = typeof prompt === 'string' && prompt ? prompt : '(its prompt comes with its first feedback)';
    node.querySelector('.countdown').textContent = countdownText(deadlineOf(item.key, item.task));
  }
  banner.hidden = items.length === 0;
  document.title = items.length ? `(${items.length}) waiting for confirmation · ${PAGE_TITLE}` : PAGE_TITLE;
}

export function tickConfirmations() {
  for (const node of $('#confirmations').children) {
    node.querySelector('.countdown').textContent = countdownText(deadlines.get(node.dataset.key)?.deadline);
  }
}

// The banner goes when the robot's active tasks no longer hold the task, not with this answer.
async function answer(robotId, taskId, reject, comment, buttons) {
  for (const button of buttons) button.disabled = true;
  const body = { reject, ...(comment.value.trim() ? { comment: comment.value.trim() } : {}) };
  const verb = reject ? 'reject' : 'confirm';
  try {
    const answered = await api(`/api/robots/${idPath(robotId)}/tasks/${idPath(taskId)}/confirm`, { method: 'POST', json: body });
    say(`${reject ? 'Rejected' : 'Confirmed'} ${taskId} on ${robotId} (by ${answered.by})`);
  } catch (error) {
    for (const button of buttons) button.disabled = false;
    say(`Could not ${verb} ${taskId} on ${robotId}: ${error.message}`, true);
  }
}
