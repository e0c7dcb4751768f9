"""The results store: one SQLite file per experiment, one transaction per realization.

Each finished realization (all its estimators) is committed in a single transaction, and
marked done in the same transaction, so a kill at any moment leaves either the whole
realization or none of it; ``--resume`` then runs exactly the realizations not marked done.
Primary keys make a duplicate impossible. The file remembers the fingerprint of the
experiment definition and refuses to mix results of a different one.

Every stored estimate row has a checksum (SHA-256 of the row as SQLite returns it, table
``row_checksums``), written in the row's transaction. Opening the store checks the rows of
every finished realization against them, so a value changed, a row added or removed in
place after it was stored is refused, naming the rows, instead of being reported as a
result. A store written before the checksums existed gets them on its first open (its rows
are taken as found).

One writer at a time: an open store holds an exclusive lock on its file, so a second
process writing to the same ``--out`` is refused at once with a message (not a SQLite
error half way). A file that is not a jitterid store (corrupt, truncated, another schema,
a folder) is refused with the fix, and every SQLite error while working (a full disk, a
read-only folder) becomes a :class:`StoreError` that says what was kept. Exports are
written atomically.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import math
import sqlite3
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Self

from .. import __version__
from ..io import atomic_write
from .config import Experiment

__all__ = ["Estimate", "SqliteStore", "Store", "StoreError"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS realizations (
    case_name TEXT NOT NULL, realization INTEGER NOT NULL, elapsed_s REAL NOT NULL,
    PRIMARY KEY (case_name, realization));
CREATE TABLE IF NOT EXISTS estimates (
    experiment TEXT NOT NULL, case_name TEXT NOT NULL, realization INTEGER NOT NULL,
    method TEXT NOT NULL, params TEXT NOT NULL, stderr TEXT NOT NULL, jitter_std REAL,
    noise_std REAL, cost REAL, success INTEGER NOT NULL, status TEXT NOT NULL,
    message TEXT NOT NULL, nfev INTEGER NOT NULL, elapsed_s REAL NOT NULL,
    PRIMARY KEY (case_name, realization, method));
CREATE TABLE IF NOT EXISTS row_checksums (
    case_name TEXT NOT NULL, realization INTEGER NOT NULL, method TEXT NOT NULL,
    sha256 TEXT NOT NULL, PRIMARY KEY (case_name, realization, method));
"""

#: The columns of ``estimates`` in the order the checksum covers them.
_ROW = (
    "experiment, case_name, realization, method, params, stderr, jitter_std, noise_std, cost, "
    "success, status, message, nfev, elapsed_s"
)


try:  # an advisory lock on the store file (POSIX); elsewhere SQLite's own locking only
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

#: The columns of each table, to recognise a store written by another program or version.
_COLUMNS = {
    "meta": ["key", "value"],
    "realizations": ["case_name", "realization", "elapsed_s"],
    "estimates": [
        "experiment",
        "case_name",
        "realization",
        "method",
        "params",
        "stderr",
        "jitter_std",
        "noise_std",
        "cost",
        "success",
        "status",
        "message",
        "nfev",
        "elapsed_s",
    ],
    "row_checksums": ["case_name", "realization", "method", "sha256"],
}


class StoreError(RuntimeError):
    """The store cannot be used as asked (exists without --resume, another definition, another
    writer, a corrupt file, a failed write); the message says how to go on."""


@dataclass(frozen=True)
class Estimate:
    """One estimator's result on one realization (a row of the store).

    ``params`` and ``stderr`` map parameter names to values (NaN where undefined);
    ``status`` is the :class:`jitterid.FitStatus` name, or ``ERROR`` when ``fit`` raised
    (``message`` then holds the error). ``elapsed_s`` is the fit's wall time.
    """

    case_name: str
    realization: int
    method: str
    params: dict[str, float]
    stderr: dict[str, float]
    jitter_std: float
    noise_std: float
    cost: float
    success: bool
    status: str
    message: str
    nfev: int
    elapsed_s: float

    def same_numbers(self, other: Estimate) -> bool:
        """Equal in everything but timing (NaN equals NaN): the reproducibility check."""

        def key(e: Estimate) -> str:
            d = {k: v for k, v in e.__dict__.items() if k != "elapsed_s"}
            return json.dumps(d, sort_keys=True)  # NaN -> "NaN" on both sides

        return key(self) == key(other)


class SqliteStore:
    """One SQLite results file held by one writer: the lock, and errors turned into
    :class:`StoreError` messages. Subclasses define the tables in :meth:`_open`.

    Parameters
    ----------
    path : str or Path
        The database file; created with its folder if missing.
    resume : bool
        Whether existing results may be continued (each subclass's :meth:`_open` refuses a
        file that holds results without it).
    """

    #: What the file's rows are, for the messages.
    _ROWS = "realizations"

    def __init__(self, path: str | Path, *, resume: bool = False) -> None:
        self.path = Path(path)
        self._lock: io.BufferedRandom | None = None
        self._db: sqlite3.Connection | None = None
        if self.path.is_dir():
            raise StoreError(
                f"{self.path} is a folder, not a results store; remove or rename it, or use "
                "another --out folder"
            )
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._lock = open(self.path, "a+b")  # noqa: SIM115 - held open while the store is
        except OSError as exc:
            raise StoreError(
                f"cannot create the results store {self.path} ({exc.strerror or exc}); choose a "
                "writable --out folder"
            ) from None
        if fcntl is not None:
            try:
                fcntl.flock(self._lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                self.close()
                raise StoreError(
                    f"{self.path} is in use by another jitterid process; wait for it to finish "
                    "(then --resume), or use another --out folder"
                ) from None
        try:
            self._open(resume)
        except StoreError:
            self.close()
            raise
        except sqlite3.OperationalError as exc:
            self.close()
            text = str(exc)
            if not any(w in text for w in ("unable to open", "readonly", "disk", "full", "locked")):
                raise StoreError(
                    f"{self.path} is not a readable jitterid results store ({exc}); move it away "
                    "(or delete it) and run again without --resume"
                ) from None
            raise StoreError(
                f"cannot use the results store {self.path} ({exc}); check that the --out folder "
                "is writable and the disk has space"
            ) from None
        except (sqlite3.DatabaseError, ValueError, TypeError) as exc:
            self.close()
            raise StoreError(
                f"{self.path} is not a readable jitterid results store ({exc}); it may be corrupt, "
                "truncated or from another program: move it away (or delete it) and run again "
                f"without --resume; its {self._ROWS} will be computed anew"
            ) from None
        except BaseException:
            self.close()
            raise

    def _open(self, resume: bool) -> None:
        """Connect, create and check the tables (raise StoreError to refuse the file)."""
        raise NotImplementedError

    def _connect(self, schema: str, columns: dict[str, list[str]]) -> sqlite3.Connection:
        """Connect with full synchronisation, create ``schema`` and check that every table
        has ``columns`` and the file passes SQLite's quick check."""
        db = self._db = sqlite3.connect(self.path)
        db.execute("PRAGMA synchronous = FULL")
        with db:
            db.executescript(schema)
        for table, cols in columns.items():
            have = [r[1] for r in db.execute(f"PRAGMA table_info({table})")]
            if have != cols:
                raise sqlite3.DatabaseError(
                    f"table {table!r} has the columns {have}, not those of this jitterid version"
                )
        if db.execute("PRAGMA quick_check").fetchone()[0] != "ok":
            raise sqlite3.DatabaseError("the SQLite integrity check fails")
        return db

    def close(self) -> None:
        """Close the file and release its lock."""
        if self._db is not None:
            self._db.close()
            self._db = None
        if self._lock is not None:
            with contextlib.suppress(OSError):
                self._lock.close()  # releases the lock
            self._lock = None

    @property
    def db(self) -> sqlite3.Connection:
        """The open connection."""
        if self._db is None:
            raise StoreError(f"{self.path} is closed")
        return self._db

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextlib.contextmanager
    def _errors(self, what: str):
        """SQLite errors while working -> StoreError saying what is kept and how to go on."""
        try:
            yield
        except sqlite3.IntegrityError as exc:
            raise StoreError(
                f"cannot {what} in {self.path}: {exc} (another process wrote the same "
                "row?); run one writer per --out folder, then --resume"
            ) from None
        except sqlite3.DatabaseError as exc:
            raise StoreError(
                f"cannot {what} in {self.path}: {exc}; the {self._ROWS} committed before are "
                "kept: fix the cause (disk space, permissions) and run again with --resume"
            ) from None
        except (TypeError, ValueError) as exc:
            raise StoreError(
                f"cannot {what} in {self.path}: a stored row is malformed ({exc}); move the "
                "file away and run again without --resume"
            ) from None


class Store(SqliteStore):
    """SQLite results store for one experiment (``<out>/<name>.sqlite``).

    Parameters
    ----------
    path : str or Path
        The database file; created with its folder if missing.
    experiment : Experiment
        The definition whose results it holds.
    resume : bool
        Whether existing results may be continued. Without it, a store that already holds
        results is refused (so nothing is mixed up or overwritten by accident).
    """

    def __init__(self, path: str | Path, experiment: Experiment, *, resume: bool = False) -> None:
        self.experiment = experiment
        super().__init__(path, resume=resume)

    def _open(self, resume: bool) -> None:
        experiment = self.experiment
        db = self._connect(_SCHEMA, _COLUMNS)
        meta = dict(db.execute("SELECT key, value FROM meta").fetchall())
        done = self.count_done()
        fp = experiment.fingerprint()
        if meta and meta.get("fingerprint") != fp:
            self.close()
            raise StoreError(
                f"{self.path} holds results of a different definition of experiment "
                f"{meta.get('experiment')!r} (fingerprint {meta.get('fingerprint')}, now {fp}); "
                "use another --out folder or delete the file"
            )
        if done and not resume:
            self.close()
            raise StoreError(
                f"{self.path} already holds {done} finished realizations; pass --resume to "
                "continue (or reuse) them, or use another --out folder"
            )
        self._check_rows(migrate=meta.get("row_checksums") != "1")
        with db:
            db.execute("INSERT OR REPLACE INTO meta VALUES ('row_checksums', '1')")
            for k, v in (("experiment", experiment.name), ("fingerprint", fp)):
                db.execute("INSERT OR IGNORE INTO meta VALUES (?, ?)", (k, v))
            db.execute("INSERT OR REPLACE INTO meta VALUES ('jitterid_version', ?)", (__version__,))
            db.execute(
                "INSERT OR REPLACE INTO meta VALUES ('definition', ?)",
                (json.dumps(_definition(experiment), sort_keys=True),),
            )

    def _check_rows(self, migrate: bool) -> None:
        """Compare every estimate row of a finished realization with its checksum; refuse a
        store where one was changed, added or removed after it was stored. ``migrate``: a
        store from before the checksums (none recorded yet) gets them, its rows as found."""
        db = self.db
        rows = db.execute(
            f"SELECT {_ROW} FROM estimates WHERE (case_name, realization) IN "
            "(SELECT case_name, realization FROM realizations)"
        ).fetchall()
        have = {
            (str(c), int(r), str(m)): str(h)
            for c, r, m, h in db.execute(
                "SELECT case_name, realization, method, sha256 FROM row_checksums WHERE "
                "(case_name, realization) IN (SELECT case_name, realization FROM realizations)"
            )
        }
        sums = {(str(row[1]), int(row[2]), str(row[3])): _checksum(row) for row in rows}
        if migrate and not have:
            with db:
                db.executemany(
                    "INSERT OR REPLACE INTO row_checksums VALUES (?, ?, ?, ?)",
                    [(*k, h) for k, h in sums.items()],
                )
            return
        changed = sorted(k for k, h in sums.items() if have.get(k) != h)
        removed = sorted(set(have) - set(sums))
        if changed or removed:
            what = [f"{c}/{r}/{m} changed or added" for c, r, m in changed[:3]]
            what += [f"{c}/{r}/{m} removed" for c, r, m in removed[:3]]
            n = len(changed) + len(removed)
            raise StoreError(
                f"{self.path} was modified after its results were stored: {n} estimate row(s) "
                f"do not match their checksums ({'; '.join(what)}{', ...' if n > 6 else ''}; "
                "case/realization/method). Its results cannot be trusted: move it away (or "
                "delete it) and run again without --resume"
            )

    def count_done(self) -> int:
        return int(self.db.execute("SELECT COUNT(*) FROM realizations").fetchone()[0])

    def done(self) -> set[tuple[str, int]]:
        """The finished (case name, realization index) pairs."""
        with self._errors("read"):
            rows = self.db.execute("SELECT case_name, realization FROM realizations").fetchall()
        return {(str(c), int(r)) for c, r in rows}

    def add_realization(self, rows: Sequence[Estimate], elapsed_s: float) -> None:
        """Commit all estimates of one realization, and mark it done, in one transaction."""
        if not rows or len({(e.case_name, e.realization) for e in rows}) != 1:
            raise ValueError("rows must be the estimates of exactly one realization")
        first = rows[0]
        db = self.db
        with self._errors(f"store realization {first.realization} of case {first.case_name!r}"), db:
            # Rows of a realization not marked done are leftovers (a damaged store): replace.
            for table in ("estimates", "row_checksums"):
                db.execute(
                    f"DELETE FROM {table} WHERE case_name = ? AND realization = ?",
                    (first.case_name, first.realization),
                )
            db.execute(
                "INSERT INTO realizations VALUES (?, ?, ?)",
                (first.case_name, first.realization, elapsed_s),
            )
            db.executemany(
                "INSERT INTO estimates VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                [
                    (
                        self.experiment.name,
                        e.case_name,
                        e.realization,
                        e.method,
                        json.dumps(e.params),
                        json.dumps(e.stderr),
                        e.jitter_std,
                        e.noise_std,
                        e.cost,
                        int(e.success),
                        e.status,
                        e.message,
                        e.nfev,
                        e.elapsed_s,
                    )
                    for e in rows
                ],
            )
            stored = db.execute(
                f"SELECT {_ROW} FROM estimates WHERE case_name = ? AND realization = ?",
                (first.case_name, first.realization),
            ).fetchall()
            db.executemany(
                "INSERT INTO row_checksums VALUES (?, ?, ?, ?)",
                [(row[1], row[2], row[3], _checksum(row)) for row in stored],
            )

    def estimates(self, runs: int | None = None) -> list[Estimate]:
        """Stored estimates of realizations ``0..runs-1`` (all if None), in a stable order."""
        limit = -1 if runs is None else min(runs, 2**62)
        with self._errors("read the estimates"):
            return self._estimates(limit)

    def _estimates(self, limit: int) -> list[Estimate]:
        cur = self.db.execute(
            "SELECT e.case_name, e.realization, method, params, stderr, jitter_std, noise_std, "
            "cost, success, status, message, nfev, e.elapsed_s FROM estimates e JOIN "
            "realizations r ON e.case_name = r.case_name AND e.realization = r.realization "
            "WHERE ? < 0 OR e.realization < ? ORDER BY e.case_name, e.realization, method",
            (limit, limit),
        )
        return [
            Estimate(
                c,
                int(r),
                m,
                _json_dict(p),
                _json_dict(s),
                _f(j),
                _f(n),
                _f(cost),
                bool(ok),
                st,
                msg,
                int(nf),
                float(el),
            )
            for c, r, m, p, s, j, n, cost, ok, st, msg, nf, el in cur
        ]

    def export_csv(self, path: str | Path, runs: int | None = None) -> Path:
        """Write the estimates as CSV, one row per (case, realization, estimator).

        Each parameter ``p`` gets the columns ``p`` and ``p_stderr``; ``jitter_std`` is the
        std of the fitted (or known) jitter law, the paper's sigma for the family (26).
        """
        rows = self.estimates(runs)
        names: list[str] = []
        for e in rows:
            names += [k for k in e.params if k not in names]
        head = [
            "experiment",
            "case",
            "realization",
            "method",
            *names,
            *(f"{k}_stderr" for k in names),
            "jitter_std",
            "noise_std",
            "cost",
            "success",
            "status",
            "nfev",
            "elapsed_s",
            "message",
        ]
        out = Path(path)

        def write(fh: io.TextIOBase) -> None:
            w = csv.writer(fh)
            w.writerow(head)
            for e in rows:
                w.writerow(
                    [
                        self.experiment.name,
                        e.case_name,
                        e.realization,
                        e.method,
                        *(_cell(e.params.get(k)) for k in names),
                        *(_cell(e.stderr.get(k)) for k in names),
                        _cell(e.jitter_std),
                        _cell(e.noise_std),
                        _cell(e.cost),
                        int(e.success),
                        e.status,
                        e.nfev,
                        f"{e.elapsed_s:.4f}",
                        e.message,
                    ]
                )

        return atomic_write(out, write)


def _checksum(row: Sequence[object]) -> str:
    """SHA-256 of an estimate row as SQLite returns it (floats written exactly by repr)."""
    text = json.dumps([repr(v) if isinstance(v, float) else v for v in row])
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _json_dict(text: str) -> dict[str, float]:
    value = json.loads(text)
    if not isinstance(value, dict):
        raise TypeError(f"expected a JSON object, got {text[:40]!r}")
    return value


def _f(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _cell(x: float | None) -> str:
    return "" if x is None else repr(float(x))


def _definition(exp: Experiment) -> dict[str, object]:
    return asdict(exp)
