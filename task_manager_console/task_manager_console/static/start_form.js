// Start a task on one robot, or on "any robot" (the console chooses: ONLINE, declaring the
// task, its resources free first, then the least loaded). The answer says where, and why.

import { api, idPath } from '/web-static/api.js';
import { $, element, say } from '/web-static/dom.js';
import { sortedRobots } from './state.js';

// The task names any robot declares, and the robot choices, kept as the robots change (the
// values chosen stay).
export function renderStartChoices() {
  const robots = sortedRobots();
  const names = [...new Set(robots.flatMap((robot) => (robot.tasks || []).map((task) => task.task_name)))].sort();
  const list = $('#declared-tasks');
  if (list.children.length !== names.length || names.some((name, index) => list.children[index].value !== name)) {
    list.replaceChildren(...names.map((name) => element('option', { value: name })));
  }
  const select = $('#start-robot');
  const chosen = select.value;
  const ids = robots.map((robot) => robot.robot_id);
  const shown = [...select.options].slice(1).map((option) => option.value);
  if (shown.join('\n') !== ids.join('\n')) {
    select.replaceChildren(element('option', { value: '', text: 'any robot' }),
      ...ids.map((id) => element('option', { value: id, text: id })));
    select.value = ids.includes(chosen) ? chosen : '';
  }
  const robotIds = $('#robot-ids');
  robotIds.replaceChildren(...ids.map((id) => element('option', { value: id })));
}

function taskData() {
  const text = $('#start-data').value.trim() || '{}';
  const data = JSON.parse(text);
  if (data === null || typeof data !== 'object' || Array.isArray(data)) throw new Error('task data: a JSON object, like {"x": 1}');
  return data;
}

function whyNot(others) {
  const entries = Object.entries(others || {});
  return entries.length ? ` Not ${entries.map(([id, why]) => `${id} (${why})`).join(', ')}.` : '';
}

async function start(event) {
  event.preventDefault();
  const button = $('#start-button');
  const taskName = $('#start-task').value.trim();
  const robotId = $('#start-robot').value;
  let data;
  try {
    data = taskData();
  } catch (error) {
    say(`Not started: ${error.message}`, true);
    return;
  }
  button.disabled = true;
  try {
    const body = { task_name: taskName, task_data: data };
    const started = robotId
      ? await api(`/api/robots/${idPath(robotId)}/tasks/start`, { method: 'POST', json: body })
      : await api('/api/fleet/start', { method: 'POST', json: body });
    const answer = $('#start-answer');
    answer.dataset.robotId = started.robot_id;
    answer.dataset.taskId = started.task_id;
    answer.textContent = started.reason ? `${started.reason}.${whyNot(started.others)}` : '';
    say(`Started ${taskName} on ${started.robot_id}: ${started.task_id}`);
  } catch (error) {
    say(`Not started: ${error.message}`, true);
  } finally {
    button.disabled = false;
  }
}

export function wireStartForm() {
  $('#start-form').addEventListener('submit', start);
}
