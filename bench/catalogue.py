"""The catalogue: one SQLite file holding campaigns, runs, points, readings, calibrations and the run journal.

Research note ``anchors-orchestration.md``, lessons 3–5:

* **One writer.** The run engine is the only process that writes. A writer holds an exclusive lock on
  ``<db>.lock`` for as long as it is open, so a second writer (a CLI run started beside the server) is
  refused instead of racing it. The lock dies with its process, which is what makes
  :meth:`Catalogue.mark_interrupted_runs` safe: when a writer opens, no live process can own a running run.
  The dashboard and the CLI read through ``Catalogue(path, readonly=True)`` (a ``mode=ro`` connection).
* **WAL journal.** Readers never block the writer and see every committed transaction. ``synchronous=NORMAL``
  keeps every commit across a killed process (only a power cut can lose the last commits, never corrupt).
* **Whole points.** :meth:`Catalogue.record_point` stores a point and all its readings in one transaction,
  so a crash leaves whole points or nothing, and a resume re-measures exactly the missing keys.
* **Honest provenance.** A run carries its plan, arguments and provenance (config hash, software version,
  device identities, simulated or not, operator). A resume is a *new* run linked by ``parent_run_id``; old
  runs are never rewritten except for their status.
* **Bulk data beside, not inside.** Frames are files under ``<db stem>-frames/run-<id>/``; readings keep
  their path relative to that ``<db stem>-frames`` folder (``run-3/grid_p12.npz``), so the database and
  its frames move together.
* **Versioned schema.** ``PRAGMA user_version`` is the schema version; :data:`_MIGRATIONS` maps each version
  to the statements that reach it from the one before, applied in one transaction per open. A file written
  by a newer sunbench is refused.

Every refusal is a :class:`CatalogueError` whose message names the problem. Every method returns plain
dicts (JSON-ready), but :meth:`Catalogue.readings`, whose typed records (:class:`bench.descriptor.ReadingRecord`)
carry any family's values: a column ``<name>_json`` comes back parsed under ``<name>``; timestamps are ISO 8601
UTC strings (``2026-05-09T07:35:25.123456Z``), which sort as text.

Threads: one :class:`Catalogue` object may be shared by the writer thread and others (an internal lock
serialises every statement), but a thread that reads a lot should open its own read-only catalogue.
"""

from __future__ import annotations

import datetime as dt
import functools
import json
import math
import os
import sqlite3
import sys
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import Any

from .descriptor import DescriptorError, ReadingDescriptor, ReadingRecord

try:  # the single-writer lock; without fcntl (Windows) the rule is only documented
    import fcntl
except ImportError:  # pragma: no cover - not on the Linux/macOS benches
    fcntl = None

__all__ = [
    "CAMPAIGN_STATUSES", "QUEUE_STATUSES", "RUN_STATUSES", "LIVE_RUN_STATUSES", "TERMINAL_RUN_STATUSES",
    "REQUIRED_PROVENANCE", "READING_FIELDS", "SCHEMA_VERSION", "Catalogue", "CatalogueError",
]

APPLICATION_ID = 0x53554E42  # "SUNB" in the database header: tells our files from any other SQLite file

CAMPAIGN_STATUSES = ("created", "running", "paused", "completed", "aborted", "failed")
QUEUE_STATUSES = ("queued", "running", "done", "failed")
RUN_STATUSES = ("created", "running", "paused", "suspended", "completed", "aborted", "failed", "crashed")
LIVE_RUN_STATUSES = ("running", "paused", "suspended")  # a process is (or was) driving the bench
TERMINAL_RUN_STATUSES = ("completed", "aborted", "failed", "crashed")

# Which statuses a run may move to from each status. A finished run stays finished (a resume is a new run),
# nothing goes back to "created", and only a run that had started can pause, be suspended or crash.
_RUN_TRANSITIONS = {
    "created": {"running", "completed", "aborted", "failed"},
    "running": {"paused", "suspended", "completed", "aborted", "failed", "crashed"},
    "paused": {"running", "suspended", "completed", "aborted", "failed", "crashed"},
    "suspended": {"running", "paused", "completed", "aborted", "failed", "crashed"},
    "completed": set(), "aborted": set(), "failed": set(), "crashed": set(),
}

# The start document must say where the data came from (research note, lesson 4).
REQUIRED_PROVENANCE = ("bench_config_hash", "software_version", "devices", "simulated", "operator")

# Fields every family's reading has, as record_point() takes them, with their defaults (None: SQL NULL); any
# other key of a reading is a field of the run's family, checked against the run's descriptor.
READING_FIELDS = {"repeat": None, "status": "ok", "frame_path": None, "t_s": None}

# The reading of schema version 1, which knew only the CMOS pinhole family: its runs get this descriptor when
# version 2 moves their spot columns into ``values_json`` (a fact of history, kept as it was written; the
# family's current descriptor is bench.families.cmos.DESCRIPTOR).
V1_CMOS_DESCRIPTOR = {"family": "cmos", "version": 1, "fields": [
    {"name": "x_px", "dtype": "number", "unit": "px", "shape": [], "required": True, "doc": "spot centre, column"},
    {"name": "y_px", "dtype": "number", "unit": "px", "shape": [], "required": True, "doc": "spot centre, row"},
    {"name": "peak_dn", "dtype": "number", "unit": "DN", "shape": [], "required": False, "doc": "brightest pixel"},
    {"name": "n_pixels", "dtype": "integer", "unit": "", "shape": [], "required": False,
     "doc": "pixels in the spot"},
    {"name": "flags", "dtype": "integer", "unit": "", "shape": [], "required": False,
     "doc": "calibration.centroid.SpotFlag bits"}]}

_POINT_FIELDS = ("azimuth_deg", "zenith_stage_deg", "zenith_deg", "azimuth_body_deg")


def _command_line() -> str:
    """``sunbench serve``: the program and its command, for the writer lock's note."""
    argv = sys.argv or ["python"]
    return " ".join([Path(argv[0]).name, *argv[1:2]])


def _in(values) -> str:
    return "(" + ", ".join(repr(v) for v in values) + ")"


def _move_v1_readings(conn: sqlite3.Connection) -> None:
    """Schema 2: version 1's spot columns into each reading's values, as JSON that keeps every float exactly
    (SQLite's json_object() writes 15 significant digits: a centroid would lose its last bits)."""
    rows = conn.execute("SELECT id, point_id, repeat, status, frame_path, t_s, x_px, y_px, peak_dn, n_pixels, flags "
                        "FROM readings ORDER BY id").fetchall()
    conn.executemany(
        "INSERT INTO readings_v2 (id, point_id, repeat, status, frame_path, t_s, values_json) "
        "VALUES (?, ?, ?, ?, ?, ?, ?)",
        [(*tuple(r)[:6], json.dumps(dict(zip(("x_px", "y_px", "peak_dn", "n_pixels", "flags"), tuple(r)[6:]))))
         for r in rows])


# --- schema ---------------------------------------------------------------------------------------------
# _MIGRATIONS[v] takes a file from version v-1 to version v: SQL statements, or a function of the connection for
# a step SQL cannot do exactly. Never edit a released entry: add the next one
# (ALTER TABLE, new tables, data moves), so old files upgrade in place when a newer sunbench opens them.
_MIGRATIONS: dict[int, tuple] = {
    1: (
        """CREATE TABLE schema_history (
            version INTEGER PRIMARY KEY,
            applied_utc TEXT NOT NULL
        )""",
        f"""CREATE TABLE campaigns (
            id INTEGER PRIMARY KEY,
            name TEXT NOT NULL CHECK (name <> ''),
            plan TEXT NOT NULL,
            spec_json TEXT NOT NULL,
            created_utc TEXT NOT NULL,
            status TEXT NOT NULL DEFAULT 'created' CHECK (status IN {_in(CAMPAIGN_STATUSES)})
        )""",
        f"""CREATE TABLE runs (
            id INTEGER PRIMARY KEY,
            campaign_id INTEGER REFERENCES campaigns(id),
            parent_run_id INTEGER REFERENCES runs(id),
            sensor_id TEXT NOT NULL CHECK (sensor_id <> ''),
            plan_name TEXT NOT NULL,
            plan_args_json TEXT NOT NULL,
            status TEXT NOT NULL DEFAULT 'created' CHECK (status IN {_in(RUN_STATUSES)}),
            exit_reason TEXT,
            created_utc TEXT NOT NULL,
            started_utc TEXT,
            ended_utc TEXT,
            n_points_planned INTEGER CHECK (n_points_planned IS NULL OR n_points_planned >= 0),
            provenance_json TEXT NOT NULL
        )""",
        "CREATE INDEX runs_by_campaign ON runs(campaign_id)",
        "CREATE INDEX runs_by_parent ON runs(parent_run_id)",
        "CREATE INDEX runs_by_status ON runs(status)",
        f"""CREATE TABLE fleet_queue (
            campaign_id INTEGER NOT NULL REFERENCES campaigns(id),
            position INTEGER NOT NULL CHECK (position >= 0),
            sensor_id TEXT NOT NULL CHECK (sensor_id <> ''),
            status TEXT NOT NULL DEFAULT 'queued' CHECK (status IN {_in(QUEUE_STATUSES)}),
            run_id INTEGER REFERENCES runs(id),
            updated_utc TEXT NOT NULL,
            PRIMARY KEY (campaign_id, position),
            UNIQUE (campaign_id, sensor_id)
        )""",
        """CREATE TABLE points (
            id INTEGER PRIMARY KEY,
            run_id INTEGER NOT NULL REFERENCES runs(id),
            key TEXT NOT NULL CHECK (key <> ''),
            stage TEXT NOT NULL,
            azimuth_deg REAL NOT NULL,
            zenith_stage_deg REAL NOT NULL,
            zenith_deg REAL NOT NULL,
            azimuth_body_deg REAL NOT NULL,
            exposure_ms REAL CHECK (exposure_ms IS NULL OR exposure_ms > 0),
            started_utc TEXT,
            completed_utc TEXT NOT NULL,
            UNIQUE (run_id, key)
        )""",
        # An "ok" reading has a centroid; a failed one keeps its error name in status and NULL coordinates.
        """CREATE TABLE readings (
            id INTEGER PRIMARY KEY,
            point_id INTEGER NOT NULL REFERENCES points(id),
            repeat INTEGER NOT NULL CHECK (repeat >= 0),
            x_px REAL,
            y_px REAL,
            peak_dn REAL,
            n_pixels INTEGER CHECK (n_pixels IS NULL OR n_pixels >= 0),
            flags INTEGER NOT NULL DEFAULT 0,
            status TEXT NOT NULL CHECK (status <> ''),
            frame_path TEXT,
            t_s REAL NOT NULL,
            UNIQUE (point_id, repeat),
            CHECK (status <> 'ok' OR (x_px IS NOT NULL AND y_px IS NOT NULL))
        )""",
        """CREATE TABLE calibrations (
            id INTEGER PRIMARY KEY,
            run_id INTEGER NOT NULL REFERENCES runs(id),
            method TEXT NOT NULL CHECK (method <> ''),
            document_json TEXT NOT NULL,
            metrics_json TEXT NOT NULL,
            chosen INTEGER NOT NULL DEFAULT 0 CHECK (chosen IN (0, 1)),
            created_utc TEXT NOT NULL
        )""",
        "CREATE INDEX calibrations_by_run ON calibrations(run_id)",
        # The database itself keeps "one chosen calibration per run", whatever the code above it does.
        "CREATE UNIQUE INDEX calibrations_one_chosen ON calibrations(run_id) WHERE chosen = 1",
        """CREATE TABLE events (
            id INTEGER PRIMARY KEY,
            run_id INTEGER REFERENCES runs(id),
            t_utc TEXT NOT NULL,
            kind TEXT NOT NULL CHECK (kind <> ''),
            message TEXT NOT NULL,
            data_json TEXT
        )""",
        "CREATE INDEX events_by_run ON events(run_id, id)",
        """CREATE TABLE run_values (
            run_id INTEGER NOT NULL REFERENCES runs(id),
            key TEXT NOT NULL CHECK (key <> ''),
            value_json TEXT NOT NULL,
            updated_utc TEXT NOT NULL,
            PRIMARY KEY (run_id, key)
        )""",
    ),
    # Sensor families: a run says which family it measured and carries its reading descriptor; readings keep
    # the fields every family shares as columns and the family's own values as JSON (bench.descriptor).
    2: (
        "ALTER TABLE runs ADD COLUMN family TEXT NOT NULL DEFAULT 'cmos' CHECK (family <> '')",
        "ALTER TABLE runs ADD COLUMN descriptor_json TEXT",
        f"UPDATE runs SET descriptor_json = '{json.dumps(V1_CMOS_DESCRIPTOR)}'",
        """CREATE TABLE readings_v2 (
            id INTEGER PRIMARY KEY,
            point_id INTEGER NOT NULL REFERENCES points(id),
            repeat INTEGER NOT NULL CHECK (repeat >= 0),
            status TEXT NOT NULL CHECK (status <> ''),
            frame_path TEXT,
            t_s REAL NOT NULL,
            values_json TEXT NOT NULL,
            UNIQUE (point_id, repeat)
        )""",
        _move_v1_readings,
        "DROP TABLE readings",
        "ALTER TABLE readings_v2 RENAME TO readings",
        "CREATE INDEX runs_by_family ON runs(family)",
    ),
}
SCHEMA_VERSION = max(_MIGRATIONS)


class CatalogueError(Exception):
    """The catalogue refused something; the message names the problem (and the file when it matters)."""


def utc_now() -> str:
    """The current time as an ISO 8601 UTC string with microseconds and a ``Z``."""
    return _iso(dt.datetime.now(dt.UTC))


def _iso(moment: dt.datetime) -> str:
    if moment.tzinfo is None:
        raise CatalogueError(f"timestamp {moment.isoformat()} has no time zone; pass an aware UTC datetime")
    return moment.astimezone(dt.UTC).isoformat(timespec="microseconds").replace("+00:00", "Z")


def _json_default(value):
    # numpy scalars and arrays, paths: what calibration code naturally hands over
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _dumps(value, what: str) -> str:
    # allow_nan=False: NaN is not JSON and would break the dashboard's parser; say None instead
    try:
        return json.dumps(value, default=_json_default, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise CatalogueError(f"{what} cannot be stored as JSON: {exc}") from None


def _row(row: sqlite3.Row | None) -> dict | None:
    """A row as a dict; ``<name>_json`` columns parsed under ``<name>``; ``chosen`` as a bool."""
    if row is None:
        return None
    out = {}
    for name in row.keys():
        value = row[name]
        if name.endswith("_json"):
            out[name[:-5]] = None if value is None else json.loads(value)
        elif name == "chosen":
            out[name] = bool(value)
        else:
            out[name] = value
    return out


def _run_ids(run_ids: int | Iterable[int]) -> list[int]:
    ids = [run_ids] if isinstance(run_ids, int) else list(run_ids)
    for run_id in ids:
        if not isinstance(run_id, int) or isinstance(run_id, bool):
            raise CatalogueError(f"run ids are integers, not {run_id!r}")
    return ids


@functools.lru_cache(maxsize=16)
def _descriptor(descriptor_json: str) -> ReadingDescriptor:
    """A run's reading descriptor from its stored JSON, parsed once, not for every point recorded."""
    return ReadingDescriptor.from_json(json.loads(descriptor_json))


def _placeholders(n: int) -> str:
    return ", ".join("?" * n)


def _finite(value, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise CatalogueError(f"{what} must be a number, not {value!r}") from None
    if not math.isfinite(number):
        raise CatalogueError(f"{what} must be finite, not {number}")
    return number


class Catalogue:
    """The SQLite catalogue of a bench.

    Parameters
    ----------
    path : str or os.PathLike
        The database file. For a writer it and its parent folders are created when missing; a reader needs
        an existing catalogue.
    readonly : bool
        Open a ``mode=ro`` connection that never writes (the dashboard, the CLI's listings). Writes through
        it fail in SQLite and come back as :class:`CatalogueError`.

    Raises
    ------
    CatalogueError
        The file is not a sunbench catalogue, was written by a newer sunbench (its schema version is higher
        than :data:`SCHEMA_VERSION`), is missing (read-only), or another process holds it open for writing.

    Notes
    -----
    Use it as a context manager or call :meth:`close`.
    """

    def __init__(self, path, *, readonly: bool = False):
        self.path = Path(path).absolute()
        self.readonly = bool(readonly)
        self._lock = threading.RLock()
        self._lock_file = None
        self._conn: sqlite3.Connection | None = None
        try:
            if self.readonly:
                self._open_reader()
            else:
                self._open_writer()
        except BaseException:
            self.close()
            raise

    # --- opening ----------------------------------------------------------------------------------------
    def _connect(self, target: str, *, uri: bool) -> sqlite3.Connection:
        try:
            # isolation_level=None: we issue BEGIN/COMMIT ourselves, so a transaction is exactly what we say
            conn = sqlite3.connect(target, uri=uri, timeout=10.0, isolation_level=None, check_same_thread=False)
        except sqlite3.Error as exc:
            raise CatalogueError(f"{self.path}: cannot open the catalogue: {exc}") from None
        conn.row_factory = sqlite3.Row
        return conn

    def _open_reader(self) -> None:
        if not self.path.is_file():
            raise CatalogueError(f"{self.path}: no catalogue there (a reader does not create one)")
        self._conn = self._connect(self.path.as_uri() + "?mode=ro", uri=True)
        try:
            self._conn.execute("PRAGMA query_only = ON")
            self._conn.execute("PRAGMA foreign_keys = ON")
            version = self._check_header()
        except sqlite3.Error as exc:
            raise CatalogueError(f"{self.path}: not a readable SQLite catalogue: {exc}") from None
        if version < SCHEMA_VERSION:
            raise CatalogueError(f"{self.path}: catalogue schema version {version} is older than this sunbench's "
                                 f"{SCHEMA_VERSION}; open it once for writing (start the bench) to upgrade it")

    def _open_writer(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._take_writer_lock()
        self._conn = self._connect(str(self.path), uri=False)
        try:
            version = self._check_header()  # before any write: a file that is not ours stays untouched
            mode = self._conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise CatalogueError(f"{self.path}: SQLite refused WAL journal mode (got {mode!r}); keep the "
                                     "catalogue on a local disk")
            # NORMAL in WAL: a commit survives a killed process; only an OS crash may lose the last ones
            self._conn.execute("PRAGMA synchronous = NORMAL")
            self._conn.execute("PRAGMA foreign_keys = ON")
            if version < SCHEMA_VERSION:
                self._migrate(version)
        except sqlite3.Error as exc:
            raise CatalogueError(f"{self.path}: not a usable SQLite catalogue: {exc}") from None

    def _take_writer_lock(self) -> None:
        if fcntl is None:  # pragma: no cover
            return
        lock_path = self._lock_path(self.path)
        handle = open(lock_path, "a+")
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            handle.close()
            # said to whoever typed the command: what holds the bench and what they can do meanwhile
            raise CatalogueError(
                f"{self.path} is in use by {holder}, which drives the bench (a catalogue has one writer). "
                "Queue campaigns and resume runs on that server's dashboard, or stop it first; "
                "`sunbench runs`, `show`, `export`, `fleet` and `run --dry-run` work meanwhile") from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} ({_command_line()})\n")
        handle.flush()
        self._lock_file = handle

    @staticmethod
    def _lock_path(path: Path) -> Path:
        return path.with_name(path.name + ".lock")

    @classmethod
    def writer(cls, path) -> str | None:
        """Who holds the catalogue at `path` open for writing (``pid 123 (sunbench serve)``), or None."""
        lock_path = cls._lock_path(Path(path).absolute())
        if fcntl is None or not lock_path.is_file():
            return None
        with open(lock_path) as handle:
            try:  # a shared lock is refused only while a writer holds the exclusive one
                fcntl.flock(handle.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
            except OSError:
                return handle.read().strip() or "another process"
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
        return None

    def _check_header(self) -> int:
        """The file's schema version, after making sure the file is ours and not from a newer sunbench."""
        version = self._conn.execute("PRAGMA user_version").fetchone()[0]
        app_id = self._conn.execute("PRAGMA application_id").fetchone()[0]
        if version == 0 and app_id == 0:
            n_objects = self._conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
            if n_objects:
                raise CatalogueError(f"{self.path}: an SQLite database that is not a sunbench catalogue")
            if self.readonly:
                raise CatalogueError(f"{self.path}: an empty database, not a sunbench catalogue yet")
            return 0
        if app_id != APPLICATION_ID:
            raise CatalogueError(f"{self.path}: an SQLite database of another application "
                                 f"(application_id {app_id:#x}), not a sunbench catalogue")
        if version > SCHEMA_VERSION:
            raise CatalogueError(f"{self.path}: catalogue schema version {version} is newer than the version "
                                 f"{SCHEMA_VERSION} this sunbench knows; upgrade sunbench to open it")
        return version

    def _migrate(self, version: int) -> None:
        # One transaction for all steps: a failed upgrade leaves the file as it was.
        with self._write(f"upgrade the schema from version {version} to {SCHEMA_VERSION}") as conn:
            for target in range(version + 1, SCHEMA_VERSION + 1):
                for statement in _MIGRATIONS[target]:
                    if callable(statement):
                        statement(conn)
                    else:
                        conn.execute(statement)
                conn.execute("INSERT INTO schema_history (version, applied_utc) VALUES (?, ?)", (target, utc_now()))
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")

    # --- life cycle -------------------------------------------------------------------------------------
    def close(self) -> None:
        """Close the connection and release the writer lock. Closing twice is harmless."""
        with self._lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None
            if self._lock_file is not None:
                self._lock_file.close()  # closing the file releases the flock
                self._lock_file = None

    def __enter__(self) -> Catalogue:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Catalogue({str(self.path)!r}, readonly={self.readonly})"

    @property
    def schema_version(self) -> int:
        """The schema version of the open file (``PRAGMA user_version``)."""
        return self._one("PRAGMA user_version")[0]

    # --- statements -------------------------------------------------------------------------------------
    def _connection(self) -> sqlite3.Connection:
        if self._conn is None:
            raise CatalogueError(f"{self.path}: the catalogue is closed")
        return self._conn

    @contextmanager
    def _write(self, what: str) -> Iterator[sqlite3.Connection]:
        """One write transaction, all or nothing; sqlite errors become :class:`CatalogueError` naming `what`.

        BEGIN IMMEDIATE takes the write lock up front, so a transaction never fails half-way for lock reasons.
        """
        with self._lock:
            conn = self._connection()
            try:
                conn.execute("BEGIN IMMEDIATE")
                yield conn
                conn.execute("COMMIT")
            except BaseException as exc:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                if isinstance(exc, sqlite3.Error):
                    raise CatalogueError(f"{self.path}: cannot {what}: {exc}") from exc
                raise

    def _all(self, sql: str, params=()) -> list[sqlite3.Row]:
        with self._lock:
            try:
                return self._connection().execute(sql, params).fetchall()
            except sqlite3.Error as exc:
                raise CatalogueError(f"{self.path}: query failed: {exc}") from exc

    def _one(self, sql: str, params=()) -> sqlite3.Row | None:
        rows = self._all(sql, params)
        return rows[0] if rows else None

    def _run_row(self, conn: sqlite3.Connection, run_id: int) -> sqlite3.Row:
        row = conn.execute("SELECT id, status, sensor_id, campaign_id, started_utc, descriptor_json "
                           "FROM runs WHERE id = ?", (run_id,)).fetchone()
        if row is None:
            raise CatalogueError(f"no run {run_id}")
        return row

    def _campaign_exists(self, conn: sqlite3.Connection, campaign_id: int) -> None:
        if conn.execute("SELECT 1 FROM campaigns WHERE id = ?", (campaign_id,)).fetchone() is None:
            raise CatalogueError(f"no campaign {campaign_id}")

    def _event(self, conn, run_id, kind, message, data=None) -> int:
        cursor = conn.execute("INSERT INTO events (run_id, t_utc, kind, message, data_json) VALUES (?, ?, ?, ?, ?)",
                              (run_id, utc_now(), kind, message, None if data is None else _dumps(data, "event data")))
        return cursor.lastrowid

    # --- campaigns --------------------------------------------------------------------------------------
    def create_campaign(self, name: str, plan: str, spec: dict) -> int:
        """Create a campaign.

        Parameters
        ----------
        name : str
            Shown to people; need not be unique.
        plan : str
            Name of the plan every run of the campaign follows.
        spec : dict
            The campaign's full specification (plan arguments, sensors, options), stored as JSON.

        Returns
        -------
        int
            The campaign id.
        """
        if not isinstance(spec, dict):
            raise CatalogueError(f"campaign spec must be a dict, not {type(spec).__name__}")
        spec_json = _dumps(spec, "campaign spec")
        with self._write(f"create campaign {name!r}") as conn:
            return conn.execute("INSERT INTO campaigns (name, plan, spec_json, created_utc) VALUES (?, ?, ?, ?)",
                                (name, plan, spec_json, utc_now())).lastrowid

    def campaign(self, campaign_id: int) -> dict:
        """One campaign: ``id, name, plan, spec, created_utc, status``. Raises "no campaign N"."""
        row = _row(self._one("SELECT * FROM campaigns WHERE id = ?", (campaign_id,)))
        if row is None:
            raise CatalogueError(f"no campaign {campaign_id}")
        return row

    def campaigns(self) -> list[dict]:
        """Every campaign, oldest first, each with ``n_runs`` (runs linked to it)."""
        return [_row(r) for r in self._all(
            "SELECT c.*, (SELECT count(*) FROM runs WHERE campaign_id = c.id) AS n_runs "
            "FROM campaigns c ORDER BY c.id")]

    def set_campaign_status(self, campaign_id: int, status: str) -> None:
        """Set a campaign's status, one of :data:`CAMPAIGN_STATUSES`."""
        if status not in CAMPAIGN_STATUSES:
            raise CatalogueError(f"unknown campaign status {status!r}; expected one of {', '.join(CAMPAIGN_STATUSES)}")
        with self._write(f"set campaign {campaign_id} status") as conn:
            self._campaign_exists(conn, campaign_id)
            conn.execute("UPDATE campaigns SET status = ? WHERE id = ?", (status, campaign_id))

    # --- fleet queue ------------------------------------------------------------------------------------
    def enqueue_sensors(self, campaign_id: int, sensor_ids: Iterable[str]) -> list[int]:
        """Append sensors to a campaign's queue, in the given order, with status "queued".

        Returns
        -------
        list of int
            Their positions in the queue (0-based, continuing after the sensors already queued).

        Raises
        ------
        CatalogueError
            No such campaign, an empty sensor id, or a sensor already in this campaign's queue.
        """
        sensor_ids = list(sensor_ids)
        for sensor_id in sensor_ids:
            if not isinstance(sensor_id, str) or not sensor_id:
                raise CatalogueError(f"sensor ids are non-empty strings, not {sensor_id!r}")
        repeated = sorted({s for s in sensor_ids if sensor_ids.count(s) > 1})
        if repeated:
            raise CatalogueError(f"sensor {', '.join(repeated)} listed twice")
        with self._write(f"enqueue sensors in campaign {campaign_id}") as conn:
            self._campaign_exists(conn, campaign_id)
            queued = {r[0] for r in conn.execute("SELECT sensor_id FROM fleet_queue WHERE campaign_id = ?",
                                                 (campaign_id,))}
            already = [s for s in sensor_ids if s in queued]
            if already:
                raise CatalogueError(f"sensor {', '.join(already)} already in campaign {campaign_id}'s queue")
            start = conn.execute("SELECT coalesce(max(position) + 1, 0) FROM fleet_queue WHERE campaign_id = ?",
                                 (campaign_id,)).fetchone()[0]
            now = utc_now()
            positions = list(range(start, start + len(sensor_ids)))
            conn.executemany("INSERT INTO fleet_queue (campaign_id, position, sensor_id, updated_utc) "
                             "VALUES (?, ?, ?, ?)",
                             [(campaign_id, p, s, now) for p, s in zip(positions, sensor_ids)])
            return positions

    def next_queued_sensor(self, campaign_id: int) -> str | None:
        """The first sensor of the queue still "queued", or None when none is left."""
        row = self._one("SELECT sensor_id FROM fleet_queue WHERE campaign_id = ? AND status = 'queued' "
                        "ORDER BY position LIMIT 1", (campaign_id,))
        return None if row is None else row[0]

    def queued_run(self, campaign_id: int, sensor_id: str) -> int | None:
        """The run last linked to a sensor of the queue (the one to resume after a crash), or None."""
        row = self._one("SELECT run_id FROM fleet_queue WHERE campaign_id = ? AND sensor_id = ?",
                        (campaign_id, sensor_id))
        if row is None:
            raise CatalogueError(f"sensor {sensor_id} is not in campaign {campaign_id}'s queue")
        return row[0]

    def set_queue_status(self, campaign_id: int, sensor_id: str, status: str, run_id: int | None = None) -> None:
        """Set a queued sensor's status (one of :data:`QUEUE_STATUSES`) and, when given, link its run.

        Parameters
        ----------
        run_id : int, optional
            The run measuring this sensor; it must be of this sensor (and of this campaign when it has one).
            None keeps the run already linked.
        """
        if status not in QUEUE_STATUSES:
            raise CatalogueError(f"unknown queue status {status!r}; expected one of {', '.join(QUEUE_STATUSES)}")
        with self._write(f"set queue status of {sensor_id} in campaign {campaign_id}") as conn:
            if conn.execute("SELECT 1 FROM fleet_queue WHERE campaign_id = ? AND sensor_id = ?",
                            (campaign_id, sensor_id)).fetchone() is None:
                raise CatalogueError(f"sensor {sensor_id} is not in campaign {campaign_id}'s queue")
            if run_id is not None:
                run = self._run_row(conn, run_id)
                if run["sensor_id"] != sensor_id:
                    raise CatalogueError(f"run {run_id} measures sensor {run['sensor_id']}, not {sensor_id}")
                if run["campaign_id"] not in (None, campaign_id):
                    raise CatalogueError(f"run {run_id} belongs to campaign {run['campaign_id']}, not {campaign_id}")
            conn.execute("UPDATE fleet_queue SET status = ?, run_id = coalesce(?, run_id), updated_utc = ? "
                         "WHERE campaign_id = ? AND sensor_id = ?", (status, run_id, utc_now(), campaign_id, sensor_id))

    def fleet(self, campaign_id: int) -> list[dict]:
        """The campaign's queue in order, joined with each sensor's run and its chosen calibration.

        Returns
        -------
        list of dict
            ``position, sensor_id, status`` (queue), ``updated_utc, run_id, run_status, exit_reason,
            n_points_planned, n_points_recorded, calibration_id, method, metrics`` (None where there is no run
            or no chosen calibration yet).
        """
        rows = self._all(
            """SELECT q.position, q.sensor_id, q.status, q.updated_utc, q.run_id,
                      r.status AS run_status, r.exit_reason, r.n_points_planned,
                      (SELECT count(*) FROM points p WHERE p.run_id = q.run_id) AS n_points_recorded,
                      c.id AS calibration_id, c.method, c.metrics_json
               FROM fleet_queue q
               LEFT JOIN runs r ON r.id = q.run_id
               LEFT JOIN calibrations c ON c.run_id = q.run_id AND c.chosen = 1
               WHERE q.campaign_id = ? ORDER BY q.position""", (campaign_id,))
        if not rows:
            self.campaign(campaign_id)  # "no campaign N" rather than an empty fleet
        return [_row(r) for r in rows]

    # --- runs -------------------------------------------------------------------------------------------
    def create_run(self, *, campaign_id: int | None, sensor_id: str, plan_name: str, plan_args: dict,
                   provenance: dict, descriptor: ReadingDescriptor, parent_run_id: int | None = None,
                   n_points_planned: int | None = None) -> int:
        """Create a run in status "created" and journal it.

        Parameters
        ----------
        campaign_id : int or None
            The campaign it belongs to; None for a stand-alone run.
        sensor_id : str
            Serial of the sensor under test.
        plan_name : str
        plan_args : dict
            The plan's arguments, as JSON.
        provenance : dict
            Must hold every key of :data:`REQUIRED_PROVENANCE` — ``bench_config_hash``, ``software_version``,
            ``devices`` (identities, e.g. ``*IDN?`` and firmware per device), ``simulated`` (bool),
            ``operator`` — and may hold more (git SHA, package versions ...).
        descriptor : bench.descriptor.ReadingDescriptor
            What one reading of the run's sensor family is; every reading recorded is checked against it.
        parent_run_id : int, optional
            The interrupted run this one resumes; it must be of the same sensor and family.
        n_points_planned : int, optional
            Number of points the plan expands to (for progress).

        Returns
        -------
        int
            The run id.
        """
        if not isinstance(plan_args, dict):
            raise CatalogueError(f"plan_args must be a dict, not {type(plan_args).__name__}")
        if not isinstance(provenance, dict):
            raise CatalogueError(f"provenance must be a dict, not {type(provenance).__name__}")
        missing = [k for k in REQUIRED_PROVENANCE if k not in provenance]
        if missing:
            raise CatalogueError(f"provenance lacks {', '.join(missing)}; a run must say where its data comes from")
        if not isinstance(provenance["simulated"], bool):
            raise CatalogueError(f"provenance 'simulated' must be true or false, not {provenance['simulated']!r}")
        if n_points_planned is not None and (not isinstance(n_points_planned, int) or n_points_planned < 0):
            raise CatalogueError(f"n_points_planned must be a non-negative integer, not {n_points_planned!r}")
        if not isinstance(descriptor, ReadingDescriptor):
            raise CatalogueError(f"descriptor must be a ReadingDescriptor, not {type(descriptor).__name__}")
        args_json, provenance_json = _dumps(plan_args, "plan_args"), _dumps(provenance, "provenance")
        descriptor_json = _dumps(descriptor.to_json(), "descriptor")
        with self._write(f"create a run of {sensor_id}") as conn:
            if campaign_id is not None:
                self._campaign_exists(conn, campaign_id)
            if parent_run_id is not None:
                parent = conn.execute("SELECT sensor_id, family FROM runs WHERE id = ?", (parent_run_id,)).fetchone()
                if parent is None:
                    raise CatalogueError(f"no run {parent_run_id} (given as parent)")
                if parent["family"] != descriptor.family:
                    raise CatalogueError(f"parent run {parent_run_id} measured a {parent['family']} sensor, not a "
                                         f"{descriptor.family} one; a resumed run continues the same family")
                if parent["sensor_id"] != sensor_id:
                    raise CatalogueError(f"parent run {parent_run_id} measured sensor {parent['sensor_id']}, "
                                         f"not {sensor_id}; a resumed run continues the same sensor")
            run_id = conn.execute(
                """INSERT INTO runs (campaign_id, parent_run_id, sensor_id, plan_name, plan_args_json, created_utc,
                                     n_points_planned, provenance_json, family, descriptor_json)
                   VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)""",
                (campaign_id, parent_run_id, sensor_id, plan_name, args_json, utc_now(), n_points_planned,
                 provenance_json, descriptor.family, descriptor_json)).lastrowid
            message = f"created (resumes run {parent_run_id})" if parent_run_id is not None else "created"
            self._event(conn, run_id, "status", message,
                        {"from": None, "to": "created", "parent_run_id": parent_run_id})
            return run_id

    def set_run_status(self, run_id: int, status: str, reason: str | None = None) -> None:
        """Move a run to `status` and journal the change (an event of kind "status").

        ``started_utc`` is set the first time the run becomes "running"; ``ended_utc`` and ``exit_reason``
        (= `reason`) when it reaches a terminal status (:data:`TERMINAL_RUN_STATUSES`). Setting the status
        a live run already has does nothing.

        Raises
        ------
        CatalogueError
            An unknown status, no such run, or a transition the run cannot make: a finished run stays
            finished (resume it with a new run), nothing returns to "created", and a run that never started
            cannot pause, be suspended or crash.
        """
        if status not in RUN_STATUSES:
            raise CatalogueError(f"unknown run status {status!r}; expected one of {', '.join(RUN_STATUSES)}")
        with self._write(f"set run {run_id} status to {status}") as conn:
            old = self._run_row(conn, run_id)["status"]
            if old == status and status not in TERMINAL_RUN_STATUSES:
                return
            if status not in _RUN_TRANSITIONS[old]:
                hint = "; resume it with a new run" if old in TERMINAL_RUN_STATUSES else ""
                raise CatalogueError(f"run {run_id} is {old}, it cannot become {status}{hint}")
            self._set_status(conn, run_id, old, status, reason)

    def _set_status(self, conn, run_id: int, old: str, status: str, reason: str | None) -> None:
        now = utc_now()
        if status == "running":
            conn.execute("UPDATE runs SET status = ?, started_utc = coalesce(started_utc, ?) WHERE id = ?",
                         (status, now, run_id))
        elif status in TERMINAL_RUN_STATUSES:
            conn.execute("UPDATE runs SET status = ?, ended_utc = ?, exit_reason = ? WHERE id = ?",
                         (status, now, reason, run_id))
        else:
            conn.execute("UPDATE runs SET status = ? WHERE id = ?", (status, run_id))
        message = f"{old} → {status}" + (f": {reason}" if reason else "")
        self._event(conn, run_id, "status", message, {"from": old, "to": status, "reason": reason})

    _RUN_SELECT = """SELECT r.*, (SELECT count(*) FROM points p WHERE p.run_id = r.id) AS n_points_recorded
                     FROM runs r"""

    def run(self, run_id: int) -> dict:
        """One run: every column of ``runs`` (``plan_args`` and ``provenance`` parsed) and ``n_points_recorded``.

        Raises
        ------
        CatalogueError
            "no run N".
        """
        row = _row(self._one(self._RUN_SELECT + " WHERE r.id = ?", (run_id,)))
        if row is None:
            raise CatalogueError(f"no run {run_id}")
        return row

    def runs(self, campaign_id: int | None = None) -> list[dict]:
        """Runs, oldest first (all of them, or those of one campaign), as :meth:`run` returns them."""
        if campaign_id is None:
            rows = self._all(self._RUN_SELECT + " ORDER BY r.id")
        else:
            rows = self._all(self._RUN_SELECT + " WHERE r.campaign_id = ? ORDER BY r.id", (campaign_id,))
        return [_row(r) for r in rows]

    def lineage(self, run_id: int) -> list[int]:
        """The run and the runs it resumes, oldest first: ``[first, ..., parent, run_id]``."""
        rows = self._all(
            """WITH RECURSIVE chain(id, parent, depth) AS (
                   SELECT id, parent_run_id, 0 FROM runs WHERE id = ?
                   UNION ALL
                   SELECT r.id, r.parent_run_id, c.depth + 1 FROM runs r JOIN chain c ON r.id = c.parent
               ) SELECT id FROM chain ORDER BY depth DESC""", (run_id,))
        if not rows:
            raise CatalogueError(f"no run {run_id}")
        return [r[0] for r in rows]

    def mark_interrupted_runs(self) -> list[int]:
        """Mark runs a dead process left live ("running", "paused", "suspended") as "crashed".

        Call it when an engine starts. The writer lock guarantees no other live process owns these runs.
        Each gets ``ended_utc``, an ``exit_reason`` and a "status" event; a fleet-queue entry that was
        "running" for such a run goes back to "queued", still linked to the crashed run, so the campaign
        picks the sensor up again and can resume from that run (:meth:`queued_run`, :meth:`lineage`).

        Returns
        -------
        list of int
            The ids of the runs marked, ascending.
        """
        with self._write("mark interrupted runs") as conn:
            rows = conn.execute(f"SELECT id, status FROM runs WHERE status IN {_in(LIVE_RUN_STATUSES)} ORDER BY id"
                                ).fetchall()
            for row in rows:
                self._set_status(conn, row["id"], row["status"], "crashed",
                                 f"the process driving the run ended while it was {row['status']}")
                conn.execute("UPDATE fleet_queue SET status = 'queued', updated_utc = ? "
                             "WHERE run_id = ? AND status = 'running'", (utc_now(), row["id"]))
            return [row["id"] for row in rows]

    def mark_interrupted_campaigns(self) -> list[int]:
        """Mark campaigns a dead process left unfinished (created, running or paused, with sensors still
        queued) as "aborted", journalled: nothing runs them until someone resumes them.

        Call it when an engine starts, after :meth:`mark_interrupted_runs`. Returns their ids, ascending.
        """
        with self._write("mark interrupted campaigns") as conn:
            rows = conn.execute(
                """SELECT id, status FROM campaigns c WHERE status IN ('created', 'running', 'paused')
                   AND EXISTS (SELECT 1 FROM fleet_queue q WHERE q.campaign_id = c.id
                               AND q.status IN ('queued', 'running')) ORDER BY id""").fetchall()
            for row in rows:
                conn.execute("UPDATE campaigns SET status = 'aborted' WHERE id = ?", (row["id"],))
                self._event(conn, None, "status", f"campaign {row['id']}: {row['status']} → aborted: the process "
                            "running it ended; resume it to go on", {"campaign_id": row["id"], "from": row["status"],
                                                                     "to": "aborted"})
            return [row["id"] for row in rows]

    # --- points and readings ----------------------------------------------------------------------------
    def record_point(self, run_id: int, key: str, *, stage: str, azimuth_deg: float, zenith_stage_deg: float,
                     zenith_deg: float, azimuth_body_deg: float, exposure_ms: float | None, readings: list[dict],
                     started_utc: str | dt.datetime | None = None) -> int:
        """Store one measured point with all its readings, in one transaction: all of it or nothing.

        Parameters
        ----------
        run_id : int
            A run that has not finished.
        key : str
            The point's identity within its plan, stable across runs; unique within the run.
        stage : str
            Plan stage ("centre", "tilt", "grid" ...).
        azimuth_deg, zenith_stage_deg : float
            Table pose: azimuth-stage and zenith-stage angles [deg].
        zenith_deg, azimuth_body_deg : float
            The true sun direction in the sensor body frame the pose gives: zenith θ and azimuth φ [deg].
        exposure_ms : float or None
            Sensor exposure [ms], > 0; None when the sensor has none or did not report it.
        readings : list of dict
            One per frame: the keys every family shares, :data:`READING_FIELDS` — ``repeat`` (default: index
            in the list), ``status`` ("ok", the default, or the name of what went wrong), ``frame_path`` (a
            file under :meth:`frames_dir`: absolute, or relative to :attr:`frames_root`), ``t_s`` [s]
            (bench-clock time of the reading, required) — and the fields of the run's family descriptor (an
            "ok" reading needs every required one; NaN means missing).
        started_utc : str, datetime or float (seconds since the epoch), optional
            When the point's measurement began; ``completed_utc`` is the time of recording.

        Returns
        -------
        int
            The point id.

        Raises
        ------
        CatalogueError
            The key is already recorded in this run, the run does not exist or has finished, there are no
            readings, a value is invalid, or a reading breaks a constraint (the message names the reading).
            Nothing is stored then.
        """
        pose = {name: _finite(value, f"point {key!r}: {name}") for name, value in zip(_POINT_FIELDS, (
            azimuth_deg, zenith_stage_deg, zenith_deg, azimuth_body_deg))}
        # None: a sensor without an exposure setting (photodiodes) or one that did not report it
        pose["exposure_ms"] = None if exposure_ms is None else _finite(exposure_ms, f"point {key!r}: exposure_ms")
        if isinstance(started_utc, (int, float)) and not isinstance(started_utc, bool):  # epoch seconds
            started_utc = dt.datetime.fromtimestamp(started_utc, dt.UTC)
        if isinstance(started_utc, dt.datetime):
            started_utc = _iso(started_utc)
        if not readings:
            raise CatalogueError(f"point {key!r} has no readings; a point is a pose with its frames")
        with self._write(f"record point {key!r} of run {run_id}") as conn:
            run = self._run_row(conn, run_id)
            descriptor = _descriptor(run["descriptor_json"])
            rows = [self._reading_row(i, reading, key, descriptor) for i, reading in enumerate(readings)]
            status = run["status"]
            if status in TERMINAL_RUN_STATUSES:
                raise CatalogueError(f"run {run_id} is {status}; points are recorded only in a run that has not ended")
            if conn.execute("SELECT 1 FROM points WHERE run_id = ? AND key = ?", (run_id, key)).fetchone():
                raise CatalogueError(f"point {key!r} is already recorded in run {run_id}")
            point_id = conn.execute(
                """INSERT INTO points (run_id, key, stage, azimuth_deg, zenith_stage_deg, zenith_deg,
                                       azimuth_body_deg, exposure_ms, started_utc, completed_utc)
                   VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)""",
                (run_id, key, stage, *pose.values(), started_utc, utc_now())).lastrowid
            for i, row in enumerate(rows):
                try:
                    conn.execute(
                        """INSERT INTO readings (point_id, repeat, status, frame_path, t_s, values_json)
                           VALUES (?, ?, ?, ?, ?, ?)""",
                        (point_id, *row))
                except sqlite3.IntegrityError as exc:
                    raise CatalogueError(f"point {key!r} of run {run_id}: reading {i} (repeat {row[0]}) refused: "
                                         f"{exc}; the point was not recorded") from exc
            return point_id

    def _reading_row(self, index: int, reading: dict, key: str, descriptor: ReadingDescriptor) -> tuple:
        where = f"point {key!r}: reading {index}"
        if not isinstance(reading, dict):
            raise CatalogueError(f"{where} must be a dict, not {type(reading).__name__}")
        shared = {**READING_FIELDS, "repeat": index, **{k: v for k, v in reading.items() if k in READING_FIELDS}}
        family = {k: v for k, v in reading.items() if k not in READING_FIELDS}
        repeat, status, t_s = shared["repeat"], shared["status"], shared["t_s"]
        if isinstance(repeat, bool) or not isinstance(repeat, int) and not (isinstance(repeat, float)
                                                                             and repeat.is_integer()):
            raise CatalogueError(f"{where}: repeat must be an integer, not {repeat!r}")
        if int(repeat) < 0:
            raise CatalogueError(f"{where}: repeat must be >= 0, not {repeat!r}")
        if not isinstance(status, str) or not status:
            raise CatalogueError(f"{where}: status must be a non-empty string, not {status!r}")
        try:
            t_s = float(t_s)
        except (TypeError, ValueError):
            raise CatalogueError(f"{where}: t_s (the reading's bench-clock time) must be a number, "
                                 f"not {t_s!r}") from None
        if not math.isfinite(t_s):
            raise CatalogueError(f"{where}: t_s must be finite, not {t_s}")
        try:
            values = descriptor.validate(family, ok=status == "ok", where=where)
        except DescriptorError as exc:
            raise CatalogueError(f"{exc} (frames go to files under frames_dir())") from None
        frame_path = shared["frame_path"]
        if frame_path is not None:
            frame_path = self._relative_frame_path(frame_path, where)
        return int(repeat), status, frame_path, t_s, json.dumps(values, allow_nan=False)

    def completed_keys(self, run_ids: int | Iterable[int]) -> set[str]:
        """Keys of the points recorded in these runs (give a :meth:`lineage` to resume a run)."""
        ids = _run_ids(run_ids)
        return {r[0] for r in self._all(
            f"SELECT key FROM points WHERE run_id IN ({_placeholders(len(ids))})", ids)}

    def points(self, run_ids: int | Iterable[int]) -> list[dict]:
        """The points of these runs, in recording order, each with ``n_readings``."""
        ids = _run_ids(run_ids)
        return [_row(r) for r in self._all(
            f"""SELECT p.*, (SELECT count(*) FROM readings r WHERE r.point_id = p.id) AS n_readings
                FROM points p WHERE p.run_id IN ({_placeholders(len(ids))}) ORDER BY p.id""", ids)]

    def readings(self, run_ids: int | Iterable[int]) -> list[ReadingRecord]:
        """The readings of these runs, ordered by point (recording order) then repeat, as typed records: the
        fields every family shares, the point's pose and direction, and the family's ``values`` (by the run's
        descriptor, :meth:`descriptor`). ``frame_path`` is relative to :attr:`frames_root`.
        """
        ids = _run_ids(run_ids)
        rows = self._all(
            f"""SELECT r.id, r.point_id, p.run_id, p.key, p.stage, p.azimuth_deg, p.zenith_stage_deg, p.zenith_deg,
                       p.azimuth_body_deg, p.exposure_ms, r.repeat, r.status, r.t_s, r.frame_path, r.values_json
                FROM readings r JOIN points p ON p.id = r.point_id
                WHERE p.run_id IN ({_placeholders(len(ids))}) ORDER BY p.id, r.repeat""", ids)
        return [ReadingRecord(*tuple(row)[:-1], values=json.loads(row["values_json"])) for row in rows]

    def descriptor(self, run_id: int) -> ReadingDescriptor:
        """The reading descriptor of a run (what its family's readings hold)."""
        row = self._one("SELECT descriptor_json FROM runs WHERE id = ?", (run_id,))
        if row is None:
            raise CatalogueError(f"no run {run_id}")
        return _descriptor(row["descriptor_json"])

    # --- frames -----------------------------------------------------------------------------------------
    @property
    def frames_root(self) -> Path:
        """``<folder of the database>/<db stem>-frames``: where every run's frames go."""
        return self.path.parent / f"{self.path.stem}-frames"

    def frames_dir(self, run_id: int) -> Path:
        """The folder for the frames of a run, ``<db stem>-frames/run-<id>/`` beside the database.

        A writer creates it; a read-only catalogue only names it.
        """
        if self._one("SELECT 1 FROM runs WHERE id = ?", (run_id,)) is None:
            raise CatalogueError(f"no run {run_id}")
        folder = self.frames_root / f"run-{run_id}"
        if not self.readonly:
            folder.mkdir(parents=True, exist_ok=True)
        return folder

    def _relative_frame_path(self, frame_path, what: str) -> str:
        path = Path(frame_path)
        if path.is_absolute():
            try:
                path = path.relative_to(self.frames_root)
            except ValueError:
                raise CatalogueError(f"{what}: frame {frame_path} is outside the frames folder "
                                     f"{self.frames_root}; write frames under frames_dir()") from None
        relative = PurePosixPath(path.as_posix())
        if ".." in relative.parts or not relative.parts:
            raise CatalogueError(f"{what}: frame path {frame_path!r} must stay inside the frames folder")
        return str(relative)

    # --- calibrations -----------------------------------------------------------------------------------
    def add_calibration(self, run_id: int, method: str, document: dict, metrics: dict, chosen: bool) -> int:
        """Store a calibration fitted to a run.

        Parameters
        ----------
        method : str
            Calibration method name.
        document : dict
            The calibration JSON document (what ``sunbench apply`` reads).
        metrics : dict
            Its accuracy metrics (held-out errors in degrees, residuals ...).
        chosen : bool
            True makes it the run's chosen calibration; a previously chosen one of the run is un-chosen
            in the same transaction (one chosen per run, also enforced by a unique index).

        Returns
        -------
        int
            The calibration id.
        """
        document_json, metrics_json = _dumps(document, "calibration document"), _dumps(metrics, "calibration metrics")
        with self._write(f"add a {method} calibration to run {run_id}") as conn:
            self._run_row(conn, run_id)
            if chosen:
                conn.execute("UPDATE calibrations SET chosen = 0 WHERE run_id = ? AND chosen = 1", (run_id,))
            return conn.execute(
                """INSERT INTO calibrations (run_id, method, document_json, metrics_json, chosen, created_utc)
                   VALUES (?, ?, ?, ?, ?, ?)""",
                (run_id, method, document_json, metrics_json, int(bool(chosen)), utc_now())).lastrowid

    def calibrations(self, run_id: int) -> list[dict]:
        """A run's calibrations, oldest first: ``id, run_id, method, document, metrics, chosen, created_utc``."""
        return [_row(r) for r in self._all("SELECT * FROM calibrations WHERE run_id = ? ORDER BY id", (run_id,))]

    # --- journal ----------------------------------------------------------------------------------------
    def log_event(self, run_id: int | None, kind: str, message: str, data: dict | None = None) -> int:
        """Append an event to the journal (interlock, warning, log line ...); returns its id.

        Status changes are journalled by :meth:`set_run_status` itself (kind "status"), so do not log them
        again. `run_id` None is an event of the bench rather than of a run.
        """
        with self._write(f"log a {kind} event") as conn:
            if run_id is not None:
                self._run_row(conn, run_id)
            return self._event(conn, run_id, kind, message, data)

    def events(self, run_id: int | None, after_id: int = 0) -> list[dict]:
        """Events with id > `after_id`, oldest first, of one run or (`run_id` None) of everything.

        A follower (the dashboard's event stream) passes the last id it saw to get only what is new.
        Each dict: ``id, run_id, t_utc, kind, message, data``.
        """
        if run_id is None:
            rows = self._all("SELECT * FROM events WHERE id > ? ORDER BY id", (after_id,))
        else:
            rows = self._all("SELECT * FROM events WHERE run_id = ? AND id > ? ORDER BY id", (run_id, after_id))
        return [_row(r) for r in rows]

    # --- run values -------------------------------------------------------------------------------------
    def set_run_value(self, run_id: int, key: str, value: Any) -> None:
        """Keep a value a run decided (chosen exposure [ms], tilt-stage result ...), as JSON; replaces any old one."""
        value_json = _dumps(value, f"run value {key!r}")
        with self._write(f"set run {run_id} value {key!r}") as conn:
            self._run_row(conn, run_id)
            conn.execute("""INSERT INTO run_values (run_id, key, value_json, updated_utc) VALUES (?, ?, ?, ?)
                            ON CONFLICT (run_id, key) DO UPDATE SET value_json = excluded.value_json,
                                                                    updated_utc = excluded.updated_utc""",
                         (run_id, key, value_json, utc_now()))

    def run_value(self, run_id: int, key: str, default: Any = None, *, inherit: bool = False) -> Any:
        """A value the run kept, or `default`.

        Parameters
        ----------
        inherit : bool
            Also look in the runs it resumes, newest first (a resumed run keeps its parent's exposure).
        """
        ids = self.lineage(run_id)[::-1] if inherit else [run_id]
        for candidate in ids:
            row = self._one("SELECT value_json FROM run_values WHERE run_id = ? AND key = ?", (candidate, key))
            if row is not None:
                return json.loads(row[0])
        return default

    def run_values(self, run_id: int) -> dict[str, Any]:
        """Every value the run kept, by key."""
        return {r[0]: json.loads(r[1]) for r in self._all(
            "SELECT key, value_json FROM run_values WHERE run_id = ? ORDER BY key", (run_id,))}
