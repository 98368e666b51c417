// What the page knows of the fleet, shared by its modules.

export const state = {
  robots: new Map(),   // robot id -> the robot's document (GET /api/robots, `robot` events)
  streamOpen: false,
};

// A robot's active tasks QUEUED (its queue length).
export function queueLength(robot) {
  return (robot.active || []).filter((task) => task.status === 'QUEUED').length;
}

export function sortedRobots() {
  return [...state.robots.values()].sort((a, b) => (a.robot_id < b.robot_id ? -1 : 1));
}
