"""setuptools entry point; the metadata lives in pyproject.toml (but python_requires)."""

from setuptools import setup

setup(
    # Here, not in pyproject.toml, as the other packages do (colcon reads it as a plain string).
    python_requires='>=3.11',
)
