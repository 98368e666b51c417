"""Where the simulated robot serves, and the log line that says it is ready.

Kept free of ROS imports: the launcher and tests read it without loading rclpy. (Not in
`__init__.py`: run from the repository root, `task_manager_demo/` shadows the package as a
namespace package, whose `__init__` never runs; submodules still import.)
"""

NAVIGATE_ACTION = '/navigate_to_pose'
SPIN_ACTION = '/spin'
DOCK_ACTION = '/dock'
TAKE_PHOTO_SERVICE = '/take_photo'
UPLOAD_PHOTOS_SERVICE = '/upload_photos'
ROBOT_READY_LOG = 'Simulated robot ready'
