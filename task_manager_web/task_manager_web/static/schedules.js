// The schedules panel: every schedule with when it runs, its next and last run, its counts;
// enable, disable and remove (asked again in a dialog). Read again after each change made
// here, on the events of schedules' runs and of schedule changes from other doors, and every
// minute for the next runs.

import { api, idPath } from './api.js';
import { $, element, fromNow, localTime, say, statusBadge } from './dom.js';

const REREAD_MS = 200;          // one read for a burst of events
const REFRESH_EVERY_MS = 60000;
const SCHEDULE_TASKS = ['system/schedule', 'system/unschedule', 'system/enable_schedule'];

let schedules = [];
let reread = null;       // the pending timer of loadSchedules, or null
let removing = '';       // the schedule the dialog removes
let readsBegun = 0;      // reads of the schedules begun, numbered from 1
let readShown = 0;       // the number of the read whose answer is shown

// A read's answer is shown unless a later read's already is: answers can come out of order.
export async function loadSchedules() {
  reread = null;
  const read = ++readsBegun;
  const answer = await api('/api/schedules');
  if (read < readShown) return;
  readShown = read;
  schedules = answer;
  renderSchedules();
}

export function refreshSchedules() {
  if (reread !== null) return;
  reread = setTimeout(() => { loadSchedules().catch((error) => console.debug('schedules:', error)); }, REREAD_MS);
}

// A schedule's run started or ended, or a schedule was changed (from any door).
export function onScheduleEvent(event) {
  const task = event.task;
  const run = task.source.startsWith('schedule:') && ['STARTED', 'ENDED'].includes(event.event);
  const change = SCHEDULE_TASKS.includes(task.task_name) && event.event === 'ENDED';
  if (run || change) refreshSchedules();
}

function whatCell(schedule) {
  const subtasks = schedule.task_data?.subtasks;
  if (schedule.task_name !== 'system/mission' || !Array.isArray(subtasks)) return element('td', { text: schedule.task_name });
  const names = subtasks.map((each) => each.task_name).join(' → ');
  return element('td', { text: `mission of ${plural(subtasks.length, 'step')}`, title: names });
}

function plural(count, noun) {
  return `${count} ${noun}${count === 1 ? '' : 's'}`;
}

// A cron schedule's times in its own zone ("2:00:00 AM Europe/Paris"), the others in the browser's.
function whenText(iso, schedule) {
  if (!schedule.cron || !schedule.time_zone) return localTime(iso);
  try {
    return `${new Date(iso).toLocaleString(undefined, { timeZone: schedule.time_zone })} ${schedule.time_zone}`;
  } catch {
    return localTime(iso);
  }
}

function nextRunCell(schedule) {
  if (!schedule.enabled) return element('td', { class: 'next-run', text: 'disabled' });
  if (!schedule.next_run) return element('td', { class: 'next-run', text: 'none to come' });
  return element('td', { class: 'next-run', title: schedule.next_run },
    whenText(schedule.next_run, schedule), ' ', element('span', { class: 'relative hint', 'data-at': schedule.next_run, text: fromNow(schedule.next_run) }));
}

function lastRunCell(schedule) {
  if (!schedule.last_run) return element('td', { class: 'last-run hint', text: 'not yet' });
  return element('td', { class: 'last-run', title: schedule.last_task_id },
    whenText(schedule.last_run, schedule), ' ', schedule.last_status ? statusBadge(schedule.last_status) : '');
}

function countsCell(schedule) {
  const skipped = schedule.skipped_count ? `, ${schedule.skipped_count} skipped` : '';
  return element('td', { class: 'counts', text: `${plural(schedule.run_count, 'run')}, ${schedule.missed_count} missed${skipped}` });
}

function buttonsCell(schedule) {
  return element('td', { class: 'actions' },
    element('button', {
      class: 'toggle', type: 'button', 'data-needs': 'admin', text: schedule.enabled ? 'Disable' : 'Enable',
      onclick: () => setEnabled(schedule.schedule_id, !schedule.enabled),
    }), ' ',
    element('button', {
      class: 'remove', type: 'button', 'data-needs': 'admin', text: 'Remove', onclick: () => askRemove(schedule.schedule_id),
    }));
}

function renderSchedules() {
  const rows = schedules.map((schedule) => element('tr', {
    'data-schedule-id': schedule.schedule_id, 'data-enabled': String(schedule.enabled), class: schedule.enabled ? '' : 'disabled',
  },
  element('td', { class: 'id', text: schedule.schedule_id }),
  whatCell(schedule),
  element('td', { text: schedule.description, title: `made by ${schedule.created_by}` }),
  nextRunCell(schedule),
  lastRunCell(schedule),
  countsCell(schedule),
  element('td', { class: 'enabled' }, element('span', { class: `badge ${schedule.enabled ? 'enabled' : 'disabled'}`, text: schedule.enabled ? 'enabled' : 'disabled' })),
  buttonsCell(schedule)));
  $('#schedules tbody').replaceChildren(...rows);
  $('#schedules-empty').hidden = rows.length > 0;
}

// The "in 4 min" beside each next run, moved on without reading the schedules again.
export function tickSchedules() {
  for (const span of document.querySelectorAll('#schedules .relative')) span.textContent = fromNow(span.dataset.at);
}

async function setEnabled(scheduleId, enabled) {
  try {
    await api(`/api/schedules/${idPath(scheduleId)}`, { method: 'PATCH', json: { enabled } });
    say(`Schedule ${scheduleId} ${enabled ? 'enabled' : 'disabled'}`);
  } catch (error) {
    say(`Could not ${enabled ? 'enable' : 'disable'} ${scheduleId}: ${error.message}`, true);
  }
  await loadSchedules().catch((error) => console.debug('schedules:', error));
}

function askRemove(scheduleId) {
  removing = scheduleId;
  $('#remove-schedule-id').textContent = scheduleId;
  $('#remove-dialog').showModal();
}

async function removeSchedule(event) {
  event.preventDefault();
  const scheduleId = removing;
  $('#remove-dialog').close();
  try {
    await api(`/api/schedules/${idPath(scheduleId)}`, { method: 'DELETE' });
    say(`Schedule ${scheduleId} removed`);
  } catch (error) {
    say(`Could not remove ${scheduleId}: ${error.message}`, true);
  }
  await loadSchedules().catch((error) => console.debug('schedules:', error));
}

export function wireSchedules() {
  $('#remove-form').addEventListener('submit', removeSchedule);
  $('#remove-keep').addEventListener('click', () => $('#remove-dialog').close());
  setInterval(refreshSchedules, REFRESH_EVERY_MS);
}
