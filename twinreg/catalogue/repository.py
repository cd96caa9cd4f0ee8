"""The catalogue: add, query, update and remove reference models, never leaving it half-written.

Layout of a catalogue folder::

    catalogue.sqlite             the database (alembic-managed schema)
    files/<sha[:2]>/<sha>.<ext>  the source files, content-addressed (the catalogue is self-contained and movable)
    meshes/<sha>.npz             the normalised meshes (metres, Z up, front +X) used to build twins

Writes follow one pattern: compute everything first, then under the folder's writer lock write files to temporary
names and rename them, insert the row in one transaction, and delete the new files again if the transaction fails.
"""

from __future__ import annotations

import contextlib
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sqlalchemy import and_, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, defer

import cosco
from cosco.taxonomy import descriptor

from ..errors import CatalogueError, DuplicateModelError, ModelNotFoundError, require_positive
from ..io.decimate import GE_MAX_TRIANGLES, decimate
from ..io.outdir import atomic_path
from ..settings import DEFAULT
from .categories import check_category
from .db import DB_NAME, open_engine, writer_lock
from .models import RefModel, pack, unpack
from .names import SORT_KEYS, check_name, check_text, is_sha256, parse_ref, preferred_stem, printable, safe_auto_name
from .prepare import PreparedModel, file_sha256, is_scan_file, prepare_model, prepare_scan

EDITABLE = ("name", "make", "model", "body_class", "tags", "category")
# large columns, loaded only when a model's arrays are needed (a size query over thousands of rows stays light)
BLOBS = ("points", "section_longitudinal", "section_transverse", "section_longitudinal_fine",
         "section_transverse_fine")


@dataclass
class ModelGeometry:
    """What matching and export need of a catalogue model: arrays, not rows."""

    id: int
    name: str
    size: np.ndarray
    sections: cosco.Sections
    mesh_vertices: np.ndarray
    mesh_faces: np.ndarray
    points: np.ndarray
    mesh_glass: np.ndarray | None = None


def atomic_copy(src: Path, dst: Path) -> bool:
    """Copy ``src`` to ``dst`` through a temporary file and a rename. Returns False if ``dst`` already existed."""
    if dst.exists():
        return False
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)
    return True


@contextlib.contextmanager
def undone_on_failure(session: Session):
    """Yield a list for the files a transaction writes; if the block fails, the session is rolled back and those
    files deleted, so that rows and files go in together or not at all."""
    created: list[Path] = []
    try:
        yield created
    except BaseException:
        session.rollback()
        for f in created:
            f.unlink(missing_ok=True)
        raise


def _atomic_npz(dst: Path, **arrays) -> bool:
    if dst.exists():
        return False
    with atomic_path(dst, ".npz") as tmp:
        np.savez_compressed(tmp, **arrays)
    return True


class Catalogue:
    """A catalogue folder. ``Catalogue(path)`` opens (and upgrades) it; reads of a missing catalogue see it empty."""

    def __init__(self, folder, create: bool = True):
        """``create``: whether a missing catalogue may be created; it is created by its first write, never by
        opening it (a refused command leaves no empty catalogue behind). With ``create`` False a write to a missing
        catalogue is a :class:`CatalogueError` saying so."""
        self.folder = Path(folder)
        self._create = create
        self._engine = None
        if self.folder.exists() and not self.folder.is_dir():
            raise CatalogueError(f"{self.folder}: is a file, not a catalogue folder; give --library the folder "
                                 "that holds catalogue.sqlite")
        if (self.folder / DB_NAME).exists():
            self._engine = open_engine(self.folder, create=False)

    @property
    def exists(self) -> bool:
        return self._engine is not None

    @property
    def engine(self):
        """The SQLAlchemy engine of the catalogue's database (opened, and created, on first use)."""
        if self._engine is None:
            self._engine = open_engine(self.folder, create=self._create)
        return self._engine

    def after_fork(self) -> None:
        """In a child forked from the process that opened the catalogue: its pooled connections are left to the
        parent (SQLAlchemy's ``dispose(close=False)``); this process opens its own."""
        if self._engine is not None:
            self._engine.dispose(close=False)

    def session(self) -> Session:
        if self._engine is None:
            self._engine = open_engine(self.folder, create=self._create)
        return Session(self._engine, expire_on_commit=False)

    # ---- reading -------------------------------------------------------------------------------------------
    def count(self) -> int:
        if not self.exists:
            return 0
        with self.session() as s:
            return int(s.scalar(select(func.count(RefModel.id))))

    def list(self, near=None, tol: float | None = None, body_class: str | None = None,
             category: str | None = None) -> list[RefModel]:
        """All models, or those whose L, W and H are each within ``tol`` (m, default the matcher's
        ``Settings.matching.size_tol``) of ``near`` (one indexed query), of ``category`` when given."""
        tol = require_positive("--tol", tol) or DEFAULT.matching.size_tol
        if category is not None:
            category = check_category(category)
        if not self.exists:
            return []
        q = self.size_query(near, tol, body_class, category)
        with self.session() as s:
            return list(s.scalars(q))

    def listing(self, near=None, tol: float | None = None, body_class: str | None = None, tags=(),
                sort: str = "id", category: str | None = None) -> list[RefModel]:
        """:meth:`list`, keeping the models that carry every tag of ``tags``, in the order ``sort`` (one of
        :data:`SORT_KEYS`; names, makes and classes without regard to case)."""
        if sort not in SORT_KEYS:
            raise CatalogueError(f"--sort {sort}: not one of {', '.join(SORT_KEYS)}")
        wanted = set(tags or ())
        rows = [r for r in self.list(near=near, tol=tol, body_class=body_class, category=category)
                if wanted <= set(r.tags)]
        key = {"class": lambda r: (r.body_class or "").lower(), "make": lambda r: (r.make or "").lower(),
               "name": lambda r: r.name.lower()}.get(sort, lambda r: getattr(r, sort))
        return sorted(rows, key=key)

    @staticmethod
    def size_query(near=None, tol: float = DEFAULT.matching.size_tol, body_class: str | None = None,
                   category: str | None = None):
        """The SELECT of :meth:`list` (large columns deferred), for reuse and for checking its query plan."""
        q = select(RefModel)
        conds = []
        if near is not None:
            length, width, height = (float(x) for x in near)
            conds += [RefModel.length.between(length - tol, length + tol),
                      RefModel.width.between(width - tol, width + tol),
                      RefModel.height.between(height - tol, height + tol)]
        if body_class:  # "sedan" finds "sedan/liftback" and "Sedan (fastback)"
            conds.append(func.lower(RefModel.body_class).contains(body_class.lower(), autoescape=True))
        if category is not None:
            conds.append(RefModel.category == category)
        if conds:
            q = q.where(and_(*conds))
        return q.options(*(defer(getattr(RefModel, b)) for b in BLOBS)).order_by(RefModel.id)

    def descriptors(self) -> tuple[np.ndarray, np.ndarray]:
        """Every model's id (n,) and descriptor (n, 5): L, W, H and the section-top heights ``profile_mid``,
        ``profile_end`` (one query, no blobs)."""
        if not self.exists:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 5))
        cols = (RefModel.id, RefModel.length, RefModel.width, RefModel.height, RefModel.profile_mid,
                RefModel.profile_end)
        with self.session() as s:
            rows = s.execute(select(*cols).order_by(RefModel.id)).all()
        table = np.array([[np.nan if v is None else v for v in r] for r in rows], dtype=np.float64).reshape(-1, 6)
        return table[:, 0].astype(np.int64), table[:, 1:]

    def rows(self, ids) -> list[RefModel]:
        """The rows (blobs deferred) of the models ``ids``, in that order."""
        ids = [int(i) for i in ids]
        if not ids:
            return []
        q = select(RefModel).where(RefModel.id.in_(ids)).options(*(defer(getattr(RefModel, b)) for b in BLOBS))
        with self.session() as s:
            by_id = {r.id: r for r in s.scalars(q)}
        return [by_id[i] for i in ids]

    def get(self, ref) -> RefModel:
        """A model by REF: ``id:N``, ``name:TEXT``, an id (digits) or a unique name (:mod:`.names`); bare digits
        that are both an id and an old model's name are refused, listing both."""
        kind, text = parse_ref(ref)
        shown = printable(ref)
        if not self.exists:
            raise ModelNotFoundError(f"no model '{shown}': the catalogue in {self.folder} is empty")
        with self.session() as s:
            by_id = s.get(RefModel, int(text)) if kind in ("id", "either") and text.isdigit() else None
            by_name = s.scalar(select(RefModel).where(RefModel.name == text)) if kind in ("name", "either") else None
            if by_id is not None and by_name is not None and by_id.id != by_name.id:
                raise CatalogueError(f"'{shown}' is ambiguous: model id {by_id.id} ('{printable(by_id.name)}') and "
                                     f"model {by_name.id} named '{shown}'; say id:{text} or name:{text}")
            row = by_id if by_id is not None else by_name
            if row is None:
                raise ModelNotFoundError(f"no model '{shown}' in {self.folder}; see `twinreg list-models`")
            return row

    def geometry(self, row: RefModel, with_mesh: bool = True) -> ModelGeometry:
        """Arrays of one model (sections, sampled points and, unless ``with_mesh`` is False, the normalised
        mesh). A damaged row or mesh file is a :class:`CatalogueError` naming the model and the fix."""
        try:
            return self._geometry(row, with_mesh)
        except (ValueError, KeyError, OSError, EOFError) as exc:
            raise CatalogueError(f"{self.folder}: model {row.id} '{printable(row.name)}' is damaged ({exc}); remove "
                                 f"it (`twinreg remove-model id:{row.id} --yes`) and add its file again") from exc

    def _geometry(self, row: RefModel, with_mesh: bool) -> ModelGeometry:
        with self.session() as s:
            blobs = s.execute(select(*(getattr(RefModel, b) for b in BLOBS)).where(RefModel.id == row.id)).one()
        blob = dict(zip(BLOBS, blobs))
        if with_mesh:
            mesh = np.load(self.mesh_path(row), allow_pickle=False)
        else:
            mesh = {"vertices": np.zeros((0, 3)), "faces": np.zeros((0, 3), dtype=np.int64)}
        return ModelGeometry(
            id=row.id, name=row.name, size=np.array([row.length, row.width, row.height]),
            sections=cosco.Sections(
                unpack(blob["section_longitudinal"]), unpack(blob["section_transverse"]), row.section_res,
                unpack(blob["section_longitudinal_fine"]) if blob["section_longitudinal_fine"] else None,
                unpack(blob["section_transverse_fine"]) if blob["section_transverse_fine"] else None),
            mesh_vertices=mesh["vertices"].astype(np.float64), mesh_faces=mesh["faces"].astype(np.int64),
            points=unpack(blob["points"]),
            mesh_glass=mesh["glass"].astype(bool) if with_mesh and "glass" in mesh.files else None,
        )

    def mesh_path(self, row: RefModel, tag: str | None = None) -> Path:
        """Where the catalogue keeps a model's normalised mesh (``meshes/<sha>.npz``) or a decimated one
        (``meshes/<sha>.<tag>.npz``): derived from its content address, never from a stored path."""
        if not is_sha256(row.sha256):
            raise CatalogueError(f"{self.folder}: model {row.id} '{printable(row.name)}' is damaged (its content address "
                                 f"is not a sha256); remove it (`twinreg remove-model id:{row.id} --yes`)")
        return self.folder / "meshes" / (f"{row.sha256}.npz" if tag is None else f"{row.sha256}.{tag}.npz")

    def scan_meshes(self, rows) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
        """``(vertices, faces, glass)`` of the normalised meshes of ``rows``, as the scan simulator takes them."""
        out = []
        for row in rows:
            g = self.geometry(row)
            out.append((g.mesh_vertices, g.mesh_faces, g.mesh_glass))
        return out

    def ge_mesh(self, row: RefModel, max_faces: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The model's mesh decimated to Google Earth's limit (or to ``max_faces`` triangles), cached beside the
        full mesh (``meshes/<sha>.ge.npz``, ``<sha>.<max_faces>.npz``, written atomically the first time a twin
        uses the model)."""
        path = self.mesh_path(row, "ge" if max_faces is None else str(int(max_faces)))
        if path.exists():
            d = np.load(path)
            return d["vertices"].astype(np.float64), d["faces"].astype(np.int64)
        if max_faces is None:
            geo = self.geometry(row)
            v, f = decimate(geo.mesh_vertices, geo.mesh_faces, GE_MAX_TRIANGLES)
        else:  # from the Google Earth mesh: a small target is reached in a fraction of the time
            v, f = decimate(*self.ge_mesh(row), max_faces)
        # as the cache holds it: the first twin that uses the model and every later one get the same mesh
        v, f = v.astype(np.float32), f.astype(np.int32)
        try:
            _atomic_npz(path, vertices=v, faces=f)
        except OSError:
            pass  # a read-only catalogue still builds twins, only slower
        return v.astype(np.float64), f.astype(np.int64)

    # ---- writing -------------------------------------------------------------------------------------------
    def check_free_name(self, name: str, where: str = "") -> str:
        """``name`` if it may name a new model here (usable and not taken), else the error saying why; asked
        before a costly measurement (add_prepared checks again, under the writer lock)."""
        check_name(name, where)
        if self.exists:
            with self.session() as s:
                if s.scalar(select(RefModel.id).where(RefModel.name == name)) is not None:
                    raise DuplicateModelError(f"{where}the name '{printable(name)}' is taken; pass another --name")
        return name

    def _free_name(self, s: Session, wanted: str | None, path: Path, hint: str | None = None) -> str:
        """``wanted`` (refused when taken), else a free name from ``hint`` or the file's name (its folder's when
        the file's is generic: :func:`~twinreg.catalogue.names.preferred_stem`)."""
        if wanted:
            check_name(wanted, f"{path}: ")
            if s.scalar(select(RefModel.id).where(RefModel.name == wanted)) is not None:
                raise DuplicateModelError(f"{path}: the name '{wanted}' is taken; pass another --name")
            return wanted
        first = hint or preferred_stem(path)
        candidates = list(dict.fromkeys([safe_auto_name(first), safe_auto_name(f"{path.parent.name}_{path.stem}")]))
        for base in candidates:
            if s.scalar(select(RefModel.id).where(RefModel.name == base)) is None:
                return base
        k = 2
        while s.scalar(select(RefModel.id).where(RefModel.name == f"{candidates[-1]}-{k}")) is not None:
            k += 1
        return f"{candidates[-1]}-{k}"

    def add_prepared(self, prep: PreparedModel, name=None, make=None, model=None, body_class=None,
                     tags=(), name_hint: str | None = None) -> RefModel:
        """Store a prepared model: one transaction, files written to temporary names and renamed."""
        for option, value in (("--make", make), ("--model", model), ("--body-class", body_class),
                              *(("--tag", t) for t in tags)):
            check_text(value, option, f"{prep.path}: ")
        sha = prep.sha256
        ext = prep.path.suffix.lower()
        stored = Path("files") / sha[:2] / f"{sha}{ext}"
        mesh_file = Path("meshes") / f"{sha}.npz"
        self.engine  # created (and upgraded) before the writer lock is taken: the upgrade takes it itself
        with writer_lock(self.folder):
            with self.session() as s:
                existing = s.scalar(select(RefModel).where(RefModel.sha256 == sha))
                if existing is not None:
                    raise DuplicateModelError(f"{prep.path}: same content as model {existing.id} "
                                              f"'{existing.name}' already in the catalogue")
                final_name = self._free_name(s, name, prep.path, name_hint)
                with undone_on_failure(s) as created:
                    try:
                        if atomic_copy(prep.path, self.folder / stored):
                            created.append(self.folder / stored)
                        if _atomic_npz(self.folder / mesh_file, vertices=prep.mesh.vertices.astype(np.float32),
                                       faces=prep.mesh.faces.astype(np.int32), glass=prep.mesh.glass):
                            created.append(self.folder / mesh_file)
                        shape = prep.shape
                        desc = descriptor(shape.size.as_array(), shape.sections.longitudinal)
                        row = RefModel(
                            name=final_name, category=prep.category, source=prep.source, make=make, model=model,
                            body_class=body_class,
                            tags_json=json.dumps(sorted(set(tags))), sha256=sha, source_name=prep.path.name,
                            stored_file=str(stored), mesh_file=str(mesh_file), n_faces=len(prep.mesh.faces),
                            unit=prep.mesh.unit, unit_scale=prep.mesh.scale, unit_source=prep.mesh.unit_source,
                            up_axis=prep.mesh.up, front_axis=prep.mesh.front, notes="; ".join(prep.mesh.notes),
                            length=shape.size.length, width=shape.size.width, height=shape.size.height,
                            mesh_length=float(prep.mesh_size[0]), mesh_width=float(prep.mesh_size[1]),
                            mesh_height=float(prep.mesh_size[2]),
                            sym_found=shape.symmetry.found, sym_pcr=shape.symmetry.pcr,
                            sym_rmse=float(shape.symmetry.rmse), sym_heading=shape.heading,
                            sym_level=prep.level.level if prep.level is not None else None,
                            sample_spacing=prep.spacing, n_points=len(prep.points), points=pack(prep.points),
                            section_longitudinal=pack(shape.sections.longitudinal),
                            section_transverse=pack(shape.sections.transverse), section_res=shape.sections.res,
                            glass_fraction=prep.glass_fraction,
                            profile_mid=float(desc[3]), profile_end=float(desc[4]),
                            section_longitudinal_fine=pack(shape.sections.fine[0]),
                            section_transverse_fine=pack(shape.sections.fine[1]),
                            frame_x=float(shape.frame.origin_xy[0]), frame_y=float(shape.frame.origin_xy[1]),
                            frame_heading=float(shape.frame.heading),
                            params_json=json.dumps({"sample_spacing": prep.spacing}),
                        )
                        s.add(row)
                        s.commit()
                    except IntegrityError as exc:
                        raise DuplicateModelError(f"{prep.path}: already in the catalogue ({exc.orig})") from exc
                return row

    def add(self, path, name=None, make=None, model=None, body_class=None, tags=(), unit="auto", up="auto",
            front="auto", category=None, scale: float = 1.0, name_hint: str | None = None,
            ground_z: float | None = None) -> RefModel:
        """Load, normalise, measure and store one mesh file of a ``category`` (``car`` when None; ``scale``: a
        factor after the unit; ``ground_z``: a scanned object's ground, :func:`prepare_scan`). See
        :func:`prepare_model`."""
        category = check_category(category)
        if not (np.isfinite(scale) and 1e-4 <= scale <= 1e4):
            raise CatalogueError(f"--scale {scale:g}: give a factor between 0.0001 and 10000")
        path = Path(path)
        if self.exists and path.is_file():  # refuse a duplicate before the costly part
            sha = file_sha256(path)
            with self.session() as s:
                existing = s.scalar(select(RefModel).where(RefModel.sha256 == sha))
            if existing is not None:
                raise DuplicateModelError(f"{path}: same content as model {existing.id} "
                                          f"'{existing.name}' already in the catalogue")
        if path.is_file() and is_scan_file(path):
            prep = prepare_scan(path, category, unit=unit, factor=float(scale), ground_z=ground_z)
        else:
            prep = prepare_model(path, unit=unit, up=up, front=front, category=category, factor=float(scale))
        return self.add_prepared(prep, name=name, make=make, model=model, body_class=body_class, tags=tags,
                                 name_hint=name_hint)

    def update(self, ref, **fields) -> RefModel:
        """Change editable fields (name, make, model, body_class, tags)."""
        row = self.get(ref)
        with writer_lock(self.folder), self.session() as s:
            row = s.get(RefModel, row.id)
            for key, value in fields.items():
                if value is None:
                    continue
                if key not in EDITABLE:
                    raise CatalogueError(f"'{key}' cannot be edited; editable: {', '.join(EDITABLE)}")
                if key == "name":
                    check_name(value)
                elif key == "tags":
                    for t in value:
                        check_text(t, "--tag")
                elif key in ("make", "model", "body_class"):
                    check_text(value, "--" + key.replace("_", "-"))
                if key == "category":
                    value = check_category(value)
                if key == "tags":
                    row.tags_json = json.dumps(sorted(set(value)))
                else:
                    setattr(row, key, value)
            try:
                s.commit()
            except IntegrityError as exc:
                s.rollback()
                raise DuplicateModelError(f"the name '{fields.get('name')}' is taken; choose another") from exc
            return row

    def remove(self, ref) -> RefModel:
        """Delete a model row, then its files, all under the writer lock (a concurrent add of the same file waits
        until the files are gone, then writes them anew). The row goes first: a crash leaves orphan files, which a
        later add of the same content reuses, never a row pointing to nothing. Only files inside the catalogue's
        ``files/`` and ``meshes/`` that no other row names are deleted, whatever the row says."""
        row = self.get(ref)
        with writer_lock(self.folder):
            with self.session() as s:
                victim = s.get(RefModel, row.id)
                if victim is None:
                    raise ModelNotFoundError(f"no model '{printable(ref)}' in {self.folder}; see `twinreg list-models`")
                s.delete(victim)
                s.flush()
                used = {p for pair in s.execute(select(RefModel.stored_file, RefModel.mesh_file)) for p in pair}
                s.commit()
            for path in self._own_files(row, used):
                path.unlink(missing_ok=True)
        return row

    def _own_files(self, row: RefModel, used: set) -> list[Path]:
        """The files of ``row`` that may be deleted: inside ``files/`` or ``meshes/`` (symlinks not followed out),
        regular files, named by no other row (``used``: the other rows' paths)."""
        roots = [(self.folder / sub).resolve() for sub in ("files", "meshes")]
        paths = [row.stored_file, row.mesh_file]
        if is_sha256(row.sha256):  # the decimated meshes, named by the content's address
            paths += [p.relative_to(self.folder).as_posix() for p in (self.folder / "meshes").glob(f"{row.sha256}.*.npz")]
        out = []
        for rel in dict.fromkeys(p for p in paths if p):
            if rel in used or Path(rel).is_absolute() or ".." in Path(rel).parts:
                continue
            p = self.folder / rel
            if p.is_symlink() or not p.is_file():
                continue
            if any(r in p.resolve().parents for r in roots):
                out.append(p)
        return out

    def close(self) -> None:
        """Release the database (the folder can then be moved)."""
        if self._engine is not None:
            self._engine.dispose()
