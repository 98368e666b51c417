"""What the gateways share (the web gateway, the MQTT bridge, the VDA 5050 adapter).

A gateway reaches the node only through the client (`task_manager.client`), speaks the JSON protocol
(`task_manager.protocol`) and may import, besides those two: this package, core's values
(`task_manager.core`: bounds, names, statuses, errors, request text, door sources) and
`task_manager.process_setup` (what a ROS 2 process of ours sets up first) and
`task_manager.cpu_priority` (a gateway's nice value). Never `task_manager.ros`,
not even through another module, nor the modules the client and the node keep to themselves
(`rclpy_tools`, `messages`): the contracts of `.importlinter` say so.

- `documents`: the client's records as protocol documents (what every gateway sends).
- `requests`: a request document as client calls, the same for every door.
- `secret_file`: whether a file that holds a secret is readable by others.
"""
