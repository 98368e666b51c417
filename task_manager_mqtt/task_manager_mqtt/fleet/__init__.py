"""Parts of the FleetClient (`task_manager_mqtt.fleet_client`): `receiving.py`, what robots send,
read and handed on."""
