"""Recording and announcing what happens: history writes, task events, log lines, active tasks
and the once-per-turn publications."""
