"""The thin ROS 2 layer around the core: the node, task runners, message conversion."""
