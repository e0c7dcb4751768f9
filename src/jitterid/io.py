"""Read and write sampled data sets: CSV or NumPy ``.npz``, with explicit units.

File format
-----------
A **data file** has one row per sample, taken on a regular *nominal* grid, and the columns

==========  ===============================================================================
``k``       nominal sample index (consecutive integers), *or*
``t``       nominal sample time (regular grid, within 0.1 % of ``T``)
``y``       the measured output samples
``u``       optional: the input as a zero-order hold on the same grid (u[k] held on
            [t_k, t_k + T), as a DAC does; the last value is held on after the last
            sample, so that jittered instants past the grid see it)
==========  ===============================================================================

A file of samples only (a ``y`` column, no ``k`` or ``t``: a sine record for the jitter
meter) is read as the samples k = 0, 1, ... when T is given (``# T:`` or ``T=``).

An **input file** (when the data file has no ``u`` column) has either the columns ``k`` or
``t`` and ``u`` (a zero-order hold on the data's grid; it may start earlier and end later)
or the columns ``time`` and ``level`` (switch times: ``level[j]`` is held from ``time[j]``
until the next switch, the last one until ``end``). The system is at rest before the input's
first time, and the input is zero there.

**Metadata** are ``# key: value`` lines before the CSV header, a 0-d string array
``metadata`` holding a JSON object in a ``.npz``, or a JSON sidecar next to the file
(``data.csv`` -> ``data.json``). Keys: ``T`` (nominal sampling interval), ``time_unit``
(``s``, ``ms``, ``us``, ``ns`` or ``min``; default ``s``, or the data file's unit for an
input file), ``y_unit``, ``u_unit`` (free text), ``noise_std`` (measurement-noise std in
y units, if known) and, for a switch-time input file, ``end`` (when the input stops;
default: one interval after the last nominal sample). Any other key must start with ``x-``
(``# x-operator: ...``) and is kept as a note; an unknown key without it is refused with the
closest known key, so that a typo such as ``time_units`` cannot silently leave the times in
seconds.

Cells are plain ASCII decimal numbers (``0.25``, ``-1e-3``): digit separators (``1_000``),
non-ASCII digits and ``inf`` are refused. Sizes stated in a ``.npz`` member's header are checked
against the member before any memory is allocated.

Times are converted to seconds, so every frequency downstream is in Hz. The library's time
origin is the first nominal sample: :attr:`Dataset.t0` records the file time it came from.

Every malformed file is refused with a :class:`DataFileError` (a ``ValueError``) that names
the file, the line (CSV) or index (``.npz``) and the column, and says how to fix it.
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import hashlib
import json
import math
import os
import re
import stat
import tempfile
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import IO, Any, Self

import numpy as np
from numpy.typing import NDArray

from ._checks import nesting_depth
from .data import SampledData
from .inputs import Input, PiecewiseConstant

__all__ = [
    "DataFileError",
    "Dataset",
    "Source",
    "atomic_write",
    "load",
    "parse_time",
    "save_data",
    "save_input",
]

FloatArray = NDArray[np.float64]
PathLike = str | Path

#: Seconds per supported time unit.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0}
_SCALE_DEC = {
    "s": Decimal(1),
    "ms": Decimal("1e-3"),
    "us": Decimal("1e-6"),
    "ns": Decimal("1e-9"),
    "min": Decimal(60),
}
#: Largest deviation of a nominal time from the regular grid, as a fraction of T.
GRID_TOL = 1e-3
_NUMERIC_KEYS = ("T", "noise_std", "end")
_TEXT_KEYS = ("time_unit", "y_unit", "u_unit")
_DATA_COLUMNS = ("k", "t", "y", "u")
_ZOH_COLUMNS = ("k", "t", "u")
_SWITCH_COLUMNS = ("time", "level")
_MISSING = ("", "na", "nan", "n/a", "null", "none", "-")
_META_KEYS = (*_NUMERIC_KEYS, *_TEXT_KEYS)
#: Deepest nesting accepted in JSON metadata (a flat object needs 1).
_MAX_DEPTH = 32
#: A plain decimal number: ASCII digits only, no digit separators, no inf/nan.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)
#: Largest data file (cells) read into memory; larger files are refused up front.
MAX_CELLS = 200_000_000
#: Extra time (in sampling intervals, at least) a 'u' column's last value is held after the
#: last sample, so that a jittered last instant still sees a defined input.
_U_TAIL = 64


class DataFileError(ValueError):
    """A data or input file that cannot be used; the message says where and how to fix it.

    Examples
    --------
    >>> import os, tempfile
    >>> import jitterid as ji
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "bad.csv")
    ...     with open(path, "w") as fh:
    ...         print("nothing,useful", file=fh)
    ...     try:
    ...         ji.load(path)
    ...     except ji.DataFileError as err:
    ...         print(type(err).__name__)
    DataFileError
    """


@dataclass(frozen=True)
class Source:
    """A file that went into a data set: its role, path and SHA-256 checksum.

    Parameters
    ----------
    role : str
        What the file holds (e.g. data, input, sidecar).
    path : str
        The file's path, as read.
    sha256 : str
        Hex SHA-256 checksum of its bytes.

    Examples
    --------
    >>> import os, tempfile
    >>> import jitterid as ji
    >>> G, u = ji.TransferFunction([2.0], [1.0, 2.0]), ji.telegraph_input(5.0, rng=1)
    >>> data = ji.simulate(G, u, ji.NoJitter(), 0.1, 40, 0.01, rng=2)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = ji.save_data(os.path.join(tmp, "run.npz"), data)
    ...     ds = ji.load(path, require_input=False)
    >>> src = ds.sources[0]
    >>> isinstance(src, ji.Source), src.role, len(src.sha256)
    (True, 'data', 64)
    """

    role: str
    path: str
    sha256: str


@dataclass(frozen=True, eq=False)
class Dataset:
    """A loaded data set, ready for :func:`jitterid.fit`.

    Attributes
    ----------
    data : SampledData
        Samples on the grid k T (time origin at the first nominal sample), with the input.
    t0 : float
        File time (s) of the first nominal sample: file time = library time + t0.
    units : dict
        ``{"time": "s", "frequency": "Hz", "y": ..., "u": ...}`` (y, u as given, or "").
    metadata : dict
        All metadata keys read from the data file (after merging its sidecar).
    sources : tuple of Source
        The files read, with their checksums (data first).
    notes : tuple of str
        What loading assumed beyond the file (e.g. a 'u' column's last value held on).

    Examples
    --------
    >>> import os, tempfile
    >>> import jitterid as ji
    >>> G, u = ji.TransferFunction([2.0], [1.0, 2.0]), ji.telegraph_input(5.0, rng=1)
    >>> data = ji.simulate(G, u, ji.NoJitter(), 0.1, 40, 0.01, rng=2)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = ji.save_data(os.path.join(tmp, "run.npz"), data)
    ...     ds = ji.load(path, require_input=False)
    >>> isinstance(ds, ji.Dataset), ds.data.N, ds.t0, ds.units["time"]
    (True, 40, 0.0, 's')
    """

    data: SampledData
    t0: float
    units: dict[str, str]
    metadata: dict[str, Any] = field(repr=False)
    sources: tuple[Source, ...]
    notes: tuple[str, ...] = ()

    @property
    def sha256(self) -> str:
        """Checksum of the data file."""
        return self.sources[0].sha256


# ---------------------------------------------------------------------------------- tables


@dataclass
class _Table:
    """Columns read from one file, with a way to name where row i came from."""

    path: Path
    columns: dict[str, FloatArray]
    where: Callable[[int], str]
    meta: dict[str, Any]

    def fail(self, msg: str) -> DataFileError:
        return DataFileError(f"{self.path}: {msg}")

    @property
    def nrows(self) -> int:
        return next(iter(self.columns.values())).size if self.columns else 0


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _check_key(path: Path | str, key: str, origin: str) -> None:
    """Refuse an unknown metadata key (a typo would silently change the units)."""
    if key in _META_KEYS or key.startswith("x-"):
        return
    lower = {k.lower(): k for k in _META_KEYS}
    close = difflib.get_close_matches(key.lower(), list(lower), n=1, cutoff=0.5)
    hint = f" Did you mean {lower[close[0]]!r}?" if close else ""
    raise DataFileError(
        f"{path}: metadata key {key!r} ({origin}) is not known.{hint} Known keys: "
        f"{', '.join(_META_KEYS)}; to keep a note, prefix its key with 'x-' (e.g. 'x-{key}')"
    )


class _Number(float):
    """A metadata number that remembers the exact decimal it was written as, so that a time
    converts to seconds exactly as :func:`save_data` intended (see :func:`_seconds`)."""

    exact: Decimal

    def __new__(cls, value: float, raw: Any) -> Self:
        obj = super().__new__(cls, value)
        obj.exact = Decimal(raw.strip()) if isinstance(raw, str) else Decimal(repr(value))
        return obj

    def __reduce__(self) -> Any:  # pickles (and copies) as a plain float
        return (float, (float(self),))


def _seconds(value: float, unit: str) -> float:
    """``value`` (in ``unit``) in seconds, rounded once from the exact decimal product."""
    exact = value.exact if isinstance(value, _Number) else Decimal(repr(float(value)))
    return float(exact * _SCALE_DEC[unit])


def _meta_value(path: Path, key: str, value: Any, origin: str) -> Any:
    _check_key(path, key, origin)
    if key in _NUMERIC_KEYS:
        try:
            if isinstance(value, str):
                val = _decimal(value)
            elif isinstance(value, (int, float)):
                val = float(value)
            else:
                val = math.nan
        except (TypeError, ValueError, OverflowError):
            val = math.nan
        if (
            isinstance(value, bool)
            or not math.isfinite(val)
            or val < 0
            or (key != "noise_std" and val == 0)
        ):
            need = ">= 0" if key == "noise_std" else "> 0"
            raise DataFileError(
                f"{path}: metadata {key!r} ({origin}) must be a finite number {need}; got {value!r}"
            )
        return _Number(val, value)
    if key in _TEXT_KEYS:
        if not isinstance(value, str):
            raise DataFileError(f"{path}: metadata {key!r} ({origin}) must be text; got {value!r}")
        if key == "time_unit" and value not in TIME_UNITS:
            raise DataFileError(
                f"{path}: metadata 'time_unit' ({origin}) must be one of {sorted(TIME_UNITS)}; "
                f"got {value!r}. Convert the times or state their unit"
            )
        return value
    return value


def _merge_sidecar(path: Path, meta: dict[str, Any]) -> dict[str, Any]:
    side = path.with_suffix(".json")
    if side == path or not side.is_file():
        return meta
    extra = _json_object(side, side.read_bytes(), "the metadata sidecar")
    if not isinstance(extra, dict):
        raise DataFileError(f"{side}: the metadata sidecar must hold a JSON object {{...}}")
    out = dict(meta)
    for key, value in extra.items():
        val = _meta_value(side, str(key), value, "JSON sidecar")
        if key in out and out[key] != val:
            raise DataFileError(
                f"{path}: metadata {key!r} is {out[key]!r} in the file but {val!r} in {side.name}; "
                "keep one of them"
            )
        out[str(key)] = val
    return out


def _json_object(path: Path, raw: bytes | str, what: str) -> Any:
    """Parse JSON text, refusing invalid, non-UTF-8 or absurdly nested documents cleanly."""
    try:
        text = raw.decode("utf-8-sig") if isinstance(raw, bytes) else raw
        if nesting_depth(text) > _MAX_DEPTH:
            raise RecursionError
        return json.loads(text)
    except UnicodeDecodeError:
        raise DataFileError(f"{path}: {what} is not UTF-8 text; save it as UTF-8 JSON") from None
    except json.JSONDecodeError as exc:
        raise DataFileError(
            f"{path}: {what} must hold a JSON object but is not valid JSON ({exc}); fix the syntax"
        ) from None
    except RecursionError:
        raise DataFileError(
            f"{path}: {what} is nested too deeply to be metadata; write a flat JSON object "
            'such as {"T": 0.5, "time_unit": "s"}'
        ) from None


def _decimal(text: str) -> float:
    """A plain ASCII decimal number (ValueError otherwise; inf if it overflows)."""
    s = text.strip()
    if not _DECIMAL.fullmatch(s):
        raise ValueError(text)
    return float(s)


def _read_csv(path: Path) -> _Table:
    if path.stat().st_size > 40 * MAX_CELLS:
        raise DataFileError(
            f"{path}: the file is {path.stat().st_size / 1e9:.1f} GB, more than jitterid reads "
            "into memory; split it or thin it to fewer samples"
        )
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise DataFileError(
            f"{path}: not a UTF-8 text file; save it as CSV (comma-separated, UTF-8) or .npz"
        ) from None
    meta: dict[str, Any] = {}
    header: list[str] | None = None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    for lineno, raw in enumerate(text.split("\n"), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if header is None and ":" in line:
                key, _, value = line[1:].partition(":")
                key = key.strip()
                if not key:
                    continue
                if key in meta:
                    raise DataFileError(f"{path}: line {lineno}: metadata {key!r} is given twice")
                meta[key] = _meta_value(path, key, value.strip(), f"line {lineno}")
            continue
        try:
            cells = next(csv.reader([raw.rstrip("\r")]))
        except csv.Error as exc:
            raise DataFileError(
                f"{path}: line {lineno}: cannot split the row into cells ({exc})"
            ) from None
        if header is None:
            header, header_line = [c.strip() for c in cells], lineno
        else:
            rows.append((lineno, cells))
    if header is None:
        raise DataFileError(
            f"{path}: no header row; the first non-comment line must name the columns"
        )
    if len(header) == 1 and any(sep in header[0] for sep in (";", "\t", " ")):
        raise DataFileError(
            f"{path}: line {header_line}: the header {header[0]!r} is one column; the file must be "
            "comma-separated (e.g. 't,y')"
        )
    _check_header(path, header, header_line)
    if all(_DECIMAL.fullmatch(c) for c in header):
        raise DataFileError(
            f"{path}: line {header_line} holds numbers, not column names; the first non-comment "
            "line must name the columns: add a header line 'y' (a sine record, with a "
            "'# T: <interval>' line or T given when loading) or 'k,y' / 't,y'"
        )
    if not rows:
        raise DataFileError(f"{path}: the file has a header but no data rows")
    values = np.empty((len(rows), len(header)))
    for i, (lineno, cells) in enumerate(rows):
        if len(cells) != len(header):
            raise DataFileError(
                f"{path}: line {lineno} has {len(cells)} cell(s) but the header (line "
                f"{header_line}) has {len(header)} column(s) {header}; fix the row"
            )
        for j, cell in enumerate(cells):
            values[i, j] = _number(path, cell, lineno, header[j])
    lines = [ln for ln, _ in rows]
    return _Table(
        path,
        {name: values[:, j].copy() for j, name in enumerate(header)},
        lambda i: f"line {lines[i]}",
        _merge_sidecar(path, meta),
    )


def _number(path: Path, cell: str, lineno: int, column: str) -> float:
    s = cell.strip()
    if s.lower() in _MISSING:
        raise DataFileError(
            f"{path}: line {lineno}, column {column!r}: missing value {cell!r}; every sample needs "
            "a number (remove the row only if that keeps the nominal grid regular)"
        )
    try:
        val = _decimal(s)
    except ValueError:
        if s.lower().lstrip("+-") in ("inf", "infinity"):
            val = math.inf
        else:
            raise DataFileError(
                f"{path}: line {lineno}, column {column!r}: {cell!r} is not a number; use "
                "plain ASCII decimal numbers without digit separators, such as 0.25, -1000 or 1e-3"
            ) from None
    if not math.isfinite(val):
        raise DataFileError(
            f"{path}: line {lineno}, column {column!r}: {cell!r} is not finite (NaN/inf are "
            "treated "
            "as missing values); every sample needs a finite number"
        )
    return val


def _check_header(path: Path, header: list[str], line: int) -> None:
    seen: set[str] = set()
    for name in header:
        if not name:
            raise DataFileError(
                f"{path}: line {line}: a column has an empty name; name every column"
            )
        if name in seen:
            raise DataFileError(f"{path}: line {line}: column {name!r} appears twice; rename one")
        seen.add(name)


def _check_npz_members(path: Path) -> None:
    """Read every member's .npy header and refuse what cannot be data, before allocating."""
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            total = 0
            for info in infos:
                name = info.filename
                if info.is_dir():
                    continue
                if not name.endswith(".npy"):
                    raise DataFileError(
                        f"{path}: member {name!r} is not a NumPy array (.npy); a data archive "
                        "holds "
                        "only arrays: write it with numpy.savez(path, t=..., y=...)"
                    )
                with zf.open(info) as fh:
                    try:
                        version = np.lib.format.read_magic(fh)
                        if version == (1, 0):
                            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                        elif version == (2, 0):
                            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
                        else:
                            raise ValueError(f"unsupported .npy version {version}")
                    except DataFileError:
                        raise
                    except Exception as exc:  # noqa: BLE001 - any error of a broken header
                        raise DataFileError(
                            f"{path}: member {name!r} has a broken .npy header "
                            f"({type(exc).__name__}: {exc}); write it again with numpy.savez"
                        ) from None
                    header_len = fh.tell()
                count = math.prod(shape)
                nbytes = count * dtype.itemsize
                if nbytes > max(info.file_size - header_len, 0):
                    raise DataFileError(
                        f"{path}: member {name!r} says it holds {count} values of shape {shape} "
                        f"({nbytes} bytes) but has only {info.file_size - header_len} bytes of "
                        "data; the archive is truncated or corrupt: write it again"
                    )
                total += count
            if total > MAX_CELLS:
                raise DataFileError(
                    f"{path}: the arrays hold {total} values, more than jitterid reads into "
                    f"memory ({MAX_CELLS}); thin the data to fewer samples"
                )
    except (
        OSError,
        EOFError,
        zipfile.BadZipFile,
        zipfile.LargeZipFile,
        NotImplementedError,
    ) as exc:
        raise DataFileError(
            f"{path}: cannot read it as a NumPy .npz archive ({type(exc).__name__}: {exc}); "
            "write it with numpy.savez(path, t=..., y=...)"
        ) from None


def _read_npz(path: Path) -> _Table:
    _check_npz_members(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as exc:
        raise DataFileError(
            f"{path}: cannot read it as a NumPy .npz archive ({type(exc).__name__}: {exc}); "
            "write it with numpy.savez(path, t=..., y=...)"
        ) from None
    meta: dict[str, Any] = {}
    if "metadata" in arrays:
        raw = arrays.pop("metadata")
        meta_obj = (
            _json_object(path, str(raw[()]), "array 'metadata'")
            if raw.ndim == 0 and raw.dtype.kind == "U"
            else None
        )
        if not isinstance(meta_obj, dict):
            raise DataFileError(
                f"{path}: array 'metadata' must be a 0-d string holding a JSON object, e.g. "
                "numpy.savez(..., metadata=json.dumps({'T': 1.0}))"
            )
        meta = {
            str(k): _meta_value(path, str(k), v, "array 'metadata'") for k, v in meta_obj.items()
        }
    if not arrays:
        raise DataFileError(f"{path}: the archive holds no data arrays")
    columns: dict[str, FloatArray] = {}
    for name, arr in arrays.items():
        if arr.ndim != 1:
            raise DataFileError(f"{path}: array {name!r} must be 1-D; got shape {arr.shape}")
        if arr.dtype.kind not in "iuf":
            raise DataFileError(
                f"{path}: array {name!r} must hold real numbers; got dtype {arr.dtype}"
            )
        col = arr.astype(float)
        bad = np.flatnonzero(~np.isfinite(col))
        if bad.size:
            raise DataFileError(
                f"{path}: array {name!r}, index {bad[0]}: missing or non-finite value {col[bad[0]]}"
                f" ({bad.size} in all); every sample needs a finite number"
            )
        columns[name] = col
    sizes = {name: c.size for name, c in columns.items()}
    if len(set(sizes.values())) > 1:
        raise DataFileError(f"{path}: the arrays must all have the same length; got {sizes}")
    if not next(iter(sizes.values())):
        raise DataFileError(f"{path}: the arrays are empty")
    return _Table(path, columns, lambda i: f"index {i}", _merge_sidecar(path, meta))


def _read(path: PathLike, role: str) -> _Table:
    p = Path(path)
    if not p.is_file():
        raise DataFileError(f"{p}: no such file (the {role} file)")
    try:
        if p.suffix.lower() == ".npz":
            return _read_npz(p)
        if p.suffix.lower() == ".csv":
            return _read_csv(p)
    except OSError as exc:
        raise DataFileError(f"{p}: cannot read the {role} file ({exc.strerror or exc})") from None
    raise DataFileError(
        f"{p}: unknown file type {p.suffix!r}; the {role} file must be .csv or .npz"
    )


# ---------------------------------------------------------------------------------- checks


def _require_columns(tab: _Table, allowed: tuple[str, ...], role: str, layout: str) -> None:
    unknown = [c for c in tab.columns if c not in allowed]
    if unknown:
        c = unknown[0]
        hint = difflib.get_close_matches(c.lower(), allowed, n=1, cutoff=0.6)
        if c.lower() in allowed:
            hint = [c.lower()]
        guess = f" Did you mean {hint[0]!r}? Names are lower case." if hint else ""
        raise tab.fail(
            f"column {c!r} is not recognised; a {role} file has the columns {layout}.{guess} "
            "Rename or remove it"
        )


def _grid(tab: _Table, T_given: float | None, unit: str) -> tuple[float, float]:
    """Validate the nominal index/time column; return (first time, T) in seconds."""
    has_k, has_t = "k" in tab.columns, "t" in tab.columns
    if has_k and has_t:
        raise tab.fail(
            "has both 'k' and 't' columns; keep one (the nominal index or the nominal time)"
        )
    if not (has_k or has_t):
        raise tab.fail(
            f"no nominal index 'k' or nominal time 't' column (found {list(tab.columns)}); add one"
        )
    n = tab.nrows
    if has_k:
        k = tab.columns["k"]
        frac = np.flatnonzero(k != np.round(k))
        if frac.size:
            i = int(frac[0])
            raise tab.fail(f"{tab.where(i)}, column 'k': {k[i]:g} is not an integer sample index")
        _increasing(tab, "k", k)
        gap = np.flatnonzero(np.diff(k) != 1)
        if gap.size:
            i = int(gap[0]) + 1
            raise tab.fail(
                f"{tab.where(i)}, column 'k': index jumps from {k[i - 1]:g} to {k[i]:g}; the "
                "nominal grid must be complete (one row per sample, k consecutive)"
            )
        if T_given is None:
            raise tab.fail(
                "the nominal sampling interval T is not given; with an index column 'k' add a "
                "'# T: <interval>' metadata line (or a JSON sidecar, or --T on the command line)"
            )
        T_s = _seconds(T_given, unit)
        return float(k[0]) * T_s, T_s
    t = tab.columns["t"]
    _increasing(tab, "t", t)
    if n < 2:
        raise tab.fail("needs at least two rows to define the sampling interval")
    T = T_given if T_given is not None else float(t[-1] - t[0]) / (n - 1)
    dev = np.abs(t - (t[0] + T * np.arange(n)))
    bad = np.flatnonzero(dev > GRID_TOL * T)
    if bad.size:
        i = int(bad[0])
        src = "the metadata" if T_given is not None else "the first and last times"
        raise tab.fail(
            f"{tab.where(i)}, column 't': {t[i]:.12g} is off the regular grid t0 + k T (T = "
            f"{T:.12g} from {src}; expected {t[0] + i * T:.12g}). The nominal grid must be "
            "regular: check for missing rows, or give the nominal index 'k' instead of times"
        )
    return _seconds(float(t[0]), unit), _seconds(T, unit)


def _increasing(tab: _Table, name: str, x: FloatArray) -> None:
    d = np.diff(x)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        what = "repeats" if d[i - 1] == 0 else "decreases"
        raise tab.fail(
            f"{tab.where(i)}, column {name!r}: {x[i]:.12g} {what} (previous row {x[i - 1]:.12g}); "
            f"sort the rows by {name!r} and remove duplicates"
        )


def _time_unit(tab: _Table, default: str = "s") -> str:
    return str(tab.meta.get("time_unit", default))


# ---------------------------------------------------------------------------------- inputs


def _zoh_from_table(tab: _Table, t0: float, T: float, n: int) -> PiecewiseConstant:
    T_in = tab.meta.get("T")
    unit = _time_unit(tab)
    if T_in is None and "k" in tab.columns:
        T_in = T / TIME_UNITS[unit]  # an index column counts samples of the data's grid
    first, T_file = _grid(tab, T_in, unit)
    if abs(T_file - T) > GRID_TOL * T:
        raise tab.fail(
            f"the input grid has T = {T_file:g} s but the data have T = {T:g} s; a zero-order-hold "
            "input must be on the data's grid (or give switch times with columns time,level)"
        )
    offset = (first - t0) / T
    if abs(offset - round(offset)) > GRID_TOL:
        raise tab.fail(
            f"the input grid starts at {first:g} s, which is not on the data's grid t0 + k T "
            f"(t0 = {t0:g} s, T = {T:g} s); align the input with the samples"
        )
    start = round(offset)
    m = tab.nrows
    if start > 0 or start + m < n:
        raise tab.fail(
            f"the input covers samples {start}..{start + m - 1} of the data grid but the data have "
            f"samples 0..{n - 1}; the input must cover every sample"
        )
    return PiecewiseConstant(T * (start + np.arange(m + 1.0)), tab.columns["u"])


def _switches_from_table(
    tab: _Table, t0: float, default_end: float, unit: str
) -> PiecewiseConstant:
    tu = _time_unit(tab, unit)
    scale = TIME_UNITS[tu]
    times = tab.columns["time"]
    _increasing(tab, "time", times)
    end = default_end if "end" not in tab.meta else _seconds(tab.meta["end"], tu)
    if end <= times[-1] * scale:
        raise tab.fail(
            f"the input ends at {end:g} s, not after its last switch time {times[-1] * scale:g} s; "
            "add a '# end: <time>' metadata line after the last switch"
        )
    return PiecewiseConstant(np.r_[times * scale, end] - t0, tab.columns["level"])


def _input(path: PathLike, t0: float, T: float, n: int, unit: str) -> tuple[Input, _Table]:
    tab = _read(path, "input")
    cols = set(tab.columns)
    if cols & set(_SWITCH_COLUMNS):
        _require_columns(tab, _SWITCH_COLUMNS, "switch-time input", "'time' and 'level'")
        for c in _SWITCH_COLUMNS:
            if c not in cols:
                raise tab.fail(
                    f"a switch-time input file needs the columns 'time' and 'level'; {c!r} is "
                    "missing"
                )
        return _switches_from_table(tab, t0, t0 + n * T, unit), tab
    _require_columns(
        tab,
        _ZOH_COLUMNS,
        "zero-order-hold input",
        "'k' or 't' and 'u' (or switch times 'time','level')",
    )
    if "u" not in cols:
        raise tab.fail(
            "no input column: give 'u' (with 'k' or 't') or switch times 'time','level'; found "
            f"{list(cols)}"
        )
    if "time_unit" not in tab.meta:
        tab.meta["time_unit"] = unit
    return _zoh_from_table(tab, t0, T, n), tab


# ---------------------------------------------------------------------------------- load


def load(
    path: PathLike,
    input: PathLike | None = None,
    *,
    T: float | str | None = None,
    noise_std: float | None = None,
    require_input: bool = True,
    hold_input: bool = False,
) -> Dataset:
    """Read a data file (and its input) into a :class:`Dataset`.

    Parameters
    ----------
    path : str or Path
        The data file (``.csv`` or ``.npz``), see the module notes for the format.
    input : str or Path, optional
        The input file, unless the data file has a ``u`` column.
    T : float or str, optional
        Nominal sampling interval in the file's time unit, or a string with its own unit
        (``"0.5s"``, ``"500ms"``, see :func:`parse_time`); needed with an index column ``k``
        when the metadata do not give it. Must agree with the metadata if both are given.
    noise_std : float, optional
        Measurement-noise std (y units), overriding the metadata's ``noise_std``.
    require_input : bool
        False for a signal record with no input (a sine for :func:`jitterid.measure_jitter`):
        a data file without a ``u`` column and no input file then loads with ``data.u``
        None. True (the default) refuses it, since a system fit needs the input. A file
        holding only a ``y`` column (no ``k`` or ``t``) is read as the samples k = 0, 1,
        ... when T is known (``T=`` or a ``# T:`` line).
    hold_input : bool
        Hold the input file's last value after its end, for the jitter's tail (as a DAC
        does, and as a ``u`` column always is): an input file with one value per sample ends
        one interval after the last sample, before a jittered last instant may fall. The
        dataset's ``notes`` say so. Default False: the input ends where the file says.

    Returns
    -------
    Dataset

    Raises
    ------
    DataFileError
        For every malformed file, naming the file, the line or index and the column.

    Examples
    --------
    Write samples and their input, then load them back for :func:`jitterid.fit`:

    >>> import os, tempfile
    >>> import jitterid as jid
    >>> u = jid.telegraph_input(20.0, rng=1)
    >>> data = jid.simulate(jid.TransferFunction([2.0], [1.0, 2.0]), u, jid.Uniform(0.05),
    ...                     T=0.1, N=100, noise_std=0.01, rng=2)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = jid.save_data(os.path.join(tmp, "y.csv"), data)
    ...     upath = jid.save_input(os.path.join(tmp, "u.csv"), u)
    ...     ds = jid.load(path, upath)
    >>> ds.data.y.shape, ds.data.T, ds.data.u is not None
    ((100,), 0.1, True)
    """
    tab = _read(path, "data")
    _require_columns(tab, _DATA_COLUMNS, "data", "'k' or 't', 'y' and optionally 'u'")
    if "y" not in tab.columns:
        raise tab.fail(
            f"no output column 'y' (found {list(tab.columns)}); name the output column 'y'"
        )
    meta_T = tab.meta.get("T")
    unit = str(tab.meta.get("time_unit", "s"))
    if T is not None:
        if isinstance(T, str):
            try:
                T = parse_time(T, unit, "T") / TIME_UNITS[unit]
            except ValueError as exc:
                raise DataFileError(str(exc)) from None
        try:
            T = float(T)
        except (TypeError, ValueError, OverflowError):
            raise DataFileError(f"T must be a number; got {T!r}") from None
        if not (math.isfinite(T) and T > 0):
            raise DataFileError(f"T must be finite and > 0; got {T!r}")
        if meta_T is not None and abs(meta_T - T) > 1e-9 * T:
            raise tab.fail(f"T = {T:g} was given but the metadata say T = {meta_T:g}; keep one")
    T_file = T if T is not None else meta_T
    notes: list[str] = []
    if "k" not in tab.columns and "t" not in tab.columns:
        # a record of samples only (e.g. a sine for the jitter meter): the rows are the
        # samples k = 0, 1, ..., which needs T
        if T_file is None:
            raise tab.fail(
                f"has no nominal index 'k' or time 't' column (found {list(tab.columns)}); a "
                "file of samples only needs the sampling interval: give T (load(path, T=...), "
                "--T on the command line) or a '# T: <interval>' line, or add a 'k' or 't' "
                "column"
            )
        tab.columns["k"] = np.arange(tab.nrows, dtype=float)
        notes.append("no 'k' or 't' column: the rows are the samples k = 0, 1, ... at T")
    t0, T_s = _grid(tab, T_file, unit)
    n = tab.nrows
    if n < 4:
        raise tab.fail(f"has {n} sample(s); at least 4 are needed")
    sources = [Source("data", str(tab.path), _sha256(tab.path))]
    if "u" in tab.columns:
        if input is not None:
            raise DataFileError(
                f"{tab.path} has an input column 'u' and an input file {input} was also given; "
                "keep one of them"
            )
        # u[k] is held on [t_k, t_k + T); the last value is held on for the jitter's tail
        # (a jittered last instant lies past the grid), which the report states.
        tail = max(n, _U_TAIL)
        times = T_s * np.arange(n + 1.0)
        times[-1] = T_s * (n - 1 + tail)
        u: Input | None = PiecewiseConstant(times, tab.columns["u"])
        notes.append(
            f"the input column 'u' is a zero-order hold; its last value u = "
            f"{tab.columns['u'][-1]:g} is assumed to hold after the last sample (for "
            f"{tail} intervals), where the jittered last instants may fall"
        )
        u_unit = str(tab.meta.get("u_unit", ""))
    elif input is None and not require_input:
        u, u_unit = None, ""
    elif input is None:
        raise tab.fail(
            "has no input column 'u' and no input file was given; give the input file "
            "(--input INPUT) or add a 'u' column (the input held on the same grid). A signal "
            "record with no input (a sine for the jitter meter) loads with "
            "load(path, require_input=False), or measure it with `jitterid jitter DATA`"
        )
    else:
        u, itab = _input(input, t0, T_s, n, unit)
        sources.append(Source("input", str(itab.path), _sha256(itab.path)))
        if hold_input and isinstance(u, PiecewiseConstant):
            end = max(u.end, T_s * (n - 1 + max(n, _U_TAIL)))
            u = u.hold_last(end)
            notes.append(
                f"the input's last value u = {u.levels[-1]:g} is held after the end of the "
                f"input file until t = {end:g} s (hold_input), where the jittered last "
                "instants may fall"
            )
        u_unit = str(itab.meta.get("u_unit", tab.meta.get("u_unit", "")))
    noise = noise_std if noise_std is not None else tab.meta.get("noise_std")
    if noise is not None:
        try:
            ok = not isinstance(noise, bool) and math.isfinite(float(noise)) and float(noise) >= 0
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise DataFileError(f"noise_std must be finite and >= 0; got {noise!r}")
    try:
        data = SampledData(
            y=tab.columns["y"], T=T_s, u=u, noise_std=None if noise is None else float(noise)
        )
    except (TypeError, ValueError) as exc:  # pragma: no cover - every case is checked above
        raise DataFileError(f"{tab.path}: {exc}") from None
    units = {
        "time": "s",
        "frequency": "Hz",
        "y": str(tab.meta.get("y_unit", "")),
        "u": u_unit,
    }
    return Dataset(
        data=data,
        t0=t0,
        units=units,
        metadata=dict(tab.meta),
        sources=tuple(sources),
        notes=tuple(notes),
    )


# ---------------------------------------------------------------------------------- save


def parse_time(text: str | float, default_unit: str = "s", name: str = "time") -> float:
    """A duration in seconds from ``"80ms"``, ``"0.5 s"``, ``"2us"`` or a bare number.

    A bare number is in ``default_unit`` (the data file's ``time_unit`` on the command line).
    Units: s, ms, us (or µs), ns, min. Raises ValueError naming ``name`` otherwise.
    """
    if default_unit not in TIME_UNITS:
        raise ValueError(f"default_unit must be one of {sorted(TIME_UNITS)}; got {default_unit!r}")
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        val, unit = float(text), default_unit
    elif isinstance(text, str):
        body, unit = text.strip(), default_unit
        for suffix in ("min", "ms", "us", "µs", "μs", "ns", "s"):
            if body.endswith(suffix) and not body.endswith("e" + suffix):
                body, unit = (
                    body[: -len(suffix)].strip(),
                    suffix.replace("µ", "u").replace("μ", "u"),
                )
                break
        try:
            val = _decimal(body)
        except ValueError:
            raise ValueError(
                f"{name}: {text!r} is not a time; write a plain decimal number with an optional "
                f"unit ({', '.join(TIME_UNITS)}), e.g. 0.08 or 80ms (a bare number is in "
                f"{default_unit})"
            ) from None
    else:
        raise TypeError(f"{name} must be a number or a string such as '80ms'; got {text!r}")
    seconds = val * TIME_UNITS[unit]
    if not math.isfinite(seconds):
        raise ValueError(f"{name}: {text!r} is not a finite time")
    return seconds


def atomic_write(path: Path, write: Callable[[Any], None], *, binary: bool = False) -> Path:
    """Write ``path`` all at once: ``write(fh)`` fills a temporary file in the same folder,
    which then replaces ``path`` (no partial or 0-byte file is ever left behind).

    The file gets the permissions an ordinary ``open(path, "w")`` would give: those of the
    file it replaces, or for a new file ``0o666`` less the process's umask (0644 under the
    usual umask 022, as the SQLite store), not the 0600 of a bare temporary file.

    Parameters
    ----------
    path : Path
        The file to (re)write.
    write : callable
        ``write(fh)`` writes the content into the open file object ``fh``.
    binary : bool, default False
        Open ``fh`` in binary mode (else text, UTF-8, no newline translation).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    try:
        mode = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        mode = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, mode)
        fh: IO[Any] = (
            os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8", newline="")
        )
        with fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def _umask() -> int:
    """The process's umask, read without changing it where the system allows (Linux
    ``/proc/self/status``: setting it to read it back is not thread-safe)."""
    with contextlib.suppress(OSError, ValueError), open("/proc/self/status", "rb") as fh:
        for line in fh:
            if line.startswith(b"Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)  # pragma: no cover - not Linux
    os.umask(mask)  # pragma: no cover
    return mask  # pragma: no cover


def _to_unit(seconds: float, unit: str) -> float | str:
    """``seconds`` in ``unit``, written so that :func:`load` gives back exactly ``seconds``:
    the float if its shortest repr does, else a decimal string with enough digits."""
    if unit == "s":
        return float(seconds)
    exact = Decimal(float(seconds)) / _SCALE_DEC[unit]  # exact: a finite decimal
    v = float(exact)
    if float(Decimal(repr(v)) * _SCALE_DEC[unit]) == seconds:
        return v
    for digits in range(17, 40):
        text = format(exact, f".{digits}g")
        if float(Decimal(text) * _SCALE_DEC[unit]) == seconds:
            return text
    return format(exact, "f")  # pragma: no cover - the exact decimal always works


def _check_meta(meta: Mapping[str, Any]) -> dict[str, Any]:
    """Validate metadata to be written the way :func:`load` will read it."""
    out: dict[str, Any] = {}
    for key, value in meta.items():
        if not isinstance(key, str):
            raise TypeError(f"metadata keys must be strings; got {key!r}")
        try:
            _meta_value(Path("metadata"), key, value, "argument")
        except DataFileError as exc:
            raise ValueError(str(exc).removeprefix("metadata: ")) from None
        if isinstance(value, (dict, list, tuple)) or value is None:
            raise ValueError(
                f"metadata {key!r} must be a number or one line of text; got {value!r}"
            )
        text = str(value)
        if "\n" in text or "\r" in text:
            raise ValueError(f"metadata {key!r} must fit on one line")
        out[key] = value
    return out


def _write(path: Path, columns: Mapping[str, FloatArray], meta: Mapping[str, Any]) -> Path:
    if path.suffix.lower() not in (".csv", ".npz"):
        raise ValueError(f"path must end in .csv or .npz; got {path.name!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".npz":
        arrays: dict[str, Any] = {k: np.asarray(v, float) for k, v in columns.items()}
        arrays["metadata"] = np.array(json.dumps(dict(meta)))
        return atomic_write(path, lambda fh: np.savez(fh, **arrays), binary=True)
    lines = ["# jitterid data format 1"]
    for key, value in meta.items():
        text = str(value)
        lines.append(f"# {key}: {value!r}" if isinstance(value, float) else f"# {key}: {text}")
    # (an exact time that needs more than 17 digits is a str here, written as it is)
    names = list(columns)
    lines.append(",".join(names))
    cols = [np.asarray(columns[n], float) for n in names]
    for row in zip(*cols, strict=True):
        lines.append(",".join(_fmt(v) for v in row))
    return atomic_write(path, lambda fh: fh.write("\n".join(lines) + "\n"))


def _fmt(v: float) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 2**53 else repr(float(v))


def _unit_of(meta: Mapping[str, Any]) -> str:
    unit = meta.get("time_unit", "s")
    if unit not in TIME_UNITS:
        raise ValueError(f"metadata 'time_unit' must be one of {sorted(TIME_UNITS)}; got {unit!r}")
    return str(unit)


def save_data(
    path: PathLike,
    data: SampledData,
    *,
    t0: float = 0.0,
    index: bool = False,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write the samples of ``data`` as a data file (``.csv`` or ``.npz``, by extension).

    Parameters
    ----------
    path : str or Path
        Target file; parent directories are created. Written atomically (a temporary file
        renamed into place), so an interrupted write leaves no partial file.
    data : SampledData
        The samples; ``data.T`` is written as metadata ``T`` (in the written time unit).
    t0 : float
        File time of the first sample (s).
    index : bool
        Write the nominal index ``k`` (True) or the nominal time ``t`` (False, default).
    metadata : mapping, optional
        Extra metadata (e.g. ``y_unit``), checked as :func:`load` checks it (unknown keys
        need an ``x-`` prefix). ``time_unit`` (default ``s``) is the unit the times and
        ``T`` are written in: they are converted, so :func:`load` gives back ``data.T``
        exactly. ``T`` comes from ``data`` (a different ``T`` here is refused).
        ``noise_std`` is written only if given here, since real data rarely know it.

    Returns
    -------
    Path
        The file written. The input is saved separately with :func:`save_input`.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import jitterid as jid
    >>> u = jid.telegraph_input(20.0, rng=1)
    >>> data = jid.simulate(jid.TransferFunction([2.0], [1.0, 2.0]), u, jid.Uniform(0.05),
    ...                     T=0.1, N=100, noise_std=0.01, rng=2)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = jid.save_data(os.path.join(tmp, "run.csv"), data)
    ...     back = jid.load(path, require_input=False)
    >>> path.name, bool(np.allclose(back.data.y, data.y))
    ('run.csv', True)
    """
    if not isinstance(data, SampledData):
        raise TypeError(f"data must be a SampledData; got {type(data).__name__}")
    extra = _check_meta(dict(metadata or {}))
    unit = _unit_of(extra)
    T_text = _to_unit(float(data.T), unit)
    T = float(T_text)
    if "T" in extra and abs(float(extra["T"]) - T) > 1e-12 * T:
        raise ValueError(
            f"metadata 'T' = {extra['T']!r} disagrees with data.T = {T!r} {unit}; "
            "T is written from data.T: remove it from metadata"
        )
    meta: dict[str, Any] = {"T": T_text, "time_unit": unit}
    meta.update({k: v for k, v in extra.items() if k not in ("T", "time_unit")})
    k = np.arange(data.N, dtype=float)
    if index:
        if abs(t0 - round(t0 / data.T) * data.T) > 1e-12 * max(1.0, abs(t0)):
            raise ValueError("with index=True, t0 must be a multiple of T")
        cols = {"k": k + round(t0 / data.T)}
    else:
        cols = {"t": float(_to_unit(float(t0), unit)) + T * k}
    cols["y"] = np.asarray(data.y, float)
    return _write(Path(path), cols, meta)


def save_input(
    path: PathLike,
    u: Input,
    *,
    t0: float = 0.0,
    T: float | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write a piecewise-constant input as an input file (``.csv`` or ``.npz``).

    Parameters
    ----------
    path : str or Path
        Target file (written atomically).
    u : PiecewiseConstant
        The input (library time, origin at the first sample).
    t0 : float
        File time of the library's t = 0 (s).
    T : float, optional
        Hold interval (s). If given, the input must be a zero-order hold on the grid k T
        (as from :func:`jitterid.zoh_input`) and is written as columns ``t,u``; otherwise
        as switch times ``time,level`` with metadata ``end``.
    metadata : mapping, optional
        Extra metadata such as ``u_unit``; ``time_unit`` (default ``s``) is the unit the
        times are written in (they are converted).

    Returns
    -------
    Path

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(5.0, rng=1)
    >>> data = ji.simulate(G, u, ji.NoJitter(), 0.1, 40, 0.01, rng=2)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     upath = ji.save_input(os.path.join(tmp, "u.csv"), u)
    ...     ds = ji.load(ji.save_data(os.path.join(tmp, "y.csv"), data), upath)
    >>> upath.name, bool(np.allclose(ds.data.u(data.t_nominal), u(data.t_nominal)))
    ('u.csv', True)
    """
    if not isinstance(u, PiecewiseConstant):
        raise TypeError(
            f"only piecewise-constant inputs can be saved; got {type(u).__name__}. "
            "Sample a multisine on a grid and save it as a zero-order hold"
        )
    extra = _check_meta(dict(metadata or {}))
    unit = _unit_of(extra)
    scale = TIME_UNITS[unit]
    for key in ("T", "end"):
        if key in extra:
            raise ValueError(f"metadata {key!r} is written from the input; remove it")
    meta: dict[str, Any] = {"time_unit": unit}
    if T is None:
        meta["end"] = _to_unit(float(u.end + t0), unit)
        meta.update({k: v for k, v in extra.items() if k != "time_unit"})
        times = (u.times[:-1] + t0) / scale
        return _write(Path(path), {"time": times, "level": u.levels}, meta)
    steps = np.diff(u.times)
    if np.max(np.abs(steps - T)) > 1e-9 * T or abs(u.times[0] / T - round(u.times[0] / T)) > 1e-9:
        raise ValueError("u is not a zero-order hold on the grid k T; omit T to save switch times")
    meta["T"] = _to_unit(float(T), unit)
    meta.update({k: v for k, v in extra.items() if k != "time_unit"})
    return _write(Path(path), {"t": (u.times[:-1] + t0) / scale, "u": u.levels}, meta)
