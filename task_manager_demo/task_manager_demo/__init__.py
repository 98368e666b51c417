"""A simulated robot and a launcher that show the Task Manager at work."""


def run_robot() -> object:
    """Console script `task-manager-demo-robot`, prepared before rclpy loads (process_setup)."""
    from task_manager.process_setup import run_program

    return run_program('task_manager_demo.sim_robot')
