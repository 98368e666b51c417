// The start form, generated from each task's JSON Schema: start the task now, or schedule it
// (at a time, every N seconds, on a cron expression in a time zone) with the same options.

import { api } from './api.js';
import { $, element, localTime, say } from './dom.js';
import { refreshSchedules } from './schedules.js';
import { state } from './state.js';

export async function loadDeclared() {
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

// When a schedule runs, as POST /api/schedules takes it; an error names what is missing.
function whenFields() {
  const when = $('#start-when').value;
  if (when === 'at') {
    const at = $('#when-at').value;
    if (!at) throw new Error('give the time to run it at');
    return { at: new Date(at).toISOString() };
  }
  if (when === 'every') {
    const period = Number($('#when-every').value);
    if (!(period > 0)) throw new Error('give its period, in seconds (more than 0)');
    return { period_sec: period };
  }
  const cron = $('#when-cron').value.trim();
  if (!cron) throw new Error("give a cron expression (five fields: '0 2 * * *' is 02:00 every day)");
  return { cron, time_zone: $('#when-time-zone').value.trim() };
}

async function startTask(taskName, request) {
  const started = await api('/api/tasks/start', { method: 'POST', json: request });
  say(`Started ${taskName}: ${started.task_id}`);
}

async function scheduleTask(taskName, request) {
  const scheduleId = $('#when-schedule-id').value.trim();
  const body = { ...request, ...whenFields(), ...(scheduleId ? { schedule_id: scheduleId } : {}) };
  const answer = await api('/api/schedules', { method: 'POST', json: body });
  if (!answer.scheduled) {
    say(`Could not schedule ${taskName}: ${answer.message}`, true);
    return;
  }
  const next = answer.next_run ? `, next run ${localTime(answer.next_run)}` : '';
  say(`Scheduled ${taskName}: ${answer.schedule_id}${next}`);
  refreshSchedules();
}

async function submitStart(event) {
  event.preventDefault();
  const taskName = $('#task-select').value;
  const now = $('#start-when').value === 'now';
  try {
    const request = { task_name: taskName, task_data: collectTaskData(), ...startOptions() };
    await (now ? startTask(taskName, request) : scheduleTask(taskName, request));
  } catch (error) {
    say(`Could not ${now ? 'start' : 'schedule'} ${taskName}: ${error.message}`, true);
  }
}

// Only the fields of the chosen "when"; the button says what it does.
function showWhen() {
  const when = $('#start-when').value;
  for (const label of document.querySelectorAll('[data-when]')) label.hidden = !label.dataset.when.split(' ').includes(when);
  $('#start-button').textContent = when === 'now' ? 'Start' : 'Schedule';
}

function offerTimeZones() {
  const zones = typeof Intl.supportedValuesOf === 'function' ? Intl.supportedValuesOf('timeZone') : [];
  $('#time-zones').replaceChildren(...zones.map((zone) => element('option', { value: zone })));
  $('#when-time-zone').value = Intl.DateTimeFormat().resolvedOptions().timeZone || 'UTC';
}

export function wireStartForm() {
  $('#task-select').addEventListener('change', renderFields);
  $('#start-form').addEventListener('submit', submitStart);
  $('#start-when').addEventListener('change', showWhen);
  offerTimeZones();
  showWhen();
}
