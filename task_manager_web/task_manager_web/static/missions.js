// Missions as rows of steps (done, running, paused, skipped, failed, pending), the latest few,
// each with its pause or resume button while it runs.

import { $, element, statusBadge } from './dom.js';
import { state } from './state.js';
import { pauseButton } from './tasks.js';

const MISSIONS_KEPT = 5;

export function rememberMission(task) {
  state.missions.set(task.task_id, task);
  const ids = [...state.missions.keys()];
  for (const id of ids.slice(0, Math.max(0, ids.length - MISSIONS_KEPT))) state.missions.delete(id);
  renderMissions();
}

// A step's state: the mission's feedback, or the step's own events when newer (a step paused
// with its mission changes no feedback of the mission).
function stepClass(subtask) {
  if (subtask.skipped) return 'skipped';
  const own = state.tasks.get(subtask.task_id);
  const status = own && !own.endedAt && subtask.task_status === 'IN_PROGRESS' ? own.status : subtask.task_status;
  return {
    DONE: 'done', IN_PROGRESS: 'running', PAUSED: 'paused', ERROR: 'failed', CANCELED: 'canceled',
  }[status] || 'pending';
}

// A mission's document as the events leave it; ended, it is no longer active.
function shownMission(mission) {
  const active = state.tasks.get(mission.task_id);
  return active && !active.endedAt ? mission : { ...mission, endedAt: true };
}

export function renderMissions() {
  const missions = [...state.missions.values()].reverse().map((mission) => {
    const subtasks = mission.feedback?.subtasks || [];
    const steps = subtasks.map((subtask, index) => {
      const kind = stepClass(subtask);
      return element('div', {
        class: `step ${kind}`, 'data-step': String(index), 'data-state': kind, title: subtask.task_id,
      }, element('span', { class: 'name', text: subtask.task_name }), element('span', { text: kind }));
    });
    return element('div', { class: 'mission', 'data-mission-id': mission.task_id },
      element('div', { class: 'mission-title' },
        element('span', { text: `Mission ${mission.task_id.slice(0, 8)}` }),
        statusBadge(mission.status),
        element('span', { class: 'hint', text: `from ${mission.source}` }),
        pauseButton(shownMission(mission))),
      element('div', { class: 'steps' }, ...steps));
  });
  $('#missions').replaceChildren(...missions);
  $('#missions-empty').hidden = missions.length > 0;
}
