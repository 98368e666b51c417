"""Parts of the FleetClient (`task_manager_mqtt.fleet_client`): `receiving.py`, what robots
send, read and handed on; `publishing.py`, requests sent and the broker's answer to each;
`transport.py`, paho's client on a socket that reads ahead and writes in one go."""
