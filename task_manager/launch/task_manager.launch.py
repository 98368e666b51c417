"""Launch the Task Manager with a parameters file (needs a full ROS 2 install)."""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    default_params = PathJoinSubstitution(
        [FindPackageShare('task_manager'), 'params', 'task_manager_defaults.yaml']
    )
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'params_file',
                default_value=default_params,
                description='Parameters file declaring the tasks',
            ),
            Node(
                package='task_manager',
                executable='task-manager',
                name='task_manager',
                output='screen',
                parameters=[LaunchConfiguration('params_file')],
            ),
        ]
    )
