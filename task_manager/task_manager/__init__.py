"""ROS 2 Task Manager: start, track and end every task of a robot in one place."""
