// The fleet console's page: plain JavaScript modules, no build step, nothing from outside the
// console. It shares the robot dashboard's helpers and look (/web-static/: the token, requests,
// elements, the event stream, the history table, the style sheet). Live state comes from /api/events: its `hello` gives every robot
// on each (re)connection, then `robot` and `result` events; the history is read again then.

import { api, loadRole, wireToken } from '/web-static/api.js';
import { $, element, say } from '/web-static/dom.js';
import { followEvents } from '/web-static/events.js';
import { renderConfirmations, tickConfirmations } from './confirmations.js';
import { addHistoryRow, loadHistory, wireHistory } from './history.js';
import { renderRobots, robotsRunning } from './robots.js';
import { renderStartChoices, wireStartForm } from './start_form.js';
import { state } from './state.js';

function showConnection(databaseUp = true) {
  const badge = $('#connection');
  const banner = $('#banner');
  badge.className = `badge ${state.streamOpen ? 'connected' : 'unreachable'}`;
  badge.textContent = state.streamOpen ? 'connected' : 'console not reachable';
  if (!state.streamOpen) banner.textContent = 'The console is not reachable: retrying. The robots shown are stale.';
  else if (!databaseUp) banner.textContent = 'The fleet history database is not reachable: results wait with the broker until it is back.';
  banner.hidden = state.streamOpen && databaseUp;
}

// Robots changed since the page last showed them (null: every robot), shown at most every
// RENDER_MS: a busy fleet's events are drawn in batches.
const RENDER_MS = 100;
let changed = new Set();
let renderDue = false;

function renderFleet() {
  renderDue = false;
  renderRobots(changed);
  changed = new Set();
  renderConfirmations();
  renderStartChoices();
}

function robotChanged(robotId) {
  if (changed && robotId !== null) changed.add(robotId);
  else changed = null;
  if (!renderDue) {
    renderDue = true;
    setTimeout(renderFleet, RENDER_MS);
  }
}

function onHello(hello) {
  state.robots = new Map(hello.robots.map((robot) => [robot.robot_id, robot]));
  showConnection(hello.database_up);
  robotChanged(null);
  loadHistory().catch((error) => say(`Could not read the fleet history: ${error.message}`, true));
}

function onRobot(robot) {
  state.robots.set(robot.robot_id, robot);
  robotChanged(robot.robot_id);
}

function answerChip(answer) {
  const text = answer.ok
    ? `${answer.robot_id}: ${answer.task?.status || 'stopped'}`
    : `${answer.robot_id}: ${answer.error?.code || 'refused'}${answer.error?.message ? ` (${answer.error.message})` : ''}`;
  return element('span', { class: `stop-answer${answer.ok ? '' : ' refused'}`, 'data-robot-id': answer.robot_id, 'data-ok': String(answer.ok), text });
}

async function stopAll() {
  const button = $('#stop-all');
  button.disabled = true;
  try {
    const result = await api('/api/fleet/stop', { method: 'POST' });
    const stopped = result.answers.filter((answer) => answer.ok).length;
    say(`STOP ALL: ${stopped} of ${result.answers.length} robots stopped`, stopped < result.answers.length);
    $('#stop-answers').replaceChildren(...result.answers.map(answerChip));
    $('#stop-answers').hidden = result.answers.length === 0;
  } catch (error) {
    say(`STOP ALL failed: ${error.message}`, true);
  } finally {
    button.disabled = false;
  }
}

function main() {
  wireToken();
  $('#stop-all').addEventListener('click', stopAll);
  wireStartForm();
  wireHistory();
  setInterval(() => { tickConfirmations(); renderRobots(robotsRunning()); }, 1000);
  showConnection();
  loadRole();
  followEvents({
    opened: () => { state.streamOpen = true; },
    closed: () => { state.streamOpen = false; showConnection(); },
    hello: onHello,
    robot: onRobot,
    result: addHistoryRow,
  });
}

main();
