"""every model's category (its kind: car, lamp_post, hydrant...), source (a CAD mesh or a scanned object) and level
of symmetry

Revision ID: 0005_category
Revises: 0004_profile
Create Date: 2026-12-03 12:30:00
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0005_category'
down_revision: Union[str, None] = '0004_profile'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    # SQLite's DDL is not undone when a migration fails half-way (pysqlite commits it): a catalogue left with
    # some of these columns by an interrupted upgrade is completed, not refused
    conn = op.get_bind()
    inspector = sa.inspect(conn)
    have = {c["name"] for c in inspector.get_columns('ref_models')}
    indexes = {i["name"] for i in inspector.get_indexes('ref_models')}
    with op.batch_alter_table('ref_models', schema=None) as batch_op:
        if 'category' not in have:
            batch_op.add_column(sa.Column('category', sa.String(length=40), nullable=False, server_default='car'))
        if 'source' not in have:
            batch_op.add_column(sa.Column('source', sa.String(length=10), nullable=False, server_default='mesh'))
        if 'sym_level' not in have:
            batch_op.add_column(sa.Column('sym_level', sa.String(length=20), nullable=True))
        if 'ix_ref_models_category' not in indexes:
            batch_op.create_index(batch_op.f('ix_ref_models_category'), ['category'], unique=False)
    # every model so far is a car from a mesh; its level of symmetry is measured from the surface points it holds
    # by the catalogue's upgrade, in this upgrade's transaction (twinreg.catalogue.db.fill_levels): a migration
    # changes the schema only and never runs the method's live code (it must not change when the code does)


def downgrade() -> None:
    with op.batch_alter_table('ref_models', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_ref_models_category'))
        batch_op.drop_column('sym_level')
        batch_op.drop_column('source')
        batch_op.drop_column('category')
