// A card per robot: its connection, its active task and how far it is, its queue length and its
// last result. A card is kept between changes (rebuilt inside), in the robots' id order.

import { $, compactJson, element, formatSeconds, fromNow, statusBadge } from '/web-static/dom.js';
import { queueLength, sortedRobots } from './state.js';

const RUNNING = ['IN_PROGRESS', 'PAUSED'];

// The task a card shows as the robot's: a running (or paused) one of no mission, the mission
// before its steps; else the first active one.
function activeTask(robot) {
  const active = robot.active || [];
  const running = active.filter((task) => RUNNING.includes(task.status));
  return running.find((task) => !task.mission_id) || running[0] || null;
}

// How far the task is: a mission's steps done of all, or a feedback's own fraction; null if
// nothing says.
function progressOf(task, robot) {
  if (task.task_name === 'system/mission') {
    const steps = task.feedback?.subtasks;
    if (Array.isArray(steps) && steps.length) {
      const done = steps.filter((step) => step.task_status === 'DONE').length;
      return { value: done, max: steps.length, text: `step ${Math.min(done + 1, steps.length)} of ${steps.length}` };
    }
    const stepTasks = (robot.active || []).filter((each) => each.mission_id === task.task_id);
    if (stepTasks.length) return { value: 0, max: 1, text: `${stepTasks.length} step(s) active` };
  }
  const fraction = task.feedback?.progress ?? task.feedback?.percent_complete;
  if (typeof fraction === 'number') {
    const max = fraction > 1 ? 100 : 1;
    return { value: fraction, max, text: `${Math.round((fraction / max) * 100)} %` };
  }
  return null;
}

function runningFor(task) {
  if (!task.started) return '';
  const seconds = (Date.now() - Date.parse(task.started)) / 1000 - (task.paused_sec || 0);
  return formatSeconds(Math.max(0, seconds));
}

function activeRows(robot) {
  const task = activeTask(robot);
  if (!task) return [element('dt', { text: 'Active' }), element('dd', { class: 'active-task', text: 'idle' })];
  const progress = progressOf(task, robot);
  const feedback = task.feedback && !progress ? compactJson(task.feedback, 80) : '';
  return [
    element('dt', { text: 'Active' }),
    element('dd', { class: 'active-task', 'data-task-id': task.task_id },
      element('strong', { text: task.task_name }), ' ', statusBadge(task.status),
      element('div', { class: 'since', text: `${task.task_id} · ${task.source}${task.started ? ` · ${runningFor(task)}` : ''}` })),
    ...(progress ? [element('dt', { text: 'Progress' }), element('dd', {},
      element('progress', { value: String(progress.value), max: String(progress.max) }),
      element('span', { class: 'since', text: progress.text }))] : []),
    ...(feedback ? [element('dt', { text: 'Feedback' }), element('dd', { class: 'since', text: feedback, title: JSON.stringify(task.feedback) })] : []),
  ];
}

function lastResultRows(robot) {
  const last = robot.last_result;
  if (!last) return [element('dt', { text: 'Last result' }), element('dd', { class: 'last-result', text: 'none yet' })];
  return [
    element('dt', { text: 'Last result' }),
    element('dd', { class: 'last-result', 'data-task-id': last.task_id },
      `${last.task_name} `, statusBadge(last.status),
      element('div', { class: 'since', text: `${last.task_id}${last.ended ? ` · ${fromNow(last.ended)}` : ''}${last.error_message ? ` · ${last.error_message}` : ''}` })),
  ];
}

function cardContent(robot) {
  const state = robot.connection_state;
  const warnings = [];
  if (state === 'ONLINE' && robot.task_manager_connected === false) warnings.push('its Task Manager is not reachable');
  if (robot.silent) warnings.push('silent: no word from it for a while');
  const active = robot.active || [];
  return [
    element('div', { class: 'robot-title' },
      element('span', { class: 'robot-id', text: robot.robot_id }),
      element('span', { class: `badge ${state} connection-state`, text: state })),
    element('div', { class: 'since', text: robot.since ? `since ${new Date(robot.since).toLocaleString()}` : '' }),
    ...warnings.map((text) => element('div', { class: 'warning', text })),
    element('dl', {},
      ...activeRows(robot),
      element('dt', { text: 'Queue' }),
      element('dd', { class: 'queue-length', text: String(queueLength(robot)) }),
      element('dt', { text: 'Tasks' }),
      element('dd', { class: 'active-count', text: `${active.length} active${robot.active_omitted ? ` (+${robot.active_omitted} not listed)` : ''}` }),
      ...lastResultRows(robot)),
  ];
}

// Rebuild the cards of the robots in `changed` (every card when left out), in id order; the
// count of robots online. At 200 robots a change rebuilds its own card only.
export function renderRobots(changed = null) {
  const robots = sortedRobots();
  const container = $('#robots');
  const cards = new Map([...container.children].map((card) => [card.dataset.robotId, card]));
  const ordered = robots.map((robot) => {
    let card = cards.get(robot.robot_id);
    if (card && changed && !changed.has(robot.robot_id)) return card;
    card = card || element('article', { 'data-robot-id': robot.robot_id });
    card.className = `robot ${robot.connection_state}`;
    card.dataset.state = robot.connection_state;
    card.dataset.taskManager = robot.task_manager_connected ? 'connected' : 'unreachable';
    card.replaceChildren(...cardContent(robot));
    return card;
  });
  const inPlace = ordered.length === container.children.length && ordered.every((card, index) => container.children[index] === card);
  if (!inPlace) container.replaceChildren(...ordered);
  $('#robots-empty').hidden = robots.length > 0;
  const online = robots.filter((robot) => robot.connection_state === 'ONLINE').length;
  $('#fleet-count').textContent = `${online} of ${robots.length} robots online`;
}

// The robots whose card shows a running time (rebuilt each second).
export function robotsRunning() {
  return new Set(sortedRobots().filter((robot) => activeTask(robot)?.started).map((robot) => robot.robot_id));
}
