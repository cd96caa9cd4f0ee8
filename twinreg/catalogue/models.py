"""SQLAlchemy 2.0 ORM of the catalogue. Schema changes go through alembic (``migrations/``)."""

from __future__ import annotations

import json
from datetime import datetime, timezone

import numpy as np
from sqlalchemy import Boolean, DateTime, Float, Index, Integer, LargeBinary, MetaData, String, Text
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


def _now() -> datetime:
    return datetime.now(timezone.utc)


def pack(arr: np.ndarray) -> bytes:
    """(n, k) float array to bytes: a little header (rows, cols) then float32 values."""
    a = np.ascontiguousarray(arr, dtype="<f4")
    return np.array(a.shape, dtype="<i4").tobytes() + a.tobytes()


def unpack(blob: bytes) -> np.ndarray:
    """Inverse of :func:`pack`, as float64.

    >>> unpack(pack(np.arange(6.0).reshape(3, 2))).tolist()
    [[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]]
    """
    if blob is None or len(blob) < 8:
        raise ValueError("a stored array is missing its header")
    shape = tuple(int(v) for v in np.frombuffer(blob[:8], dtype="<i4"))
    if min(shape) < 0 or shape[0] * shape[1] * 4 != len(blob) - 8:
        raise ValueError(f"a stored array's header says {shape} but holds {len(blob) - 8} bytes")
    return np.frombuffer(blob[8:], dtype="<f4").reshape(shape).astype(np.float64)


class RefModel(Base):
    """A reference CAD model, normalised (metres, Z up, front +X, footprint centred, lowest point z = 0)."""

    __tablename__ = "ref_models"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    make: Mapped[str | None] = mapped_column(String(100))
    model: Mapped[str | None] = mapped_column(String(200))
    body_class: Mapped[str | None] = mapped_column(String(50), index=True)
    tags_json: Mapped[str] = mapped_column(Text, default="[]")
    #: the model's kind (:mod:`twinreg.catalogue.categories`) and where it comes from (``mesh``: a CAD file;
    #: ``scan``: a scanned object)
    category: Mapped[str] = mapped_column(String(40), default="car", server_default="car", index=True)
    source: Mapped[str] = mapped_column(String(10), default="mesh", server_default="mesh")

    sha256: Mapped[str] = mapped_column(String(64), unique=True)
    source_name: Mapped[str] = mapped_column(String(500))
    stored_file: Mapped[str] = mapped_column(String(500))
    mesh_file: Mapped[str] = mapped_column(String(500))
    n_faces: Mapped[int] = mapped_column(Integer)

    unit: Mapped[str] = mapped_column(String(20))
    unit_scale: Mapped[float] = mapped_column(Float)
    unit_source: Mapped[str] = mapped_column(String(200))
    up_axis: Mapped[str] = mapped_column(String(4))
    front_axis: Mapped[str] = mapped_column(String(4))
    notes: Mapped[str] = mapped_column(Text, default="")

    length: Mapped[float] = mapped_column(Float, index=True)  # m, the scan-visible size
    width: Mapped[float] = mapped_column(Float, index=True)  # m
    height: Mapped[float] = mapped_column(Float, index=True)  # m
    mesh_length: Mapped[float] = mapped_column(Float)  # m, the whole mesh
    mesh_width: Mapped[float] = mapped_column(Float)  # m
    mesh_height: Mapped[float] = mapped_column(Float)  # m

    sym_found: Mapped[bool] = mapped_column(Boolean)  # a plane at or above the PCR threshold
    sym_pcr: Mapped[float] = mapped_column(Float)  # point correspondence ratio
    sym_rmse: Mapped[float] = mapped_column(Float)  # m
    sym_heading: Mapped[float] = mapped_column(Float)  # rad
    #: the level of symmetry (:mod:`cosco.levels`): none, mirror, two_mirrors, rotational
    sym_level: Mapped[str | None] = mapped_column(String(20), nullable=True)

    sample_spacing: Mapped[float] = mapped_column(Float)  # m between samples
    n_points: Mapped[int] = mapped_column(Integer)  # samples
    points: Mapped[bytes] = mapped_column(LargeBinary)  # float32 (n, 3) samples
    section_longitudinal: Mapped[bytes] = mapped_column(LargeBinary)
    section_transverse: Mapped[bytes] = mapped_column(LargeBinary)
    section_res: Mapped[float] = mapped_column(Float)  # m
    section_longitudinal_fine: Mapped[bytes | None] = mapped_column(LargeBinary, nullable=True)
    section_transverse_fine: Mapped[bytes | None] = mapped_column(LargeBinary, nullable=True)
    frame_x: Mapped[float | None] = mapped_column(Float, nullable=True)
    frame_y: Mapped[float | None] = mapped_column(Float, nullable=True)
    frame_heading: Mapped[float | None] = mapped_column(Float, nullable=True)
    glass_fraction: Mapped[float] = mapped_column(Float, default=0.0, server_default="0")
    #: height (m) of the longitudinal section's top at 1/4 and 3/4 of the half-length from the middle, both ends
    #: averaged (:func:`cosco.taxonomy.descriptor`): with L, W, H the descriptor matching ranks candidates by
    profile_mid: Mapped[float | None] = mapped_column(Float, nullable=True)
    profile_end: Mapped[float | None] = mapped_column(Float, nullable=True)
    params_json: Mapped[str] = mapped_column(Text, default="{}", server_default="{}")

    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=_now)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=_now, onupdate=_now)

    __table_args__ = (Index("ix_ref_models_size", "length", "width", "height"),)

    @property
    def tags(self) -> list[str]:
        return json.loads(self.tags_json or "[]")

    def to_dict(self) -> dict:
        """The contract's JSON shape, plus provenance."""
        return {
            "id": self.id, "name": self.name, "category": self.category or "car", "source": self.source or "mesh",
            "make": self.make, "model": self.model, "body_class": self.body_class, "tags": self.tags,
            "size": {"length": round(self.length, 3), "width": round(self.width, 3), "height": round(self.height, 3)},
            "mesh_size": {"length": round(self.mesh_length, 3), "width": round(self.mesh_width, 3),
                          "height": round(self.mesh_height, 3)},
            "symmetry": {"found": bool(self.sym_found), "pcr": round(self.sym_pcr, 4), "level": self.sym_level},
            "n_points": self.n_points, "sample_spacing_m": self.sample_spacing, "sha256": self.sha256,
            "source_name": self.source_name, "unit": self.unit, "unit_source": self.unit_source,
            "up": self.up_axis, "front": self.front_axis, "n_faces": self.n_faces,
            "glass_fraction": round(self.glass_fraction or 0.0, 4), "notes": self.notes,
            "created_at": self.created_at.isoformat() if self.created_at else None,
            "updated_at": self.updated_at.isoformat() if self.updated_at else None,
        }
