"""Fleet console of the ROS 2 Task Manager: every robot on an MQTT broker, a fleet history in a
database (SQLite or PostgreSQL), REST, live events and a page. Cloud-side: no rclpy."""
