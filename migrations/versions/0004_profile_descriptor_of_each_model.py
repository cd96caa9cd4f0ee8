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


#: the stations of the descriptor as it was at this revision (a migration keeps its own copy: it must not change
#: when the code does)
_STATIONS = (0.25, 0.75)


def _descriptor(size: np.ndarray, longitudinal: np.ndarray) -> np.ndarray:
    """(5,) length, width, height and the top of the longitudinal section at the stations (cosco.taxonomy's
    descriptor at revision 0004)."""
    lon = np.asarray(longitudinal, dtype=np.float64).reshape(-1, 2)
    half = max(size[0] / 2, 1e-6)
    tops = []
    for s in _STATIONS:
        both = []
        for sign in (-1.0, 1.0):
            near = np.abs(lon[:, 0] / half - sign * s) < 0.1 if len(lon) else np.zeros(0, bool)
            both.append(float(lon[near, 1].max()) if near.any() else np.nan)
        tops.append(np.nanmean(both) if np.isfinite(both).any() else 0.0)
    return np.concatenate([np.asarray(size, dtype=np.float64), tops])


def upgrade() -> None:
    with op.batch_alter_table('ref_models', schema=None) as batch_op:
        batch_op.add_column(sa.Column('profile_mid', sa.Float(), nullable=True))
        batch_op.add_column(sa.Column('profile_end', sa.Float(), nullable=True))
    # existing models get theirs from the sections they already hold
    conn = op.get_bind()
    rows = conn.execute(sa.text("SELECT id, length, width, height, section_longitudinal FROM ref_models")).fetchall()
    for mid, length, width, height, blob in rows:
        d = _descriptor(np.array([length, width, height]), _unpack(blob))
        conn.execute(sa.text("UPDATE ref_models SET profile_mid = :a, profile_end = :b WHERE id = :i"),
                     {"a": float(d[3]), "b": float(d[4]), "i": mid})


def downgrade() -> None:
    with op.batch_alter_table('ref_models', schema=None) as batch_op:
        batch_op.drop_column('profile_end')
        batch_op.drop_column('profile_mid')
