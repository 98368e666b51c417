// What the page knows, shared by its modules.

export const state = {
  tasks: new Map(),      // task id -> Task document (active, or ended moments ago)
  missions: new Map(),   // mission id -> Task document of the mission
  declared: [],          // DeclaredTask documents (GET /api/tasks)
  nodeConnected: false,
  streamOpen: false,
};

export function isLive() {
  return state.streamOpen && state.nodeConnected;
}

// Pause and resume buttons for a task that can pause (a mission; a task declared
// `pause: restart`) and is no mission's step (its mission is paused instead).
export function canPause(task) {
  if (task.endedAt || task.mission_id) return false;
  const declared = state.declared.find((each) => each.task_name === task.task_name);
  return Boolean(declared && declared.pause && declared.pause !== 'none');
}
