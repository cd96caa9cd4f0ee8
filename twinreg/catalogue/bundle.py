"""Portable catalogues: ``export-library lib.zip`` and ``import-library lib.zip``.

A bundle is a zip holding ``bundle.json`` (the format, the catalogue's schema revision, every member's size and
sha256), ``catalogue.sqlite`` (a consistent copy of the database: rows, sampled clouds, sections, provenance) and
the model files (``files/``: the originals as added; ``meshes/``: the normalised meshes and the decimated ones the
twins use). Import checks every checksum before it touches anything, upgrades an older bundle's schema in a
scratch folder, then adds the rows in one transaction and the files through temporary names: a refused or
failed import leaves the catalogue as it was. Names already in the catalogue are clashes: they are reported and
nothing changes, unless ``rename`` (a free name is taken: ``name-2``) or ``skip`` is asked for; a model whose
content (sha256) is already in the catalogue is left out and reported.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import CatalogueError
from ..outdir import atomic_path
from .db import DB_NAME, current_revision, make_engine, upgrade, writer_lock
from .prepare import file_sha256
from .repository import atomic_copy, undone_on_failure

FORMAT = "twinreg-library"
VERSION = 1


def export_library(catalogue, zip_path) -> dict:
    """Write the catalogue to ``zip_path`` (through a temporary name); returns the bundle's manifest."""
    folder = Path(catalogue.folder)
    if catalogue.count() == 0:
        raise CatalogueError(f"{folder}: the catalogue is empty; nothing to export")
    zip_path = Path(zip_path)
    with tempfile.TemporaryDirectory() as tmp:
        snapshot = Path(tmp) / DB_NAME
        with writer_lock(folder):  # a consistent copy: no writer between the rows and the files
            src = sqlite3.connect(folder / DB_NAME)
            dst = sqlite3.connect(snapshot)
            src.backup(dst)
            src.close()
            dst.execute("PRAGMA journal_mode=DELETE")
            dst.close()
            members = [(snapshot, DB_NAME)] + [(p, p.relative_to(folder).as_posix())
                                                for sub in ("files", "meshes") if (folder / sub).is_dir()
                                                for p in sorted((folder / sub).rglob("*")) if p.is_file()
                                                and ".tmp" not in p.name]
            manifest = {"format": FORMAT, "version": VERSION, "schema_revision": current_revision(catalogue.engine),
                        "n_models": catalogue.count(),
                        "members": {name: {"bytes": p.stat().st_size, "sha256": file_sha256(p)} for p, name in members}}
            with atomic_path(zip_path) as tmp_zip:
                with zipfile.ZipFile(tmp_zip, "w", zipfile.ZIP_STORED) as z:
                    z.writestr("bundle.json", json.dumps(manifest, indent=1))
                    for p, name in members:
                        z.write(p, name)
    return manifest


@dataclass
class ImportResult:
    """What an import did: names added (bundle name -> stored name), left out (with why), clashes found."""

    added: dict = field(default_factory=dict)
    skipped: list = field(default_factory=list)
    clashes: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"added": self.added, "skipped": self.skipped, "clashes": self.clashes}


def _verified(zip_path: Path, into: Path) -> dict:
    """Extract the bundle into ``into`` after checking it; returns its manifest. Raises CatalogueError naming
    the first fault."""
    try:
        z = zipfile.ZipFile(zip_path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise CatalogueError(f"{zip_path}: not a twinreg library bundle ({exc}); export one with "
                             "`twinreg export-library FILE.zip`") from exc
    with z:
        try:
            manifest = json.loads(z.read("bundle.json"))
        except (KeyError, ValueError) as exc:
            raise CatalogueError(f"{zip_path}: no readable bundle.json; not a twinreg library bundle") from exc
        if manifest.get("format") != FORMAT or manifest.get("version", 99) > VERSION:
            raise CatalogueError(f"{zip_path}: bundle format {manifest.get('format')} v{manifest.get('version')} "
                                 f"is not one this twinreg reads ({FORMAT} v{VERSION}); update twinreg")
        names = set(z.namelist()) - {"bundle.json"}
        expected = manifest.get("members", {})
        if names != set(expected):
            extra = sorted(names ^ set(expected))[:3]
            raise CatalogueError(f"{zip_path}: its members do not match bundle.json ({', '.join(extra)}); the file "
                                 "is damaged, export it again")
        for name, info in expected.items():
            if ".." in Path(name).parts or name.startswith("/"):
                raise CatalogueError(f"{zip_path}: member {name} points outside the catalogue; refused")
            h = hashlib.sha256()
            try:
                with z.open(name) as fh:
                    for chunk in iter(lambda: fh.read(1 << 20), b""):
                        h.update(chunk)
            except (zipfile.BadZipFile, OSError, EOFError) as exc:
                raise CatalogueError(f"{zip_path}: member {name} cannot be read ({exc}); the file is damaged, "
                                     "export it again") from exc
            if h.hexdigest() != info["sha256"]:
                raise CatalogueError(f"{zip_path}: member {name} fails its checksum; the file is damaged, export it "
                                     "again")
        z.extractall(into)
    return manifest


def import_library(catalogue, zip_path, rename: bool = False, skip: bool = False) -> ImportResult:
    """Add a bundle's models to ``catalogue``. Clashing names change nothing unless ``rename`` or ``skip``."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from .models import RefModel

    zip_path = Path(zip_path)
    if rename and skip:
        raise CatalogueError("--rename and --skip exclude each other; give one")
    result = ImportResult()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _verified(zip_path, tmp)
        engine = make_engine(tmp / DB_NAME)
        try:
            upgrade(engine)  # an older bundle's schema brought to this twinreg's
            with Session(engine) as s:
                incoming = list(s.scalars(select(RefModel).order_by(RefModel.id)))
                for r in incoming:
                    s.expunge(r)
        finally:
            engine.dispose()
        folder = Path(catalogue.folder)
        with writer_lock(folder), catalogue.session() as s:
            names = set(s.scalars(select(RefModel.name)))
            shas = set(s.scalars(select(RefModel.sha256)))
            plan = []
            for r in incoming:
                if r.sha256 in shas:
                    result.skipped.append({"name": r.name, "why": "same content already in the catalogue"})
                    continue
                if r.name in names:
                    result.clashes.append(r.name)
                    if skip:
                        result.skipped.append({"name": r.name, "why": "name already in the catalogue"})
                        continue
                    if not rename:
                        continue
                plan.append(r)
            if result.clashes and not (rename or skip):
                raise CatalogueError(f"{zip_path}: {len(result.clashes)} model name(s) already in {folder} "
                                     f"({', '.join(result.clashes[:5])}); nothing imported; give --rename or --skip")
            with undone_on_failure(s) as created:
                for r in plan:
                    new_name = r.name
                    k = 2
                    while new_name in names:
                        new_name, k = f"{r.name}-{k}", k + 1
                    names.add(new_name)
                    for rel in _files_of(tmp, r):
                        if atomic_copy(tmp / rel, folder / rel):
                            created.append(folder / rel)
                    data = {c.name: getattr(r, c.name) for c in RefModel.__table__.columns if c.name != "id"}
                    data["name"] = new_name
                    s.add(RefModel(**data))
                    result.added[r.name] = new_name
                s.commit()
    return result


def _files_of(root: Path, row) -> list[str]:
    """The bundle's files of one model: its original, its normalised mesh and its cached decimated meshes."""
    out = [row.stored_file, row.mesh_file]
    out += [p.relative_to(root).as_posix() for p in sorted((root / "meshes").glob(f"{row.sha256}.*.npz"))]
    return [f for f in out if (root / f).is_file()]
