"""VDA 5050 adapter of the Task Manager: a standard master control drives the robot's tasks."""


def run() -> object:
    """Console script `task-manager-vda5050`, prepared before rclpy loads (process_setup)."""
    from task_manager.process_setup import run_program

    return run_program('task_manager_vda5050.main')
