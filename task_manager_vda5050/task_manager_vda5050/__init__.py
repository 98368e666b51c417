"""VDA 5050 adapter of the Task Manager: a standard master control drives the robot's tasks."""
