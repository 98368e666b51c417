"""Running requests: the dispatcher (admission, conflicts, start, cancel, end), each task's run
state, the runners of action and service tasks, the watch on their servers, and the schedules'
timer."""
