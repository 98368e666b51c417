"""Helpers for tests of the Task Manager and of systems built on it."""
