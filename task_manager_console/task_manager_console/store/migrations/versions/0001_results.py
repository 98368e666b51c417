"""The results table, with its exactly-once key (robot_id, sequence).

Revision ID: 0001
Revises:
"""

import sqlalchemy as sa
from alembic import op

revision = '0001'
down_revision = None
branch_labels = None
depends_on = None

ID = sa.BigInteger().with_variant(sa.Integer, 'sqlite')
TEXT = 256


def upgrade() -> None:
    op.create_table(
        'results',
        sa.Column('id', ID, nullable=False),
        sa.Column('robot_id', sa.String(TEXT), nullable=False),
        sa.Column('sequence', sa.BigInteger, nullable=False),
        sa.Column('task_id', sa.String(TEXT), nullable=False),
        sa.Column('task_name', sa.String(TEXT), nullable=False),
        sa.Column('source', sa.String(TEXT), nullable=False),
        sa.Column('status', sa.String(32), nullable=False),
        sa.Column('error_code', sa.String(64), nullable=False),
        sa.Column('received', sa.DateTime, nullable=True),
        sa.Column('started', sa.DateTime, nullable=True),
        sa.Column('ended', sa.DateTime, nullable=False),
        sa.Column('result', sa.JSON, nullable=True),
        sa.Column('parent_id', sa.String(TEXT), nullable=False),
        sa.Column('details', sa.JSON, nullable=False),
        sa.Column('stored_at', sa.DateTime, nullable=False),
        sa.PrimaryKeyConstraint('id', name='pk_results'),
        sa.UniqueConstraint('robot_id', 'sequence', name='uq_results_robot_id_sequence'),
    )


def downgrade() -> None:
    op.drop_table('results')
