"""The history's filter indexes end with the query's whole order (ended, id): a filter's newest
results come straight from its index, whatever the planner guesses of how they are spread.

With (task_name, ended), PostgreSQL ordering by ended and id took the (ended, id) index and
filtered it, guessing a third of the rows near the top would match: when the newest 57,000
results were of another task, it read them all first (77 ms, not 0.2).

Revision ID: 0003
Revises: 0002
"""

from alembic import op

revision = '0003'
down_revision = '0002'
branch_labels = None
depends_on = None

FILTERS = ('robot_id', 'task_name', 'status', 'source')


def upgrade() -> None:
    for column in FILTERS:
        op.drop_index(f'ix_results_{column}_ended', 'results')
        op.create_index(f'ix_results_{column}_ended_id', 'results', [column, 'ended', 'id'])


def downgrade() -> None:
    for column in FILTERS:
        op.drop_index(f'ix_results_{column}_ended_id', 'results')
        op.create_index(f'ix_results_{column}_ended', 'results', [column, 'ended'])
