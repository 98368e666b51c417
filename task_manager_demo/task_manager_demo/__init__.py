"""A simulated robot and a launcher that show the Task Manager at work."""


def run_robot() -> object:
    """Console script `task-manager-demo-robot`, prepared before rclpy loads (process_setup)."""
    from task_manager.process_setup import block_stop_signals, run_program

    block_stop_signals()  # before rclpy is imported: every thread it starts inherits the mask
    return run_program('task_manager_demo.sim_robot')
