"""Who may come in, and how: the token file and roles (`tokens.py`), the role of each system
task and what a start starts in turn (`task_roles.py`), each route's role (`access.py`), and the
middlewares every request passes (`front_door.py`, `read_bound.py`, `body_door.py`). Shared
with the fleet console (no rclpy here)."""
