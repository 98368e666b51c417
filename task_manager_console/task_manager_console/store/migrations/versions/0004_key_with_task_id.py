"""The exactly-once key is the robot, its sequence and the task id: a robot whose history began
again (a new history file: reinstalled, or its history moved) numbers its results from 1 again,
with other tasks, and those are new results, where the key of robot and sequence took them for
results delivered again and stored none of them.

Revision ID: 0004
Revises: 0003
"""

from alembic import op

revision = '0004'
down_revision = '0003'
branch_labels = None
depends_on = None

OLD_KEY = ('robot_id', 'sequence')
NEW_KEY = ('robot_id', 'sequence', 'task_id')


def upgrade() -> None:
    with op.batch_alter_table('results') as table:  # SQLite: the table copied
        table.drop_constraint(f'uq_results_{"_".join(OLD_KEY)}', type_='unique')
        table.create_unique_constraint(f'uq_results_{"_".join(NEW_KEY)}', list(NEW_KEY))


def downgrade() -> None:
    with op.batch_alter_table('results') as table:
        table.drop_constraint(f'uq_results_{"_".join(NEW_KEY)}', type_='unique')
        table.create_unique_constraint(f'uq_results_{"_".join(OLD_KEY)}', list(OLD_KEY))
