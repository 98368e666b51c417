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

export async function loadHistory() {
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

export function addHistoryRow(task) {
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

export function wireHistory() {
  $('#history-filters').addEventListener('submit', (event) => { event.preventDefault(); loadHistory().catch((error) => say(error.message, true)); });
  $('#export-csv').addEventListener('click', exportCsv);
}
