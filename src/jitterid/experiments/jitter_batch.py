"""A production batch of jitter measurements: many sine records, one table.

:func:`run_batch` measures every record of a folder, a glob or a multi-record file with
:func:`jitterid.measure_jitter` plus its converter figures, and writes one row per record
(jitter std, interval, noise, SNR/SINAD/ENOB/THD/SFDR, the jitter-limited SNR, status and
error) to an SQLite table and a CSV file:

- **records**: each ``.csv``/``.npz`` data file (the format of :func:`jitterid.load`, a
  ``y`` column with no input) is one record; a *multi-record file* is a ``.npz`` whose
  ``y`` is 2-D (one record per row, ``T`` in its ``metadata`` JSON as for a data file) or a
  2-D ``.npy`` (T from the options). A file's records are read one row at a time: the
  batch never holds more than the records in flight;
- **resumable**: each row is committed to the SQLite store as its record finishes (one
  transaction), so a batch killed at any moment (``kill -9``) keeps every finished row;
  ``resume=True`` (``--resume``) skips them. The store remembers the options and refuses to
  mix rows measured with others;
- **never stopped by a bad record**: a record that cannot be read or measured (corrupt,
  constant, too short, not a sine) is a row with status ``ERROR`` and its error, and the
  batch goes on;
- **parallel**: 1 worker runs in this process; more run on a local Dask cluster
  (:func:`jitterid.experiments.runner.dask_client`, loopback only), or on the Dask
  scheduler given (its workers need jitterid and must see the record files at the same
  paths; the rows of multi-record files are sent to them). Every fit runs single-threaded,
  so the table does not depend on the number of workers.
"""

from __future__ import annotations

import csv
import glob
import hashlib
import io
import json
import math
import time
import zipfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack
from dataclasses import asdict, dataclass
from itertools import islice
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from .. import __version__
from .._threads import single_thread
from ..io import TIME_UNITS, atomic_write, parse_time
from .store import SqliteStore, StoreError

if TYPE_CHECKING:
    from dask.distributed import Client

    from ..metrology.meter import JitterMeasurement

__all__ = [
    "BATCH_COLUMNS",
    "BatchOptions",
    "BatchStore",
    "BatchSummary",
    "RecordRef",
    "find_records",
    "measure_record",
    "run_batch",
]

#: The file kinds a batch reads.
RECORD_SUFFIXES = (".csv", ".npz", ".npy")
#: The table's columns, in order (times in s, frequencies in Hz, levels in dB).
BATCH_COLUMNS = (
    "record",
    "source",
    "row",
    "N",
    "T_s",
    "frequency_hz",
    "jitter_std_s",
    "jitter_std_stderr_s",
    "jitter_lo95_s",
    "jitter_hi95_s",
    "noise_std",
    "snr_db",
    "sinad_db",
    "enob_bits",
    "thd_db",
    "sfdr_db",
    "jitter_limited_snr_db",
    "family",
    "law_verdict",
    "harmonics",
    "status",
    "error",
    "message",
    "elapsed_s",
)
_TEXT = {"record", "source", "family", "law_verdict", "status", "error", "message"}
_INT = {"row", "N", "harmonics"}
_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);\n"
    "CREATE TABLE IF NOT EXISTS records ("
    + ", ".join(
        f"{c} {'TEXT' if c in _TEXT else 'INTEGER' if c in _INT else 'REAL'}"
        + (" PRIMARY KEY" if c == "record" else "")
        for c in BATCH_COLUMNS
    )
    + ");"
)
#: The CSV and SQLite files a batch writes into its folder.
TABLE_NAME = "jitter_batch"


@dataclass(frozen=True)
class BatchOptions:
    """How every record of a batch is measured (see :func:`jitterid.measure_jitter`).

    Attributes
    ----------
    method : str or None
        ``"ml"`` or ``"gaussian"``; None: :func:`~jitterid.measure_jitter`'s default.
    laws : tuple of str or None
        Jitter families; None: the default ones.
    frequency : float or None
        The tone's frequency (Hz), a start the fit refines.
    band_hz : (float, float) or None
        A band to search for the frequency's aliases.
    harmonics : int or None
        Harmonics of the sine model; None: the highest one that stands above the noise
        (:func:`~jitterid.metrology.converter.significant_harmonics`), per record.
    resolution : float or None
        The noise floor (units of y); None: the meter's default.
    full_scale : float or None
        The converter's full-scale range, peak to peak (units of y), for ENOB and dBFS.
    T : str or None
        The sampling interval for records whose file does not give it (``"1ns"``; a bare
        number is in the file's time unit).
    """

    method: str | None = None
    laws: tuple[str, ...] | None = None
    frequency: float | None = None
    band_hz: tuple[float, float] | None = None
    harmonics: int | None = None
    resolution: float | None = None
    full_scale: float | None = None
    T: str | None = None

    def fingerprint(self) -> str:
        """A short hash of the options (the store refuses rows measured with others)."""
        text = json.dumps(asdict(self), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class RecordRef:
    """One record of a batch: a file, or a row of a multi-record file (``row >= 0``)."""

    record: str
    source: str
    row: int


@dataclass(frozen=True)
class BatchSummary:
    """What :func:`run_batch` did.

    Attributes
    ----------
    store, csv : Path
        The SQLite table and its CSV export.
    total, already_done, new, errors : int
        Records in the batch, skipped as finished (``resume``), measured now, and rows of
        the whole table with status ``ERROR``.
    wall_s : float
        Wall time of this call.
    """

    store: Path
    csv: Path
    total: int
    already_done: int
    new: int
    errors: int
    wall_s: float


# --------------------------------------------------------------------------- records


def find_records(source: str | Path) -> list[Path]:
    """The record files of a batch source, sorted: a folder's ``.csv``/``.npz``/``.npy``
    files, the files a glob pattern matches, or one file.

    Parameters
    ----------
    source : str or Path
        A folder, a glob pattern (``"runs/*.csv"``) or a file.

    Returns
    -------
    list of Path

    Raises
    ------
    ValueError
        Nothing matches: the message says what was looked for.
    """
    p = Path(source)
    if p.is_dir():
        files = sorted(
            q for q in p.iterdir() if q.is_file() and q.suffix.lower() in RECORD_SUFFIXES
        )
        what = f"the folder {p} holds no {', '.join(RECORD_SUFFIXES)} record files"
    elif p.is_file():
        files, what = [p], ""
    elif glob.has_magic(str(source)):
        files = sorted(
            Path(q)
            for q in glob.glob(str(source), recursive=True)
            if Path(q).is_file() and Path(q).suffix.lower() in RECORD_SUFFIXES
        )
        what = f"the pattern {source!r} matches no {', '.join(RECORD_SUFFIXES)} record files"
    else:
        raise ValueError(f"{source}: no such file or folder (give a folder, a glob or a file)")
    if not files:
        raise ValueError(what)
    return files


def _npy_header(fh: Any) -> tuple[tuple[int, ...], bool, np.dtype[Any]]:
    version = np.lib.format.read_magic(fh)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(fh)
    if version in ((2, 0), (3, 0)):
        return np.lib.format.read_array_header_2_0(fh)
    raise ValueError(f"unsupported .npy version {version}")


def _rows_in(path: Path) -> int:
    """Records held by a multi-record file (its 2-D y's rows); 0 for a single-record file."""
    try:
        if path.suffix.lower() == ".npy":
            with path.open("rb") as fh:
                shape, _, _ = _npy_header(fh)
            return shape[0] if len(shape) == 2 else 0
        if path.suffix.lower() == ".npz":
            with zipfile.ZipFile(path) as zf:
                if "y.npy" not in zf.namelist():
                    return 0
                with zf.open("y.npy") as fh:
                    shape, _, _ = _npy_header(fh)
            return shape[0] if len(shape) == 2 else 0
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return 0  # read (and refused) as a single record, which names the problem
    return 0


def is_multi_record(path: str | Path) -> bool:
    """Whether ``path`` is a multi-record file (a 2-D ``y`` in a ``.npz``, a 2-D ``.npy``).

    Parameters
    ----------
    path : str or Path
        The file.
    """
    p = Path(path)
    return p.is_file() and _rows_in(p) > 0


def _refs(files: Iterable[Path], root: Path | None) -> Iterator[RecordRef]:
    for f in files:
        name = str(f.relative_to(root)) if root is not None and f.is_relative_to(root) else str(f)
        rows = _rows_in(f)
        if rows:
            for r in range(rows):
                yield RecordRef(f"{name}#{r}", str(f), r)
        else:
            yield RecordRef(name, str(f), -1)


def _file_T(meta: dict[str, Any], given: str | None, path: Path) -> float:
    unit = str(meta.get("time_unit", "s"))
    if unit not in TIME_UNITS:
        raise ValueError(f"{path}: time_unit {unit!r} is not one of {sorted(TIME_UNITS)}")
    if given is not None:
        return parse_time(given, unit, "T")
    if "T" not in meta:
        raise ValueError(
            f"{path}: the sampling interval is not given; add T to the file's metadata (as for "
            "a data file) or give T (--T)"
        )
    return float(meta["T"]) * TIME_UNITS[unit]


def _rows(path: Path, options: BatchOptions) -> Iterator[tuple[np.ndarray, float] | str]:
    """The rows of a multi-record file, one at a time, each as (y, T) or an error text
    (a row that cannot be read; the rows after a broken one are errors as well)."""
    total = _rows_in(path)
    done = 0
    try:
        with ExitStack() as stack:
            fh: IO[bytes]
            if path.suffix.lower() == ".npy":
                T = _file_T({}, options.T, path)
                fh = stack.enter_context(path.open("rb"))
            else:
                zf = stack.enter_context(zipfile.ZipFile(path))
                meta: dict[str, Any] = {}
                if "metadata.npy" in zf.namelist():
                    with zf.open("metadata.npy") as mf:
                        raw = np.lib.format.read_array(mf, allow_pickle=False)
                    meta = json.loads(str(raw[()]))
                    if not isinstance(meta, dict):
                        raise ValueError("its 'metadata' is not a JSON object")
                T = _file_T(meta, options.T, path)
                fh = stack.enter_context(zf.open("y.npy"))
            shape, fortran, dtype = _npy_header(fh)
            if fortran:
                raise ValueError("y is stored in Fortran order; save it C-ordered (np.save)")
            size = shape[1] * dtype.itemsize
            for done in range(total):
                buf = fh.read(size)
                if len(buf) != size:
                    raise ValueError(f"the data end in row {done}: the file is truncated")
                yield np.frombuffer(buf, dtype=dtype).astype(float), T
            done = total
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError, TypeError) as exc:
        msg = f"{path}: cannot read row {done} ({type(exc).__name__}: {exc})"
        for _ in range(done, total):
            yield msg


Task = tuple[RecordRef, Any]  # (record, None: load the file | (y, T) | an error text)


def _tasks(refs: Iterable[RecordRef], options: BatchOptions, skip: set[str]) -> Iterator[Task]:
    """The records not in ``skip``, each with its payload; a multi-record file's rows are
    read in order as they are sent (a finished row is read past, not kept)."""
    open_rows: tuple[str, Iterator[Any]] | None = None
    for ref in refs:
        if ref.row < 0:
            if ref.record not in skip:
                yield ref, None
            continue
        if open_rows is None or open_rows[0] != ref.source:
            open_rows = (ref.source, _rows(Path(ref.source), options))
        payload = next(open_rows[1], "the file holds fewer rows than its header says")
        if ref.record not in skip:
            yield ref, payload


# --------------------------------------------------------------------------- one record


def _nan_row(ref: RecordRef) -> dict[str, Any]:
    row: dict[str, Any] = {c: math.nan for c in BATCH_COLUMNS}
    row.update(record=ref.record, source=ref.source, row=ref.row, N=0, harmonics=0)
    row.update(family="", law_verdict="", status="ERROR", error="", message="")
    return row


def measurement_row(ref: RecordRef, m: JitterMeasurement, n: int) -> dict[str, Any]:
    """The table row of one measurement (with its converter figures, if attached).

    Parameters
    ----------
    ref : RecordRef
        The record.
    m : JitterMeasurement
        Its measurement.
    n : int
        The record's length.
    """
    from ..metrology.reading import law_evidence

    lo, hi = m.interval(0.95)
    row = _nan_row(ref)
    fig = m.converter
    row.update(
        N=int(n),
        T_s=m.T,
        frequency_hz=m.frequency,
        jitter_std_s=m.jitter_std,
        jitter_std_stderr_s=m.jitter_std_stderr,
        jitter_lo95_s=lo,
        jitter_hi95_s=hi,
        noise_std=m.noise_std,
        family=m.family,
        law_verdict=law_evidence(m).verdict,
        harmonics=int(getattr(m.fit.structure, "harmonics", 1)),
        status=m.status.name,
        message=m.message,
    )
    if fig is not None:
        row.update(
            snr_db=fig.snr_db,
            sinad_db=fig.sinad_db,
            enob_bits=fig.enob_bits,
            thd_db=fig.thd_db,
            sfdr_db=fig.sfdr_db,
            jitter_limited_snr_db=fig.jitter_limited_snr_db,
        )
    return row


def measure_record(y: np.ndarray, T: float, options: BatchOptions) -> tuple[JitterMeasurement, int]:
    """Measure one record as a batch does: the harmonics (``options.harmonics`` or the
    significant ones), :func:`jitterid.measure_jitter`, the converter figures.

    Parameters
    ----------
    y : ndarray
        The record.
    T : float
        Its sampling interval (s).
    options : BatchOptions
        How to measure it.

    Returns
    -------
    (JitterMeasurement, int)
        The measurement with its converter figures, and the harmonics modelled.
    """
    from ..metrology.converter import significant_harmonics
    from ..metrology.meter import measure_jitter

    harmonics = options.harmonics
    if harmonics is None:
        try:
            harmonics = significant_harmonics(y, T, options.frequency)
        except ValueError:  # a record the meter refuses too: its own message says why
            harmonics = 1
    kwargs: dict[str, Any] = {"harmonics": harmonics, "band_hz": options.band_hz}
    if options.method is not None:
        kwargs["method"] = options.method
    if options.laws:
        kwargs["laws"] = options.laws
    if options.resolution is not None:
        kwargs["resolution"] = options.resolution
    m = measure_jitter(y, T, options.frequency, **kwargs)
    return m.with_converter(y, full_scale=options.full_scale), harmonics


def _run_task(task: Task, options: BatchOptions) -> dict[str, Any]:
    """One record's row; any error becomes a row with status ERROR (the batch goes on)."""
    from ..io import load

    ref, payload = task
    t0 = time.perf_counter()
    try:
        with single_thread():
            if isinstance(payload, str):  # the row could not be read
                raise OSError(payload)
            if payload is None:
                ds = load(ref.source, T=options.T, require_input=False)
                y, T = ds.data.y, ds.data.T
            else:
                y, T = payload
            m, _ = measure_record(y, T, options)
            row = measurement_row(ref, m, y.size)
    except Exception as exc:  # noqa: BLE001 - a bad record is a row, the batch goes on
        row = _nan_row(ref)
        row["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    row["elapsed_s"] = time.perf_counter() - t0
    return row


# --------------------------------------------------------------------------- the table


class BatchStore(SqliteStore):
    """The batch's SQLite table (``<out>/jitter_batch.sqlite``): one row per record,
    committed as the record finishes.

    Parameters
    ----------
    path : str or Path
        The database file.
    options : BatchOptions
        The options its rows are measured with (a store of other options is refused).
    resume : bool
        Continue a table that holds rows (without it, such a table is refused).
    """

    _ROWS = "records"

    def __init__(self, path: str | Path, options: BatchOptions, *, resume: bool = False) -> None:
        self.options = options
        super().__init__(path, resume=resume)

    def _open(self, resume: bool) -> None:
        db = self._connect(_SCHEMA, {"meta": ["key", "value"], "records": list(BATCH_COLUMNS)})
        meta = dict(db.execute("SELECT key, value FROM meta").fetchall())
        fp = self.options.fingerprint()
        if meta and meta.get("fingerprint") != fp:
            raise StoreError(
                f"{self.path} holds rows measured with other options ({meta.get('options')}); "
                "give the same options to --resume, or use another --out folder"
            )
        done = self.count()
        if done and not resume:
            raise StoreError(
                f"{self.path} already holds {done} finished records; pass --resume to skip "
                "them and measure the rest, or use another --out folder"
            )
        with db:
            db.execute("INSERT OR IGNORE INTO meta VALUES ('fingerprint', ?)", (fp,))
            db.execute(
                "INSERT OR IGNORE INTO meta VALUES ('options', ?)",
                (json.dumps(asdict(self.options), sort_keys=True),),
            )
            db.execute("INSERT OR REPLACE INTO meta VALUES ('jitterid_version', ?)", (__version__,))

    def count(self) -> int:
        """Rows stored."""
        return int(self.db.execute("SELECT COUNT(*) FROM records").fetchone()[0])

    def done(self) -> set[str]:
        """The finished records' names."""
        with self._errors("read"):
            return {str(r[0]) for r in self.db.execute("SELECT record FROM records")}

    def add(self, row: dict[str, Any]) -> None:
        """Commit one record's row (one transaction)."""
        values = [_sql(row[c]) for c in BATCH_COLUMNS]
        with self._errors(f"store the row of {row['record']!r}"), self.db:
            self.db.execute(
                f"INSERT INTO records VALUES ({', '.join('?' * len(BATCH_COLUMNS))})", values
            )

    def rows(self) -> list[dict[str, Any]]:
        """Every row, ordered by source file and row."""
        with self._errors("read the rows"):
            cur = self.db.execute(
                f"SELECT {', '.join(BATCH_COLUMNS)} FROM records ORDER BY source, row, record"
            )
            return [{c: _py(c, v) for c, v in zip(BATCH_COLUMNS, r, strict=True)} for r in cur]

    def export_csv(self, path: str | Path) -> Path:
        """Write the table as CSV (times in s; an empty cell where a value is undefined)."""
        rows = self.rows()

        def write(fh: io.TextIOBase) -> None:
            w = csv.writer(fh)
            w.writerow(BATCH_COLUMNS)
            for r in rows:
                w.writerow([_cell(c, r[c]) for c in BATCH_COLUMNS])

        return atomic_write(Path(path), write)


def _sql(v: Any) -> Any:
    if isinstance(v, float) and math.isnan(v):
        return None
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


def _py(column: str, v: Any) -> Any:
    if column in _TEXT:
        return "" if v is None else str(v)
    if column in _INT:
        return -1 if v is None else int(v)
    return math.nan if v is None else float(v)


def _cell(column: str, v: Any) -> str:
    if column in _TEXT or column in _INT:
        return str(v)
    return "" if math.isnan(v) else repr(float(v))


# --------------------------------------------------------------------------- the run


def run_batch(
    source: str | Path,
    out: str | Path,
    options: BatchOptions | None = None,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> BatchSummary:
    """Measure every record of ``source`` into one table (``<out>/jitter_batch.sqlite`` and
    ``.csv``), each row committed as its record finishes.

    Parameters
    ----------
    source : str or Path
        A folder, a glob pattern or a (multi-record) file (:func:`find_records`).
    out : str or Path
        The output folder.
    options : BatchOptions, optional
        How each record is measured (default: :class:`BatchOptions`'s defaults).
    workers : int
        1: in this process. More: a local Dask cluster of that many single-threaded
        processes (never more than there are records to measure).
    scheduler : str, optional
        A running Dask scheduler's address (``tcp://host:port``); ``workers`` is then
        ignored. Connect only to a cluster you trust: it runs code for you and its
        results are unpickled here.
    resume : bool
        Continue a table that already holds rows: its finished records are skipped.
    progress : bool
        A tqdm progress bar on stderr.
    on_row : callable, optional
        Called with each new row (a dict of :data:`BATCH_COLUMNS`) after it is committed.

    Returns
    -------
    BatchSummary

    Raises
    ------
    ValueError
        A source with no records, or bad ``workers``.
    StoreError
        A table that cannot be used (exists without ``resume``, other options, in use).
    """
    from tqdm import tqdm

    from .runner import _check_address, local_workers

    local_workers(workers)  # refuses a count that is not an integer >= 1
    if scheduler is not None:
        _check_address(scheduler)
    opts = options if options is not None else BatchOptions()
    t0 = time.perf_counter()
    files = find_records(source)
    root = Path(source) if Path(source).is_dir() else None
    total = sum(_rows_in(f) or 1 for f in files)
    out_dir = Path(out)
    db_path = out_dir / f"{TABLE_NAME}.sqlite"
    csv_path = out_dir / f"{TABLE_NAME}.csv"
    with BatchStore(db_path, opts, resume=resume) as store:
        done = store.done()
        names = {r.record for r in _refs(files, root)}
        already = len(done & names)
        todo = total - already
        tasks = _tasks(_refs(files, root), opts, done)
        bar = tqdm(
            total=total,
            initial=already,
            desc="jitter batch",
            unit="record",
            disable=not progress,
            dynamic_ncols=True,
        )
        new = 0
        with bar:
            for row in _execute(tasks, opts, todo, workers, scheduler):
                store.add(row)
                new += 1
                bar.update(1)
                if on_row is not None:
                    on_row(row)
        store.export_csv(csv_path)
        errors = sum(1 for r in store.rows() if r["status"] == "ERROR")
    return BatchSummary(db_path, csv_path, total, already, new, errors, time.perf_counter() - t0)


def _execute(
    tasks: Iterator[Task], options: BatchOptions, count: int, workers: int, scheduler: str | None
) -> Iterator[dict[str, Any]]:
    """The tasks' rows in completion order: here, or a few per worker in flight on Dask."""
    if count <= 0:
        return
    from .runner import dask_client, local_workers

    # a local cluster no larger than the work (the one rule: runner.local_workers)
    n = workers if scheduler is not None else local_workers(workers, count)
    with ExitStack() as stack:
        client = stack.enter_context(dask_client(n, scheduler))
        if client is None:  # one local worker: this process
            for task in tasks:
                yield _run_task(task, options)
            return
        yield from _submit(client, tasks, options)


def _submit(
    client: Client, tasks: Iterator[Task], options: BatchOptions
) -> Iterator[dict[str, Any]]:
    """The tasks on ``client``'s workers, a few per worker in flight (the records are read
    as they are sent), in completion order; a task that fails on its worker (the worker
    died) is a row with its error."""
    from dask.distributed import as_completed

    n = max(len(client.scheduler_info().get("workers", {})), 1)
    refs: dict[Any, RecordRef] = {}
    pending = as_completed()

    def send(task: Task) -> None:
        fut = client.submit(_run_task, task, options, pure=False)
        refs[fut.key] = task[0]
        pending.add(fut)

    for task in islice(tasks, 2 * n + 2):
        send(task)
    for fut in pending:
        ref = refs.pop(fut.key)
        try:
            row = fut.result()
        except Exception as exc:  # noqa: BLE001 - a lost worker: the record's row says so
            row = _nan_row(ref)
            row["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
            row["elapsed_s"] = math.nan
        fut.release()
        nxt = next(tasks, None)
        if nxt is not None:
            send(nxt)
        yield row
