"""Benchmarks of the fleet console (`python -m bench --only console`): 200 simulated robots
against `task-manager-console` as users start it."""
