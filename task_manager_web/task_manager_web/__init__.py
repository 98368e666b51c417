"""Web gateway of the ROS 2 Task Manager: a REST API, live events and a dashboard."""
