"""A simulated robot and a launcher that show the Task Manager at work."""
