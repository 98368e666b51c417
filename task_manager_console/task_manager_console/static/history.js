// The fleet history: the robot dashboard's history table (/web-static/history_table.js) of every
// robot's results, each row led by its robot, a row added live as a result is stored.

import { element } from '/web-static/dom.js';
import { STATUS_FILTER, historyTable } from '/web-static/history_table.js';

export const { loadHistory, addHistoryRow, wireHistory } = historyTable({
  filters: [
    { name: 'robot_id', label: 'Robot', list: 'robot-ids' },
    { name: 'task_name', label: 'Task', list: 'declared-tasks' },
    STATUS_FILTER,
    { name: 'source', label: 'Source' },
  ],
  sinceParameter: 'ended_after',
  keyOf: (result) => `${result.robot_id}\n${result.sequence}`,
  attributes: (result) => ({ 'data-robot-id': result.robot_id }),
  leadingCells: (result) => [element('td', { text: result.robot_id })],
  csvName: 'fleet_history.csv',
});
