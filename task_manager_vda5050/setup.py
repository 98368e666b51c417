"""colcon (ament_python) entry point; the metadata lives in pyproject.toml (but python_requires)."""

from setuptools import setup

PACKAGE = 'task_manager_vda5050'

setup(
    # Here, not in pyproject.toml, so that colcon reads it as a plain string.
    python_requires='>=3.11',
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
    ],
)
