// The durable history: the history table of the robot's tasks (history_table.js), a row added
// live as each task ends.

import { STATUS_FILTER, historyTable } from './history_table.js';
import { statusCell } from './tasks.js';

export const { loadHistory, addHistoryRow, wireHistory } = historyTable({
  filters: [{ name: 'task_name', label: 'Task', list: 'task-names' }, STATUS_FILTER, { name: 'source', label: 'Source' }],
  sinceParameter: 'since',
  keyOf: (task) => task.task_id,
  statusCell: (task) => statusCell(task, task.status),
  csvName: 'task_history.csv',
});
