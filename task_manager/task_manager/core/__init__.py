"""The Task Manager's logic, free of ROS: task model, registry, conflicts, missions."""
