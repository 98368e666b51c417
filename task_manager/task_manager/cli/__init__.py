"""`taskctl`: the Task Manager from the command line."""


def run() -> object:
    """Console script `taskctl`, prepared before rclpy loads (process_setup)."""
    from task_manager.process_setup import run_program

    return run_program('task_manager.cli.main')
