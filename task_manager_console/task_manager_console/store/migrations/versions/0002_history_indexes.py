"""The indexes of the history's queries: newest first, by robot, task, name, status, source.

Revision ID: 0002
Revises: 0001
"""

from alembic import op

revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None

INDEXES = {
    'ix_results_ended_id': ['ended', 'id'],
    'ix_results_robot_id_ended': ['robot_id', 'ended'],
    'ix_results_task_id': ['task_id'],
    'ix_results_task_name_ended': ['task_name', 'ended'],
    'ix_results_status_ended': ['status', 'ended'],
    'ix_results_source_ended': ['source', 'ended'],
}


def upgrade() -> None:
    for name, columns in INDEXES.items():
        op.create_index(name, 'results', columns)


def downgrade() -> None:
    for name in INDEXES:
        op.drop_index(name, 'results')
