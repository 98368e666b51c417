// The durable history: the history table of the robot's tasks (history_table.js), a row added
// live as each task ends.

import { STATUS_FILTER, historyTable } from './history_table.js';
import { statusCell } from './tasks.js';

export const { loadHistory, addHistoryRow, wireHistory } = historyTable({
  filters: [{ name: 'task_name', label: 'Task', list: 'task-names' }, STATUS_FILTER, { name: 'source', label: 'Source' }],
  sinceParameter: 'since',
  // a task id may be used again once its task ended: its number in the history tells the ends apart
  keyOf: (task) => `${task.task_id}\n${task.sequence}`,
  statusCell: (task) => statusCell(task, task.status),
  csvName: 'task_history.csv',
});
