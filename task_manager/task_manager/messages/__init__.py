"""Every conversion between ROS messages and Python or JSON, in one package without rclpy.

`json_codec` turns JSON task data into any message class and back by the class's own
introspection; `goal_schema` states its rules as the JSON Schema of a goal or request;
`task_messages` builds the Task Manager's own messages from its records.
"""
