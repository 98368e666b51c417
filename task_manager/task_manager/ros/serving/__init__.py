"""Serving the node's action: ExecuteTask through the action's own services, goals bound to
their tasks, and the optional per-task servers."""
