// The fleet history: filters, rows added live as results are stored, and the CSV export.

import { api } from '/web-static/api.js';
import { $, compactJson, element, formatSeconds, say, statusBadge } from '/web-static/dom.js';

const HISTORY_ROWS = 100;
const FILTERS = ['robot_id', 'task_name', 'status', 'source'];

function historyQuery(extra = {}) {
  const form = new FormData($('#history-filters'));
  const query = new URLSearchParams({ limit: String(HISTORY_ROWS), ...extra });
  for (const name of FILTERS) if (form.get(name)) query.set(name, form.get(name));
  const since = form.get('since');
  if (since) query.set('ended_after', new Date(Date.now() - Number(since) * 1000).toISOString());
  return query;
}

function keyOf(result) {
  return `${result.robot_id}\n${result.sequence}`;
}

function historyRow(result) {
  return element('tr', { 'data-key': keyOf(result), 'data-robot-id': result.robot_id, 'data-task-id': result.task_id },
    element('td', { text: result.robot_id }),
    element('td', { text: result.sequence ? String(result.sequence) : '' }),
    element('td', { text: result.task_name }),
    element('td', { class: 'id', text: result.task_id }),
    element('td', { text: result.source }),
    element('td', { class: 'status' }, statusBadge(result.status)),
    element('td', { text: result.ended ? new Date(result.ended).toLocaleString() : '' }),
    element('td', { text: result.duration_sec == null ? '' : formatSeconds(result.duration_sec) }),
    element('td', { class: 'result', text: result.error_message || compactJson(result.result ?? {}), title: JSON.stringify(result.result ?? {}) }));
}

function showEmpty() {
  $('#history-empty').hidden = $('#history tbody').children.length > 0;
}

// Results stored while a read is in flight, which its answer may not hold: put back on top.
const storedDuringReads = new Set();

export async function loadHistory() {
  const storedMeanwhile = [];
  storedDuringReads.add(storedMeanwhile);
  try {
    const results = await api(`/api/history?${historyQuery()}`);
    const read = new Set(results.map(keyOf));
    $('#history tbody').replaceChildren(...results.map(historyRow));
    for (const result of storedMeanwhile) if (!read.has(keyOf(result))) showRow(result);
    showEmpty();
  } finally {
    storedDuringReads.delete(storedMeanwhile);
  }
}

function matchesFilters(result) {
  const form = new FormData($('#history-filters'));
  return FILTERS.every((name) => !form.get(name) || form.get(name) === result[name]);
}

// A result stored (a `result` event): on top, if the filters take it.
export function addHistoryRow(result) {
  if (!matchesFilters(result)) return;
  for (const storedMeanwhile of storedDuringReads) storedMeanwhile.push(result);
  showRow(result);
}

function showRow(result) {
  const body = $('#history tbody');
  if ([...body.children].some((row) => row.dataset.key === keyOf(result))) return;
  body.prepend(historyRow(result));
  while (body.children.length > HISTORY_ROWS) body.lastElementChild.remove();
  showEmpty();
}

async function exportCsv() {
  try {
    const response = await api(`/api/history?${historyQuery({ limit: '10000', format: 'csv' })}`, { raw: true });
    const link = element('a', { href: URL.createObjectURL(await response.blob()), download: 'fleet_history.csv' });
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
