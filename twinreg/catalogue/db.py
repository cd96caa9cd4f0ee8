"""Opening a catalogue folder: the SQLite engine (busy timeout, WAL), a process lock for writers, and the alembic
upgrade to head that every open performs."""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
from importlib.resources import files
from pathlib import Path

from sqlalchemy import create_engine, event, inspect
from sqlalchemy.engine import Engine

from ..errors import CatalogueError
from .models import unpack

DB_NAME = "catalogue.sqlite"
LOCK_NAME = ".lock"
BUSY_TIMEOUT_S = 60


def migrations_dir() -> Path:
    """The alembic script folder: the package ``twinreg.migrations`` (the repository's top-level ``migrations/``,
    mapped into the package by pyproject.toml, installed or editable)."""
    try:
        here = Path(str(files("twinreg.migrations")))
    except ModuleNotFoundError:
        here = Path("__missing__")
    if not (here / "env.py").is_file():
        raise CatalogueError(f"{here}: the catalogue migrations are missing; reinstall twinreg")
    return here


def library_path(path=None) -> Path:
    """``--library`` if given, else ``$TWINREG_LIBRARY``, else ``./library``."""
    if path:
        return Path(path)
    return Path(os.environ.get("TWINREG_LIBRARY", "library"))


@contextlib.contextmanager
def writer_lock(folder: Path):
    """An exclusive advisory lock on the catalogue folder, held by one writing process at a time."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / LOCK_NAME, "a+") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def make_engine(db_file: Path) -> Engine:
    engine = create_engine(f"sqlite:///{db_file}", connect_args={"timeout": BUSY_TIMEOUT_S})

    @event.listens_for(engine, "connect")
    def _pragmas(dbapi_conn, _record):  # pragma: no cover - exercised by every connection
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute(f"PRAGMA busy_timeout={BUSY_TIMEOUT_S * 1000}")
        cur.execute("PRAGMA foreign_keys=ON")
        cur.close()

    return engine


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Run the alembic migrations up to ``revision`` on this engine."""
    from alembic import command
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(migrations_dir()))
    with engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, revision)
        if revision == "head":  # in the upgrade's transaction: killed half-way, the next open upgrades again
            fill_levels(conn)


def current_revision(engine: Engine) -> str | None:
    with engine.connect() as conn:
        if not inspect(conn).has_table("alembic_version"):
            return None
        row = conn.exec_driver_sql("SELECT version_num FROM alembic_version").first()
        return row[0] if row else None


def head_revision() -> str:
    """The newest revision id, read from the revision files (importing alembic costs 0.2 s on every command)."""
    revs, downs = set(), set()
    for f in (migrations_dir() / "versions").glob("*.py"):
        text = f.read_text(encoding="utf-8")
        rev = re.search(r"^revision(?::\s*str)?\s*=\s*['\"]([^'\"]+)['\"]", text, re.M)
        down = re.search(r"^down_revision(?:[^=]*)=\s*['\"]([^'\"]+)['\"]", text, re.M)
        if rev:
            revs.add(rev.group(1))
        if down:
            downs.add(down.group(1))
    heads = revs - downs
    if len(heads) != 1:
        raise CatalogueError(f"the migrations have {len(heads)} heads ({', '.join(sorted(heads))}); merge them")
    return heads.pop()


def _upgrade_to_head(engine: Engine, folder: Path) -> None:
    """Upgrade when the schema is not the head one, checking again under the writer lock: another process may be
    creating or upgrading the same catalogue at this moment (its first read can then even see a locked file)."""
    from sqlalchemy.exc import OperationalError

    head = head_revision()
    try:
        if current_revision(engine) == head:
            return
    except OperationalError:
        pass
    with writer_lock(folder):
        if current_revision(engine) != head:
            upgrade(engine)


def fill_levels(conn) -> int:
    """Measure the level of symmetry of the models that have none (a catalogue from before revision 0005: its
    migration adds the column, the method's live code fills it in the upgrade's transaction) from the surface
    points each holds; how many."""
    from sqlalchemy import text

    from cosco.levels import symmetry_level


    rows = conn.execute(text("SELECT id, points FROM ref_models WHERE sym_level IS NULL")).fetchall()
    for mid, blob in rows:
        conn.execute(text("UPDATE ref_models SET sym_level = :l WHERE id = :i"),
                     {"l": symmetry_level(unpack(blob)).level, "i": mid})
    return len(rows)


def open_engine(folder: Path, create: bool = True) -> Engine:
    """The engine of the catalogue in ``folder``, upgraded to the newest schema.

    Raises :class:`CatalogueError` when the folder cannot be used or the database is not a twinreg catalogue.
    """
    folder = Path(folder)
    db_file = folder / DB_NAME
    if not db_file.exists() and not create:
        raise CatalogueError(f"{folder}: no catalogue here; add a model with `twinreg add-model MESH` first")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CatalogueError(f"{folder}: cannot create the catalogue folder ({exc.strerror})") from exc
    engine = make_engine(db_file)
    try:
        _upgrade_to_head(engine, folder)
    except CatalogueError:
        raise
    except Exception as exc:
        text = str(exc).lower()
        if any(w in text for w in ("disk is full", "disk i/o", "readonly database", "read-only", "unable to open")):
            raise CatalogueError(f"{db_file}: the catalogue cannot be written ({str(exc).splitlines()[0][:120]}); "
                                 "free space on its disk or check that you may write to the folder") from exc
        raise CatalogueError(f"{db_file}: not a usable twinreg catalogue ({type(exc).__name__}: {exc}); "
                             "move it away or point --library elsewhere") from exc
    return engine
