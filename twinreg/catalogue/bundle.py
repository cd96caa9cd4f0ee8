"""Portable catalogues: ``export-library lib.zip`` and ``import-library lib.zip``.

A bundle is a zip holding ``bundle.json`` (the format, the catalogue's schema revision, every member's size and
sha256), ``catalogue.sqlite`` (a consistent copy of the database: rows, sampled clouds, sections, provenance) and
the model files (``files/``: the originals as added; ``meshes/``: the normalised meshes and the decimated ones the
twins use). Import checks every checksum before it touches anything, upgrades an older bundle's schema in a
scratch folder, then adds the rows in one transaction and the files through temporary names: a refused or
failed import leaves the catalogue as it was.

A bundle is a stranger's data and decides nothing: the byte counts of the zip's entries must equal the manifest's,
the total is capped (:data:`MAX_TOTAL_BYTES`, and a member may not inflate more than :data:`MAX_RATIO` times), and
only the database and the files of the models being imported are extracted, each checked against its checksum as
it is written. Every row is checked before anything is written (:func:`check_row`): its content address is 64 hex
characters, its file paths are the ones the importer derives from that address and the file's format, its
original file hashes to that address, its arrays match their headers and the model's stored shape, its sizes are
plausible. Any fault is one line, ``not a valid bundle: ...``, and the catalogue is unchanged. Names already in the catalogue are clashes: they are reported and
nothing changes, unless ``rename`` (a free name is taken: ``name-2``) or ``skip`` is asked for; a model whose
content (sha256) is already in the catalogue is left out and reported.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import sqlite3
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BundleError, CatalogueError, ExportError
from ..io.outdir import atomic_path
from .categories import check_category
from .db import DB_NAME, make_engine, upgrade, writer_lock
from .models import RefModel, unpack
from .names import is_sha256, name_problem, printable, text_problem
from .prepare import file_sha256
from .repository import atomic_copy, undone_on_failure

FORMAT = "twinreg-library"
VERSION = 1
#: the most a bundle may hold uncompressed (bytes), and the most one member may inflate (uncompressed/compressed)
MAX_TOTAL_BYTES = 64 * 1024 ** 3
MAX_RATIO = 200
#: the most bundle.json may take (bytes)
MAX_MANIFEST_BYTES = 16 * 1024 ** 2
_EXT = re.compile(r"\.[a-z0-9]{1,10}")
#: plausible sizes of a catalogue model (m)
SIZE_RANGE = (0.005, 400.0)  # a stop sign is 2 cm thin, a building hundreds of metres long


def model_files(sha: str, stored_ext: str) -> tuple[str, str]:
    """Where a catalogue keeps a model's original file and its normalised mesh, from its content address and
    the original's format (the importer derives them; a bundle never names them).

    >>> model_files("ab" * 32, ".obj")[0]
    'files/ab/abababababababababababababababababababababababababababababababab.obj'
    """
    return f"files/{sha[:2]}/{sha}{stored_ext}", f"meshes/{sha}.npz"


def export_library(catalogue, zip_path, force: bool = False) -> dict:
    """Write the catalogue (a :class:`~twinreg.catalogue.repository.Catalogue` or its folder) to ``zip_path``
    (through a temporary name); returns the bundle's manifest.

    Refuses a destination inside the catalogue folder and an existing file that is not a bundle (unless
    ``force``). Only reads the catalogue (no writer lock, no upgrade: a read-only catalogue exports): the database
    is copied with SQLite's backup (one consistent read), and the files are those the copied rows name, which are
    never rewritten in place."""
    folder = Path(getattr(catalogue, "folder", catalogue))
    zip_path = Path(zip_path)
    _check_destination(folder, zip_path, force)
    if not (folder / DB_NAME).is_file():
        raise CatalogueError(f"{folder}: no catalogue here; nothing to export")
    with tempfile.TemporaryDirectory() as tmp:
        snapshot = Path(tmp) / DB_NAME
        rows, revision = _snapshot(folder / DB_NAME, snapshot)
        if not rows:
            raise CatalogueError(f"{folder}: the catalogue is empty; nothing to export")
        names = set()
        for sha, stored, mesh in rows:
            names.update([stored, mesh])
            if is_sha256(sha):
                names.update(p.relative_to(folder).as_posix() for p in sorted((folder / "meshes").glob(f"{sha}.*.npz"))
                             if ".tmp" not in p.name)
        members = [(snapshot, DB_NAME)]
        for name in sorted(names):
            p = folder / name
            if not p.is_file() or ".." in Path(name).parts or Path(name).is_absolute():
                raise CatalogueError(f"{folder}: {name} is missing or outside the catalogue (a model was removed "
                                     "during the export, or the catalogue is damaged); run the export again")
            members.append((p, name))
        manifest = {"format": FORMAT, "version": VERSION, "schema_revision": revision, "n_models": len(rows),
                    "members": {name: {"bytes": p.stat().st_size, "sha256": file_sha256(p)} for p, name in members}}
        with atomic_path(zip_path) as tmp_zip:
            with zipfile.ZipFile(tmp_zip, "w", zipfile.ZIP_STORED) as z:
                z.writestr("bundle.json", json.dumps(manifest, indent=1))
                for p, name in members:
                    z.write(p, name)
    return manifest


def _snapshot(db: Path, snapshot: Path) -> tuple[list, str | None]:
    """Copy the database ``db`` to ``snapshot`` (read-only access); returns the rows' (sha256, stored_file,
    mesh_file) and the schema revision."""
    src = None
    # read-write first, though nothing is written: closing such a connection, the last one, removes the WAL's
    # -wal and -shm files, which a read-only one leaves in the user's folder (an output folder holding them could
    # no longer be replaced); then read-only; immutable: a read-only folder of a WAL database
    for uri in (f"file:{db}?mode=rw", f"file:{db}?mode=ro", f"file:{db}?immutable=1"):
        try:
            src = sqlite3.connect(uri, uri=True)
            src.execute("SELECT 1 FROM ref_models LIMIT 1").fetchall()
            break
        except sqlite3.Error as exc:
            if src is not None:
                src.close()
            src, error = None, exc
    if src is None:
        raise CatalogueError(f"{db}: cannot be read as a twinreg catalogue ({error}); check the --library folder")
    dst = sqlite3.connect(snapshot)
    try:
        src.backup(dst)
        dst.execute("PRAGMA journal_mode=DELETE")
        rows = dst.execute("SELECT sha256, stored_file, mesh_file FROM ref_models").fetchall()
        try:
            revision = (dst.execute("SELECT version_num FROM alembic_version").fetchone() or [None])[0]
        except sqlite3.Error:
            revision = None
    finally:
        src.close()
        dst.close()
    return rows, revision


def _check_destination(folder: Path, zip_path: Path, force: bool) -> None:
    try:
        zip_path.resolve().relative_to(folder.resolve())
        raise ExportError(f"{zip_path}: inside the catalogue folder {folder}; write the bundle elsewhere")
    except ValueError:
        pass
    if zip_path.is_dir():
        raise ExportError(f"{zip_path}: is a folder; name the bundle file to write (e.g. lib.zip)")
    if zip_path.exists() and not force and not _is_bundle(zip_path):
        raise ExportError(f"{zip_path}: exists and is not a twinreg bundle; choose another name or give --force")


def _is_bundle(path: Path) -> bool:
    try:
        with zipfile.ZipFile(path) as z:
            info = z.getinfo("bundle.json")
            return info.file_size < MAX_MANIFEST_BYTES and json.loads(z.read(info)).get("format") == FORMAT
    except (zipfile.BadZipFile, OSError, KeyError, ValueError, AttributeError):
        return False


@dataclass
class ImportResult:
    """What an import did: names added (bundle name -> stored name), left out (with why), clashes found."""

    added: dict = field(default_factory=dict)
    skipped: list = field(default_factory=list)
    clashes: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"added": self.added, "skipped": self.skipped, "clashes": self.clashes}


class _Bundle:
    """An opened bundle whose manifest and entries have been checked; members are extracted on demand, each
    checked against its size and checksum as it is written."""

    def __init__(self, zip_path: Path):
        self.path = zip_path
        if not zip_path.is_file():
            raise BundleError(f"{zip_path}: no such bundle file; give the .zip written by `twinreg export-library`")
        try:
            self.zip = zipfile.ZipFile(zip_path)
        except (zipfile.BadZipFile, OSError) as exc:
            raise self.error(f"not a zip file ({exc}); export one with `twinreg export-library FILE.zip`") from exc
        try:
            self.manifest = self._manifest()
            self._check_entries()
        except BaseException:
            self.zip.close()
            raise

    def error(self, why: str) -> BundleError:
        return BundleError(f"{self.path}: not a valid bundle: {why}")

    def _manifest(self) -> dict:
        try:
            info = self.zip.getinfo("bundle.json")
        except KeyError:
            raise self.error("no bundle.json; export one with `twinreg export-library FILE.zip`") from None
        if info.file_size > MAX_MANIFEST_BYTES:
            raise self.error(f"bundle.json takes {info.file_size} bytes (at most {MAX_MANIFEST_BYTES})")
        try:
            manifest = json.loads(self.zip.read(info))
        except (ValueError, zipfile.BadZipFile, OSError, EOFError) as exc:
            raise self.error(f"bundle.json cannot be read ({exc})") from exc
        if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
            raise self.error(f"bundle.json does not name the format {FORMAT}")
        version = manifest.get("version")
        if not isinstance(version, int) or version > VERSION:
            raise self.error(f"bundle format version {printable(version)} is not one this twinreg reads (up to "
                             f"{VERSION}); update twinreg")
        members = manifest.get("members")
        if not isinstance(members, dict) or DB_NAME not in members:
            raise self.error(f"bundle.json lists no {DB_NAME}: a bundle holds a catalogue database")
        for name, m in members.items():
            ok = isinstance(m, dict) and isinstance(m.get("bytes"), int) and m["bytes"] >= 0 and is_sha256(m.get("sha256"))
            if not ok:
                raise self.error(f"bundle.json's entry for {printable(name)[:100]} lacks a byte count or a sha256")
            parts = Path(name).parts
            if name.startswith("/") or "\\" in name or ".." in parts or not parts or ":" in parts[0]:
                raise self.error(f"member {printable(name)[:100]} points outside the catalogue")
        return manifest

    def _check_entries(self) -> None:
        members = self.manifest["members"]
        infos = {i.filename: i for i in self.zip.infolist() if i.filename != "bundle.json"}
        if set(infos) != set(members) or len(infos) != len(self.zip.infolist()) - 1:
            extra = sorted(set(infos) ^ set(members))[:3]
            raise self.error(f"its entries do not match bundle.json ({printable(', '.join(extra))[:200]}); export it again")
        total = 0
        for name, info in infos.items():
            if info.file_size != members[name]["bytes"]:
                raise self.error(f"member {name} holds {info.file_size} bytes, bundle.json says "
                                 f"{members[name]['bytes']}")
            if info.file_size > max(1 << 20, MAX_RATIO * info.compress_size):
                raise self.error(f"member {name} inflates {info.file_size / max(info.compress_size, 1):.0f} times "
                                 "(a zip bomb?)")
            total += info.file_size
        if total > MAX_TOTAL_BYTES:
            raise self.error(f"it holds {total / 1e9:.1f} GB uncompressed (at most {MAX_TOTAL_BYTES / 1e9:.0f} GB)")

    def has(self, name: str) -> bool:
        return name in self.manifest["members"]

    def extract(self, name: str, into: Path) -> Path:
        """Write member ``name`` under ``into`` (its size and checksum checked while it is written)."""
        want = self.manifest["members"].get(name)
        if want is None:
            raise self.error(f"it lacks {name}, which one of its models needs")
        dst = into / name
        dst.parent.mkdir(parents=True, exist_ok=True)
        h, n = hashlib.sha256(), 0
        try:
            with self.zip.open(name) as src, open(dst, "wb") as out:
                for chunk in iter(lambda: src.read(1 << 20), b""):
                    n += len(chunk)
                    if n > want["bytes"]:
                        raise self.error(f"member {name} holds more than the {want['bytes']} bytes it declares")
                    h.update(chunk)
                    out.write(chunk)
        except (zipfile.BadZipFile, EOFError, OSError) as exc:
            raise self.error(f"member {name} cannot be read ({exc}); export it again") from exc
        if n != want["bytes"] or h.hexdigest() != want["sha256"]:
            raise self.error(f"member {name} fails its checksum; the file is damaged, export it again")
        return dst

    def close(self) -> None:
        self.zip.close()


def _blob_shape(blob, cols: int, what: str, rows: int | None = None) -> int:
    """The rows of a stored array (:func:`~twinreg.catalogue.models.unpack` checks its header against its bytes),
    or ValueError unless it has ``cols`` columns (and ``rows`` rows) of finite numbers."""
    try:
        a = unpack(blob)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"its {what} array is damaged ({exc})") from None
    if a.shape[1] != cols or (rows is not None and a.shape[0] != rows):
        raise ValueError(f"its {what} array is {a.shape}, not ({rows if rows is not None else 'n'}, {cols})")
    if not np.isfinite(a).all():
        raise ValueError(f"its {what} array holds NaN or infinite values")
    return a.shape[0]


def check_row(row) -> tuple[str, str]:
    """Raise ValueError naming what is wrong with a bundle's row; return its (stored_file, mesh_file) as the
    catalogue derives them."""
    if not is_sha256(row.sha256):
        raise ValueError("its content address is not 64 hex characters")
    why = name_problem(row.name)
    if why and not (row.name or "").isdigit():
        raise ValueError(f"its name is not usable ({why})")
    ext = Path(row.stored_file or "").suffix.lower()
    if not _EXT.fullmatch(ext):
        raise ValueError("its original file has no usable format suffix")
    stored, mesh = model_files(row.sha256, ext)
    if row.stored_file != stored or row.mesh_file != mesh:
        raise ValueError(f"its file paths ({printable(row.stored_file)[:80]}, {printable(row.mesh_file)[:80]}) are "
                         f"not where a catalogue keeps them ({stored}, {mesh})")
    numbers = {c: getattr(row, c) for c in ("length", "width", "height", "mesh_length", "mesh_width", "mesh_height")}
    for c, v in numbers.items():
        if not isinstance(v, (int, float)) or not math.isfinite(v) or not SIZE_RANGE[0] <= v <= SIZE_RANGE[1]:
            raise ValueError(f"its {c} {v!r} is not a plausible size in metres ({SIZE_RANGE[0]}-{SIZE_RANGE[1]})")
    for c in ("section_res", "sample_spacing"):
        v = getattr(row, c)
        if not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v < 1:
            raise ValueError(f"its {c} {v!r} is out of range")
    if not isinstance(row.n_points, int) or row.n_points < 10:
        raise ValueError(f"its point count {row.n_points!r} is out of range")
    _blob_shape(row.points, 3, "points", rows=row.n_points)
    for b in ("section_longitudinal", "section_transverse"):
        _blob_shape(getattr(row, b), 2, b.replace("_", " "))
    for b in ("section_longitudinal_fine", "section_transverse_fine"):
        if getattr(row, b) is not None:
            _blob_shape(getattr(row, b), 2, b.replace("_", " "))
    try:
        tags = json.loads(row.tags_json or "[]")
        json.loads(row.params_json or "{}")
    except ValueError as exc:
        raise ValueError("its tags or parameters are not JSON") from exc
    if not isinstance(tags, list) or not all(isinstance(t, str) and name_problem(t) is None for t in tags):
        raise ValueError("its tags are not a list of plain words")
    for c in ("make", "model", "body_class", "source_name", "notes"):
        value = getattr(row, c)
        why = text_problem(value) if c in ("make", "model", "body_class") else (
            "it holds a control character" if printable(value or "") != (value or "") else None)
        if why:
            raise ValueError(f"its {c.replace('_', ' ')} is not plain text ({why})")

    try:
        if check_category(row.category) != row.category:
            raise ValueError
    except (ValueError, CatalogueError) as exc:
        raise ValueError(f"its category {printable(str(row.category))[:60]!r} is not a lower-case word") from exc
    if row.source not in ("mesh", "scan") or row.sym_level not in (None, "none", "mirror", "two_mirrors",
                                                                   "rotational"):
        raise ValueError("its source or level of symmetry is not one a catalogue writes")
    return stored, mesh


def check_mesh(path: Path) -> None:
    """Raise ValueError unless ``path`` is a normalised mesh: vertices (n, 3) finite, faces (m, 3) indexing them."""
    with np.load(path, allow_pickle=False) as d:
        v, f = d["vertices"], d["faces"]
        if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all() or len(v) == 0:
            raise ValueError("its mesh's vertices are not (n, 3) finite numbers")
        if f.ndim != 2 or f.shape[1] != 3 or f.dtype.kind not in "iu" or (len(f) and (f.min() < 0 or f.max() >= len(v))):
            raise ValueError("its mesh's faces do not index its vertices")
        if "glass" in d.files and len(d["glass"]) != len(f):
            raise ValueError("its mesh's glass flags do not match its faces")
    # the decimated caches are checked the same way by the caller


def _read_rows(bundle: _Bundle, tmp: Path) -> list:
    """The bundle's rows, from its database upgraded to this twinreg's schema in ``tmp`` (triggers and views the
    stranger's database may hold are dropped first: the upgrade must run only our own SQL)."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session


    db = bundle.extract(DB_NAME, tmp)
    try:
        con = sqlite3.connect(db)
        try:
            con.execute("PRAGMA trusted_schema=OFF")
            for kind, name in con.execute("SELECT type, name FROM sqlite_master WHERE type IN ('trigger', 'view')"
                                          ).fetchall():
                con.execute(f'DROP {kind.upper()} "{name.replace(chr(34), chr(34) * 2)}"')
            con.commit()
        finally:
            con.close()
        engine = make_engine(db)
        try:
            upgrade(engine)  # an older bundle's schema brought to this twinreg's
            with Session(engine) as s:
                rows = list(s.scalars(select(RefModel).order_by(RefModel.id)))
                for r in rows:
                    s.expunge(r)
        finally:
            engine.dispose()
    except BundleError:
        raise
    except Exception as exc:
        first = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
        raise bundle.error(f"its {DB_NAME} is not a twinreg catalogue ({first})") from exc
    seen_sha, seen_name = set(), set()
    for r in rows:
        label = f"model {r.id} '{printable(r.name)[:80]}'"
        try:
            check_row(r)
        except ValueError as exc:
            raise bundle.error(f"{label}: {exc}") from None
        if r.sha256 in seen_sha or r.name in seen_name:
            raise bundle.error(f"{label}: its content or name appears twice in the bundle")
        seen_sha.add(r.sha256)
        seen_name.add(r.name)
    return rows


def _extract_model(bundle: _Bundle, row, tmp: Path) -> list[str]:
    """Extract and check one model's files; returns them (relative paths)."""
    stored, mesh = model_files(row.sha256, Path(row.stored_file).suffix.lower())
    label = f"model '{printable(row.name)[:80]}'"
    for rel in (stored, mesh):
        if not bundle.has(rel):
            raise bundle.error(f"{label}: its file {rel} is not in the bundle")
    if file_sha256(bundle.extract(stored, tmp)) != row.sha256:
        raise bundle.error(f"{label}: its original file does not hash to its content address")
    cached = [n for n in bundle.manifest["members"] if re.fullmatch(rf"meshes/{row.sha256}\.[a-z0-9]{{1,10}}\.npz", n)]
    for rel in [mesh] + cached:
        try:
            check_mesh(bundle.extract(rel, tmp))
        except (ValueError, KeyError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise bundle.error(f"{label}: {rel} is not a usable mesh ({exc})") from None
    return [stored, mesh] + cached


def import_library(catalogue, zip_path, rename: bool = False, skip: bool = False) -> ImportResult:
    """Add a bundle's models to ``catalogue``. Clashing names change nothing unless ``rename`` or ``skip``."""
    from sqlalchemy import select


    zip_path = Path(zip_path)
    if rename and skip:
        raise CatalogueError("--rename and --skip exclude each other; give one")
    result = ImportResult()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bundle = _Bundle(zip_path)
        try:
            incoming = _read_rows(bundle, tmp)
            folder = Path(catalogue.folder)
            catalogue.engine  # created (and upgraded) before the writer lock: the upgrade takes the lock itself
            with writer_lock(folder), catalogue.session() as s:
                names = set(s.scalars(select(RefModel.name)))
                shas = set(s.scalars(select(RefModel.sha256)))
                plan = _plan(incoming, names, shas, result, rename, skip)
                if result.clashes and not (rename or skip):
                    raise CatalogueError(f"{zip_path}: {len(result.clashes)} model name(s) already in {folder} or "
                                         f"all digits ({printable(', '.join(result.clashes[:5]))}); nothing "
                                         "imported; give --rename or --skip")
                files = {r.id: _extract_model(bundle, r, tmp) for r in plan}
                _add_rows(s, plan, files, names, tmp, folder, result)
        finally:
            bundle.close()
    return result


def _plan(incoming, names, shas, result: ImportResult, rename: bool, skip: bool) -> list:
    plan = []
    for r in incoming:
        if r.sha256 in shas:
            result.skipped.append({"name": r.name, "why": "same content already in the catalogue"})
            continue
        if r.name in names or r.name.isdigit():
            result.clashes.append(r.name)
            if skip:
                result.skipped.append({"name": r.name, "why": "name already in the catalogue or all digits"})
                continue
            if not rename:
                continue
        plan.append(r)
    return plan


def _add_rows(s, plan, files: dict, names: set, tmp: Path, folder: Path, result: ImportResult) -> None:
    with undone_on_failure(s) as created:
        for r in plan:
            base = f"model-{r.name}" if r.name.isdigit() else r.name
            new_name, k = base, 2
            while new_name in names:
                new_name, k = f"{base}-{k}", k + 1
            names.add(new_name)
            for rel in files[r.id]:
                if atomic_copy(tmp / rel, folder / rel):
                    created.append(folder / rel)
            data = {c.name: getattr(r, c.name) for c in RefModel.__table__.columns if c.name != "id"}
            data["name"] = new_name
            s.add(RefModel(**data))
            result.added[r.name] = new_name
        s.commit()
