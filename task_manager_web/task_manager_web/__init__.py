"""Web gateway of the ROS 2 Task Manager: a REST API, live events and a dashboard."""


def run() -> object:
    """Console script `task-manager-web`, prepared before rclpy loads (process_setup)."""
    from task_manager.process_setup import run_program

    return run_program('task_manager_web.main')
