"""Alembic's environment of the fleet history: run on the connection FleetHistory gives it."""

from alembic import context

from task_manager_console.store.schema import metadata

if context.is_offline_mode():
    raise RuntimeError('the fleet history migrates a live database only (no --sql)')
context.configure(
    connection=context.config.attributes['connection'],
    target_metadata=metadata,
    render_as_batch=True,  # SQLite alters a table by copying it
)
with context.begin_transaction():
    context.run_migrations()
