// The durable history: filters, rows added live as tasks end, and the CSV export.

import { api } from './api.js';
import { $, compactJson, element, formatSeconds, say } from './dom.js';
import { statusCell } from './tasks.js';

const HISTORY_ROWS = 100;

function historyQuery(extra = {}) {
  const form = new FormData($('#history-filters'));
  const query = new URLSearchParams({ limit: String(HISTORY_ROWS), ...extra });
  for (const name of ['task_name', 'status', 'source']) if (form.get(name)) query.set(name, form.get(name));
  const since = form.get('since');
  if (since) query.set('since', new Date(Date.now() - Number(since) * 1000).toISOString());
  return query;
}

// One list per read in flight: the tasks that ended while it was read, which its answer may
// not hold yet; they are put back on top once it has replaced the rows.
const endedDuringReads = new Set();

export async function loadHistory() {
  const endedMeanwhile = [];
  endedDuringReads.add(endedMeanwhile);
  try {
    const tasks = await api(`/api/history?${historyQuery()}`);
    const read = new Set(tasks.map((task) => task.task_id));
    $('#history tbody').replaceChildren(...tasks.map((task) => historyRow(task)));
    for (const task of endedMeanwhile) if (!read.has(task.task_id)) showRow(task);
  } finally {
    endedDuringReads.delete(endedMeanwhile);
  }
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

export function addHistoryRow(task) {
  if (!matchesFilters(task)) return;
  for (const endedMeanwhile of endedDuringReads) endedMeanwhile.push(task);
  showRow(task);
}

function showRow(task) {
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

export function wireHistory() {
  $('#history-filters').addEventListener('submit', (event) => { event.preventDefault(); loadHistory().catch((error) => say(error.message, true)); });
  $('#export-csv').addEventListener('click', exportCsv);
}
