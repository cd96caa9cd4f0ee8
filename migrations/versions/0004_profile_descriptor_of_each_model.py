"""the cheap descriptor of each model's longitudinal section (matching ranks candidates by it)

Revision ID: 0004_profile
Revises: 0003_frame
Create Date: 2026-11-25 23:05:00
"""
from typing import Sequence, Union

import numpy as np
import sqlalchemy as sa
from alembic import op

revision: str = '0004_profile'
down_revision: Union[str, None] = '0003_frame'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def _unpack(blob: bytes) -> np.ndarray:
    shape = tuple(np.frombuffer(blob[:8], dtype="<i4"))
    return np.frombuffer(blob[8:], dtype="<f4").reshape(shape).astype(np.float64)


def upgrade() -> None:
    from cosco.taxonomy import descriptor

    with op.batch_alter_table('ref_models', schema=None) as batch_op:
        batch_op.add_column(sa.Column('profile_mid', sa.Float(), nullable=True))
        batch_op.add_column(sa.Column('profile_end', sa.Float(), nullable=True))
    # existing models get theirs from the sections they already hold
    conn = op.get_bind()
    rows = conn.execute(sa.text("SELECT id, length, width, height, section_longitudinal FROM ref_models")).fetchall()
    for mid, length, width, height, blob in rows:
        d = descriptor(np.array([length, width, height]), _unpack(blob))
        conn.execute(sa.text("UPDATE ref_models SET profile_mid = :a, profile_end = :b WHERE id = :i"),
                     {"a": float(d[3]), "b": float(d[4]), "i": mid})


def downgrade() -> None:
    with op.batch_alter_table('ref_models', schema=None) as batch_op:
        batch_op.drop_column('profile_end')
        batch_op.drop_column('profile_mid')
