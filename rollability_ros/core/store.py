"""Durable store of launch outcomes, candidate results, generation summaries, tip events and run info.

Why SQLite in WAL mode rather than an append-only file with fsync: the logger must (1) acknowledge an outcome
only once it is on disk, (2) store a duplicate trial id once, (3) let the campaign runner and the report read
while the logger writes, and (4) never leave a torn record after ``kill -9``. SQLite gives all four from the
standard library: a ``UNIQUE`` constraint does (2) without an in-memory index that must be rebuilt on start,
WAL lets readers in other processes see a consistent snapshot while one writer appends (3), and a commit with
``synchronous=FULL`` fsyncs the write-ahead log before returning (1), so a killed writer loses at most the
transaction it had not committed (4) and the next open replays or discards the log atomically. An append-only
file needs the same pieces hand-made: torn-tail detection, a dedup index, and readers that skip a half line.

One file may hold several runs (``run_id`` is in every key); a run directory holds ``store.sqlite``. The schema
is versioned with ``PRAGMA user_version`` and marked as ours with ``PRAGMA application_id``; another SQLite
file or a non-database file is refused with ``ValueError``. A store of an older schema is migrated when it is opened
(columns added since are added, its rows taking the field's default: outcomes of a version 1 store read with
``seed`` = ``NO_SEED``, those of a version 3 store with NaN continuous outcomes); nothing already stored changes. Stdlib only: this module runs on the robot computer.
"""
import dataclasses
import json
import math
import os
import sqlite3
import threading
import typing

from rollability_ros.core.records import (
    CandidateRecord,
    GenerationRecord,
    LaunchCondition,
    LaunchOutcome,
    TipEventRecord,
)

#: File name of the store inside a run directory.
STORE_FILENAME = "store.sqlite"
#: File name of the outcome logger's store inside a ``study`` or ``bringup`` session directory.
SESSION_STORE_FILENAME = "outcomes.sqlite"
#: ``PRAGMA application_id`` of a rollability store ("ROLL" in ASCII).
APPLICATION_ID = 0x524F4C4C
#: Schema version written to ``PRAGMA user_version``; bump with a migration when the tables change.
#: 1: the first schema; 2: ``launch_outcomes.seed`` (rows of a version 1 store read as ``NO_SEED``);
#: 3: ``candidates.session`` and ``generations.session`` (rows of an older store read as session "");
#: 4: the continuous outcomes of ``launch_outcomes`` (``final_tilt_deg``, ``rest_distance_m``, ``time_to_rest_s``,
#: ``peak_deceleration_mps2``; rows of an older store read as NaN: not measured).
SCHEMA_VERSION = 4


def _encode_tuple(value):
    return json.dumps([float(v) for v in value])


def _decode_tuple(text):
    return tuple(json.loads(text))


def _encode_float(value):
    # SQLite stores NaN as NULL; keep it explicit so the round trip is NaN -> NULL -> NaN
    return None if value is None or (isinstance(value, float) and math.isnan(value)) else float(value)


def _decode_float(value):
    return math.nan if value is None else float(value)


@dataclasses.dataclass(frozen=True)
class _Column:
    """One column: name, SQL type, and how a record field value is written and read back."""

    name: str
    sql_type: str
    encode: typing.Callable[[typing.Any], typing.Any]
    decode: typing.Callable[[typing.Any], typing.Any]
    default: object = None            # the record field's default, encoded; None: the field has no default
    null_default: bool = False        # the field's default is stored as NULL (a float field defaulting to NaN)

    def add_sql(self, table_name: str) -> str:
        """``ALTER TABLE`` adding this column to a store written before it existed, old rows taking the default."""
        if self.null_default:
            return f'ALTER TABLE {table_name} ADD COLUMN "{self.name}" {self.sql_type} DEFAULT NULL'
        if self.default is None:
            raise ValueError(f"cannot add column {table_name}.{self.name} to an existing store: it has no default")
        literal = "'" + self.default.replace("'", "''") + "'" if isinstance(self.default, str) else repr(self.default)
        return f'ALTER TABLE {table_name} ADD COLUMN "{self.name}" {self.sql_type} DEFAULT {literal}'


def _columns_for(record_cls, skip=()):
    """Columns for the scalar and tuple fields of a records dataclass, typed from its field annotations."""
    columns = []
    for field in dataclasses.fields(record_cls):
        if field.name in skip:
            continue
        kind = field.type if isinstance(field.type, str) else field.type.__name__
        if kind == "float":
            column = _Column(field.name, "REAL", _encode_float, _decode_float)
        elif kind == "int":
            column = _Column(field.name, "INTEGER NOT NULL", int, int)
        elif kind == "bool":
            column = _Column(field.name, "INTEGER NOT NULL", int, bool)
        elif kind == "str":
            column = _Column(field.name, "TEXT NOT NULL", str, str)
        elif kind == "tuple":
            column = _Column(field.name, "TEXT NOT NULL", _encode_tuple, _decode_tuple)
        else:
            raise TypeError(f"no store column type for {record_cls.__name__}.{field.name}: {kind}")
        if field.default is not dataclasses.MISSING and kind in ("int", "bool", "str"):
            column = dataclasses.replace(column, default=column.encode(field.default))
        elif kind == "float" and isinstance(field.default, float) and math.isnan(field.default):
            column = dataclasses.replace(column, null_default=True)   # not measured: NULL reads back as NaN
        columns.append(column)
    return columns


class _Table:
    """A records dataclass stored as one table, rows kept in insertion order by ``seq``."""

    def __init__(self, name, record_cls, unique, flatten=None):
        self.name = name
        self.record_cls = record_cls
        self.unique = unique
        # flatten: (field name, nested dataclass) stored as its own columns, e.g. LaunchOutcome.condition
        self.flatten = flatten
        nested = _columns_for(flatten[1]) if flatten else []
        self.nested_names = [c.name for c in nested]
        self.columns = _columns_for(record_cls, skip=(flatten[0],) if flatten else ()) + nested

    def add_missing_columns(self, conn: sqlite3.Connection) -> None:
        """Add the columns a store of an older schema lacks (e.g. ``seed``, schema 2), old rows getting the default.

        Runs inside the caller's write transaction, so a second process migrating the same file sees them added.
        """
        existing = {row[1] for row in conn.execute(f"PRAGMA table_info({self.name})")}
        for column in self.columns:
            if existing and column.name not in existing:
                conn.execute(column.add_sql(self.name))

    def create_sql(self) -> str:
        body = ", ".join(f'"{c.name}" {c.sql_type}' for c in self.columns)
        keys = ", ".join(f'"{k}"' for k in self.unique)
        return (f'CREATE TABLE IF NOT EXISTS {self.name} (seq INTEGER PRIMARY KEY AUTOINCREMENT, {body}, '
                f'UNIQUE ({keys}))')

    def insert_sql(self) -> str:
        names = ", ".join(f'"{c.name}"' for c in self.columns)
        marks = ", ".join("?" for _ in self.columns)
        return f"INSERT OR IGNORE INTO {self.name} ({names}) VALUES ({marks})"

    def select_sql(self, filters: typing.Iterable[str]) -> str:
        names = ", ".join(f'"{c.name}"' for c in self.columns)
        where = " AND ".join(f'"{name}" = ?' for name in filters)
        return f"SELECT {names} FROM {self.name}" + (f" WHERE {where}" if where else "") + " ORDER BY seq"

    def to_row(self, record: "Record") -> tuple:
        values = dataclasses.asdict(record)
        if self.flatten:
            values.update(values.pop(self.flatten[0]))
        return tuple(c.encode(values[c.name]) for c in self.columns)

    def from_row(self, row: typing.Sequence[typing.Any]) -> typing.Any:
        values = {c.name: c.decode(v) for c, v in zip(self.columns, row)}
        if self.flatten:
            field_name, nested_cls = self.flatten
            values[field_name] = nested_cls(**{n: values.pop(n) for n in self.nested_names})
        return self.record_cls(**values)


#: A record the store keeps (one table each).
Record = typing.Union[LaunchOutcome, CandidateRecord, GenerationRecord, TipEventRecord]

_OUTCOMES = _Table("launch_outcomes", LaunchOutcome, ("run_id", "trial_id"),
                   flatten=("condition", LaunchCondition))
_CANDIDATES = _Table("candidates", CandidateRecord, ("run_id", "generation", "index"))
_GENERATIONS = _Table("generations", GenerationRecord, ("run_id", "generation"))
_TIP_EVENTS = _Table("tip_events", TipEventRecord, ("robot", "tipped_at_s"))
_TABLES = (_OUTCOMES, _CANDIDATES, _GENERATIONS, _TIP_EVENTS)
_TABLE_OF = {table.record_cls: table for table in _TABLES}
_RUNS_SQL = "CREATE TABLE IF NOT EXISTS runs (run_id TEXT PRIMARY KEY, kind TEXT NOT NULL, info TEXT NOT NULL)"


def unique_key(record: "Record") -> tuple:
    """The key under which the store keeps ``record`` once, e.g. ``(run_id, trial_id)`` of a LaunchOutcome."""
    table = _TABLE_OF.get(type(record))
    if table is None:
        raise ValueError(f"the store holds no {type(record).__name__} records")
    return tuple(getattr(record, name) for name in table.unique)


class StoreDamaged(ValueError):
    """A store that opened but whose pages cannot be read back (SQLite: "database disk image is malformed"):
    the message names the file. A ``ValueError``, so a command says it in one line; a writer that must not
    acknowledge what it could not store (the outcome logger) tells it from a malformed record by its type."""


def _is_damage(exc: sqlite3.DatabaseError) -> bool:
    """SQLite's "database disk image is malformed" or "file is not a database": the plain ``DatabaseError``, not
    one of its kinds (locked or I/O: ``OperationalError``; a broken constraint: ``IntegrityError``, ...)."""
    return type(exc) is sqlite3.DatabaseError


def store_path(path: typing.Union[str, os.PathLike]) -> str:
    """Return the store file for ``path``: the path itself, or ``<dir>/store.sqlite`` for a directory."""
    path = os.fspath(path)
    return os.path.join(path, STORE_FILENAME) if os.path.isdir(path) else path


class Store:
    """SQLite store of run records; every ``add_*`` is committed (fsynced) before it returns.

    Thread-safe per instance (one connection behind a lock); several processes may open the same file
    (SQLite locks it; readers see committed data only).

    Parameters
    ----------
    path : str or os.PathLike
        Store file, or a run directory (then ``<dir>/store.sqlite``). Created with its schema if missing.
    """

    def __init__(self, path):
        self.path = store_path(path)
        self._lock = threading.Lock()
        self._conn: typing.Optional[sqlite3.Connection] = None   # None once closed: _connection() refuses
        try:
            conn = self._conn = sqlite3.connect(self.path, timeout=30.0, check_same_thread=False, isolation_level=None)
        except sqlite3.Error as exc:
            raise ValueError(f"cannot open store {self.path}: {exc}") from exc
        try:
            self._open_schema()
        except sqlite3.DatabaseError as exc:
            conn.close()
            raise ValueError(f"{self.path} is not a usable rollability store (corrupt or not SQLite): {exc}") from exc
        except ValueError:
            conn.close()
            raise

    def _open_schema(self):
        conn = self._connection()
        conn.execute("PRAGMA busy_timeout = 30000")
        # one read transaction, so the three describe the same moment: read one by one, they could straddle the
        # commit of another process creating this store (application_id still 0, tables already there) and call a
        # store being created another application's file
        conn.execute("BEGIN")
        try:
            application_id = conn.execute("PRAGMA application_id").fetchone()[0]
            version = conn.execute("PRAGMA user_version").fetchone()[0]
            has_tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0] > 0
        finally:
            conn.execute("COMMIT")
        if has_tables and application_id != APPLICATION_ID:
            raise ValueError(f"{self.path} is an SQLite file of another application "
                             f"(application_id {application_id:#x}), not a rollability store")
        if version > SCHEMA_VERSION:
            raise ValueError(f"{self.path} has store schema version {version}, newer than this code "
                             f"({SCHEMA_VERSION}); update rollability_ros")
        if conn.execute("PRAGMA journal_mode = WAL").fetchone()[0].lower() != "wal":
            raise ValueError(f"{self.path}: cannot switch the store to WAL mode (network file system?)")
        conn.execute("PRAGMA synchronous = FULL")
        if not has_tables or version < SCHEMA_VERSION:
            conn.execute("BEGIN IMMEDIATE")
            try:
                for table in _TABLES:
                    table.add_missing_columns(conn)
                    conn.execute(table.create_sql())
                conn.execute(_RUNS_SQL)
                conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise

    def check_intact(self) -> None:
        """Raise :class:`StoreDamaged` naming the file unless SQLite's ``quick_check`` finds every page and index
        intact (it reads the whole file: a resume calls it once, before starting anything)."""
        rows = self._read("PRAGMA quick_check(5)")
        problems = [row[0] for row in rows if row[0] != "ok"]
        if problems:
            raise self._damaged("; ".join(problems)[:300])

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    def close(self) -> None:
        """Close the connection (idempotent)."""
        with self._lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None

    def _connection(self) -> sqlite3.Connection:
        if self._conn is None:
            raise ValueError(f"store {self.path} is closed")
        return self._conn

    def _write(self, sql, params):
        """Run one statement in its own committed transaction; return the number of rows it changed."""
        with self._lock:
            conn = self._connection()
            conn.execute("BEGIN IMMEDIATE")
            try:
                changed = conn.execute(sql, params).rowcount
                conn.execute("COMMIT")
            except BaseException as exc:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                if isinstance(exc, sqlite3.DatabaseError) and _is_damage(exc):
                    raise self._damaged(exc) from exc
                raise
        return changed

    def _insert(self, table, record):
        if not isinstance(record, table.record_cls):
            raise ValueError(f"expected a {table.record_cls.__name__}, got {type(record).__name__}")
        owner = table.unique[0]  # run_id or robot: a record must say whose it is
        if not getattr(record, owner):
            raise ValueError(f"{table.record_cls.__name__}.{owner} must be non-empty")
        return self._write(table.insert_sql(), table.to_row(record)) == 1

    def _read(self, sql: str, params: tuple = ()) -> list:
        """All rows of one query; :class:`StoreDamaged` naming the file when SQLite finds its pages damaged (the
        header can be intact, so opening succeeded, while a table's pages are not)."""
        with self._lock:
            try:
                return self._connection().execute(sql, params).fetchall()
            except sqlite3.DatabaseError as exc:
                if _is_damage(exc):
                    raise self._damaged(exc) from exc
                raise

    def _damaged(self, cause: typing.Union[sqlite3.DatabaseError, str]) -> StoreDamaged:
        """The error naming this store as damaged by ``cause`` (SQLite's error, or what ``quick_check`` found)."""
        return StoreDamaged(f"store {self.path} is damaged ({cause}); nothing more is written to it; restore it "
                            "from a copy (`sqlite3 FILE .recover` salvages the rows left)")

    def _select(self, table, **filters):
        filters = {k: v for k, v in filters.items() if v is not None}
        rows = self._read(table.select_sql(filters), tuple(filters.values()))
        return [table.from_row(row) for row in rows]

    def add_launch_outcome(self, outcome: LaunchOutcome) -> bool:
        """Store ``outcome`` durably; return False (and store nothing) if its (run_id, trial_id) is stored.

        Raises ``ValueError`` for an outcome that fails :meth:`LaunchOutcome.validate`.
        """
        outcome.validate()
        return self._insert(_OUTCOMES, outcome)

    def launch_outcomes(self, run_id: typing.Optional[str] = None) -> typing.List[LaunchOutcome]:
        """Launch outcomes (all runs, or one), in insertion order."""
        return self._select(_OUTCOMES, run_id=run_id)

    def trial_ids(self, run_id: str) -> typing.Set[str]:
        """The set of trial ids stored for ``run_id`` (what a resumed campaign skips)."""
        return {row[0] for row in self._read("SELECT trial_id FROM launch_outcomes WHERE run_id = ?", (run_id,))}

    def add_candidate(self, candidate: CandidateRecord) -> bool:
        """Store a candidate result; False if its (run_id, generation, index) is already stored."""
        return self._insert(_CANDIDATES, candidate)

    def candidates(self, run_id: typing.Optional[str] = None,
                   generation: typing.Optional[int] = None) -> typing.List[CandidateRecord]:
        """Candidate results (optionally of one run and/or generation), in insertion order."""
        return self._select(_CANDIDATES, run_id=run_id, generation=generation)

    def add_generation(self, generation: GenerationRecord) -> bool:
        """Store a generation summary; False if its (run_id, generation) is already stored."""
        return self._insert(_GENERATIONS, generation)

    def generations(self, run_id: typing.Optional[str] = None) -> typing.List[GenerationRecord]:
        """Generation summaries (all runs, or one), in insertion order."""
        return self._select(_GENERATIONS, run_id=run_id)

    def add_tip_event(self, event: TipEventRecord) -> bool:
        """Store a field tip event; False if an event of that robot at that ``tipped_at_s`` is stored."""
        return self._insert(_TIP_EVENTS, event)

    def tip_events(self, robot: typing.Optional[str] = None) -> typing.List[TipEventRecord]:
        """Tip events (all robots, or one), in insertion order."""
        return self._select(_TIP_EVENTS, robot=robot)

    def set_run_info(self, run_id: str, kind: str, info: typing.Mapping[str, object]) -> None:
        """Create or replace the description of run ``run_id``.

        Parameters
        ----------
        run_id : str
        kind : str
            What the run is, e.g. ``"campaign"`` or ``"optimization"``.
        info : dict
            JSON-serialisable details (config, backend, start time, ...).
        """
        if not run_id:
            raise ValueError("run_id must be non-empty")
        try:
            text = json.dumps(info, sort_keys=True)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"run info of {run_id} is not JSON-serialisable: {exc}") from exc
        self._write("INSERT OR REPLACE INTO runs (run_id, kind, info) VALUES (?, ?, ?)", (run_id, str(kind), text))

    def run_info(self, run_id: str) -> typing.Optional[typing.Dict[str, typing.Any]]:
        """``{"kind": ..., "info": {...}}`` for ``run_id``, or None if it was never described."""
        rows = self._read("SELECT kind, info FROM runs WHERE run_id = ?", (run_id,))
        if not rows:
            return None
        try:
            info = json.loads(rows[0][1])
        except (TypeError, ValueError) as exc:
            raise StoreDamaged(f"store {self.path} is damaged: the run info of {run_id} is not JSON ({exc})") from exc
        return {"kind": rows[0][0], "info": info}

    def run_ids(self) -> typing.List[str]:
        """Every run id that has run info, outcomes, candidates or generations, sorted."""
        union = " UNION ".join(f"SELECT run_id FROM {t}" for t in ("runs", "launch_outcomes", "candidates",
                                                                       "generations"))
        return [row[0] for row in self._read(f"SELECT run_id FROM ({union}) ORDER BY run_id")]
