"""Simulated robots for the console's tests and benchmarks: each speaks its bridge's MQTT
protocol (docs/fleet-mqtt.md) without ROS, and hundreds of them share one thread.

`robot.py`: a SimulatedRobot publishes what a robot's bridge publishes (`documents.py`: made
from the protocol's models): its `connection` (and the bridge's last will, CONNECTIONBROKEN),
its declared `tasks` and its `active_tasks` (retained, QoS 1) and its `result`s (QoS 1, in
sequence order), on an account of its own, as a bridge has (the broker ties a client id to its
account: one account, one connection).

`robot_loop.py`: every robot of a process runs on one RobotLoop, one thread that drives all
their MQTT connections (paho's external loop over a selector): 200 robots cost one thread.
"""
