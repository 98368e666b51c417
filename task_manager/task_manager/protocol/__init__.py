"""The JSON protocol of every non-ROS source (the web gateway, the MQTT bridge).

Defined once, as pydantic models in `models`; `schema/*.schema.json` are their JSON Schema
documents, written by `python -m task_manager.protocol` (a test checks they are current),
for clients in other languages. `records` turns the client's records into this JSON.
It loads neither rclpy nor a web or MQTT stack.
"""
