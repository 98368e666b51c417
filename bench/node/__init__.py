"""Benchmarks of the node alone: dispatch, admission, history, memory, startup and more."""
