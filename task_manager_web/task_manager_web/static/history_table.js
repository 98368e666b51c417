// A table of ended tasks: its filters (built into the form #history-filters), the rows read with
// them, rows added live as tasks end, and the CSV export. Shared by the robot dashboard
// (history.js) and the fleet console's page, which loads it from /web-static/.

import { api } from './api.js';
import { $, compactJson, element, formatSeconds, say, statusBadge } from './dom.js';

const HISTORY_ROWS = 100;
const SINCE_CHOICES = [['3600', '1 hour'], ['86400', '24 hours'], ['604800', '7 days'], ['', 'any time']];
const SINCE_DEFAULT = '86400';
export const STATUS_FILTER = { name: 'status', label: 'Status', choices: ['DONE', 'ERROR', 'CANCELED'] };

function filterControl({ name, label, list, choices }) {
  if (choices) {
    const options = ['', ...choices].map((choice) => element('option', { value: choice, text: choice || 'any' }));
    return [element('label', { text: `${label} ` }, element('select', { name }, ...options))];
  }
  const input = element('input', { name, placeholder: 'any', ...(list ? { list } : {}) });
  const control = element('label', { text: `${label} ` }, input);
  return list && !document.getElementById(list) ? [control, element('datalist', { id: list })] : [control];
}

function sinceControl() {
  const options = SINCE_CHOICES.map(([value, text]) => {
    const option = element('option', { value, text });
    option.selected = value === SINCE_DEFAULT;
    return option;
  });
  return element('label', { text: 'Ended within ' }, element('select', { name: 'since' }, ...options));
}

// options:
//   filters: the form's filters, each {name, label, list (a datalist's id), choices}, sent as
//     the query's parameters of their names and matched against a live row's fields;
//   sinceParameter: the query's parameter of the earliest end (the form's "Ended within");
//   keyOf(entry): what tells one stored end (a row's document) from another: an entry already
//     shown is not shown again (a live row may come after a read that already held it, or twice);
//   attributes(entry): the row's attributes besides data-key and data-task-id (none by default);
//   leadingCells(entry): the cells before the task's own (none by default);
//   statusCell(entry): the status's cell (its badge by default);
//   csvName: the export's file name.
export function historyTable(options) {
  const names = options.filters.map((filter) => filter.name);
  const attributes = options.attributes || (() => ({}));
  const leadingCells = options.leadingCells || (() => []);
  const statusCell = options.statusCell || ((entry) => element('td', { class: 'status' }, statusBadge(entry.status)));

  function historyQuery(extra = {}) {
    const form = new FormData($('#history-filters'));
    const query = new URLSearchParams({ limit: String(HISTORY_ROWS), ...extra });
    for (const name of names) if (form.get(name)) query.set(name, form.get(name));
    const since = form.get('since');
    if (since) query.set(options.sinceParameter, new Date(Date.now() - Number(since) * 1000).toISOString());
    return query;
  }

  function historyRow(entry) {
    return element('tr', { 'data-key': options.keyOf(entry), ...attributes(entry), 'data-task-id': entry.task_id },
      ...leadingCells(entry),
      element('td', { text: entry.sequence ? String(entry.sequence) : '' }),
      element('td', { text: entry.task_name }),
      element('td', { class: 'id', text: entry.task_id }),
      element('td', { text: entry.source }),
      statusCell(entry),
      element('td', { text: entry.ended ? new Date(entry.ended).toLocaleString() : '' }),
      element('td', { text: entry.duration_sec == null ? '' : formatSeconds(entry.duration_sec) }),
      element('td', { class: 'result', text: entry.error_message || compactJson(entry.result ?? {}), title: JSON.stringify(entry.result ?? {}) }));
  }

  function showEmpty() {
    const empty = $('#history-empty');
    if (empty) empty.hidden = $('#history tbody').children.length > 0;
  }

  // One list per read in flight: the rows that came while it was read, which its answer may
  // not hold yet; they are put back on top once it has replaced the rows.
  const cameDuringReads = new Set();

  async function loadHistory() {
    const cameMeanwhile = [];
    cameDuringReads.add(cameMeanwhile);
    try {
      const entries = await api(`/api/history?${historyQuery()}`);
      const read = new Set(entries.map(options.keyOf));
      $('#history tbody').replaceChildren(...entries.map(historyRow));
      for (const entry of cameMeanwhile) if (!read.has(options.keyOf(entry))) showRow(entry);
      showEmpty();
    } finally {
      cameDuringReads.delete(cameMeanwhile);
    }
  }

  function matchesFilters(entry) {
    const form = new FormData($('#history-filters'));
    return names.every((name) => !form.get(name) || form.get(name) === entry[name]);
  }

  // A task ended (or a result stored): on top, if the filters take it.
  function addHistoryRow(entry) {
    if (!matchesFilters(entry)) return;
    for (const cameMeanwhile of cameDuringReads) cameMeanwhile.push(entry);
    showRow(entry);
  }

  function showRow(entry) {
    const body = $('#history tbody');
    const key = options.keyOf(entry);
    if ([...body.children].some((row) => row.dataset.key === key)) return;
    body.prepend(historyRow(entry));
    while (body.children.length > HISTORY_ROWS) body.lastElementChild.remove();
    showEmpty();
  }

  async function exportCsv() {
    try {
      const response = await api(`/api/history?${historyQuery({ limit: '10000', format: 'csv' })}`, { raw: true });
      const link = element('a', { href: URL.createObjectURL(await response.blob()), download: options.csvName });
      link.click();
      URL.revokeObjectURL(link.href);
    } catch (error) {
      say(`Export failed: ${error.message}`, true);
    }
  }

  function wireHistory() {
    const form = $('#history-filters');
    form.replaceChildren(
      ...options.filters.flatMap(filterControl),
      sinceControl(),
      element('button', { type: 'submit', text: 'Apply' }),
      element('button', { type: 'button', id: 'export-csv', text: 'Export CSV' }));
    form.addEventListener('submit', (event) => { event.preventDefault(); loadHistory().catch((error) => say(error.message, true)); });
    $('#export-csv').addEventListener('click', exportCsv);
  }

  return { loadHistory, addHistoryRow, wireHistory };
}
