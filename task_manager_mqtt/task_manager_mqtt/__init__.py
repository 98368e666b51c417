"""MQTT bridge of the ROS 2 Task Manager, and the cloud side of it (FleetClient)."""
