"""`taskctl`: the Task Manager from the command line."""
