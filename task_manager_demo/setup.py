"""colcon (ament_python) entry point; the metadata lives in pyproject.toml."""

from setuptools import setup

PACKAGE = 'task_manager_demo'

setup(
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/params', ['params/demo_tasks.yaml']),
    ],
)
