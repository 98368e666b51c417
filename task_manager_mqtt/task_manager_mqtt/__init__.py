"""MQTT bridge of the ROS 2 Task Manager, and the cloud side of it (FleetClient)."""


def run() -> object:
    """Console script `task-manager-mqtt`, prepared before rclpy loads (process_setup)."""
    from task_manager.process_setup import run_program

    return run_program('task_manager_mqtt.main')
