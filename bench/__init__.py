"""Benchmarks of the Task Manager node against direct calls to the same servers (`make bench`)."""
