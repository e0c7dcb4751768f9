"""Read and write sampled data sets: CSV or NumPy ``.npz``, with explicit units.

File format
-----------
A **data file** has one row per sample, taken on a regular *nominal* grid, and the columns

==========  ===============================================================================
``k``       nominal sample index (consecutive integers), *or*
``t``       nominal sample time (regular grid, within 0.1 % of ``T``)
``y``       the measured output samples
``u``       optional: the input as a zero-order hold on the same grid (u[k] held on
            [t_k, t_k + T), as a DAC does)
==========  ===============================================================================

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
default: one interval after the last nominal sample). Other keys are kept as notes.

Times are converted to seconds, so every frequency downstream is in Hz. The library's time
origin is the first nominal sample: :attr:`Dataset.t0` records the file time it came from.

Every malformed file is refused with a :class:`DataFileError` (a ``ValueError``) that names
the file, the line (CSV) or index (``.npz``) and the column, and says how to fix it.
"""

from __future__ import annotations

import csv
import difflib
import hashlib
import json
import math
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .inputs import Input, PiecewiseConstant
from .simulate import SampledData

__all__ = ["DataFileError", "Dataset", "Source", "load", "save_data", "save_input"]

FloatArray = NDArray[np.float64]
PathLike = str | Path

#: Seconds per supported time unit.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0}
#: Largest deviation of a nominal time from the regular grid, as a fraction of T.
GRID_TOL = 1e-3
_NUMERIC_KEYS = ("T", "noise_std", "end")
_TEXT_KEYS = ("time_unit", "y_unit", "u_unit")
_DATA_COLUMNS = ("k", "t", "y", "u")
_ZOH_COLUMNS = ("k", "t", "u")
_SWITCH_COLUMNS = ("time", "level")
_MISSING = ("", "na", "nan", "n/a", "null", "none", "-")


class DataFileError(ValueError):
    """A data or input file that cannot be used; the message says where and how to fix it."""


@dataclass(frozen=True)
class Source:
    """A file that went into a data set: its role, path and SHA-256 checksum."""

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
    """

    data: SampledData
    t0: float
    units: dict[str, str]
    metadata: dict[str, Any] = field(repr=False)
    sources: tuple[Source, ...]

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


def _meta_value(path: Path, key: str, value: Any, origin: str) -> Any:
    if key in _NUMERIC_KEYS:
        try:
            val = float(value)
        except (TypeError, ValueError):
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
        return val
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
    try:
        extra = json.loads(side.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFileError(f"{side}: the metadata sidecar is not valid JSON ({exc})") from None
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


def _read_csv(path: Path) -> _Table:
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
        val = float(s)
    except ValueError:
        raise DataFileError(
            f"{path}: line {lineno}, column {column!r}: {cell!r} is not a number; use plain decimal "
            "numbers such as 0.25 or 1e-3"
        ) from None
    if not math.isfinite(val):
        raise DataFileError(
            f"{path}: line {lineno}, column {column!r}: {cell!r} is not finite (NaN/inf are treated "
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


def _read_npz(path: Path) -> _Table:
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DataFileError(
            f"{path}: cannot read it as a NumPy .npz archive ({type(exc).__name__}: {exc}); "
            "write it with numpy.savez(path, t=..., y=...)"
        ) from None
    meta: dict[str, Any] = {}
    if "metadata" in arrays:
        raw = arrays.pop("metadata")
        try:
            meta_obj = json.loads(str(raw[()])) if raw.ndim == 0 and raw.dtype.kind == "U" else None
        except json.JSONDecodeError:
            meta_obj = None
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
    if p.suffix.lower() == ".npz":
        return _read_npz(p)
    if p.suffix.lower() == ".csv":
        return _read_csv(p)
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


def _grid(tab: _Table, T_given: float | None, scale: float) -> tuple[float, float]:
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
        return float(k[0]) * T_given * scale, T_given * scale
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
    return float(t[0]) * scale, T * scale


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


def _time_scale(tab: _Table, default: str = "s") -> float:
    return TIME_UNITS[str(tab.meta.get("time_unit", default))]


# ---------------------------------------------------------------------------------- inputs


def _zoh_from_table(tab: _Table, t0: float, T: float, n: int) -> PiecewiseConstant:
    T_in = tab.meta.get("T")
    scale = _time_scale(tab)
    if T_in is None and "k" in tab.columns:
        T_in = T / scale  # an index column counts samples of the data's grid
    first, T_file = _grid(tab, None if T_in is None else float(T_in), scale)
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
    scale = _time_scale(tab, unit)
    times = tab.columns["time"]
    _increasing(tab, "time", times)
    end = default_end if "end" not in tab.meta else float(tab.meta["end"]) * scale
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
                    f"a switch-time input file needs the columns 'time' and 'level'; {c!r} is missing"
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
            f"no input column: give 'u' (with 'k' or 't') or switch times 'time','level'; found {list(cols)}"
        )
    if "time_unit" not in tab.meta:
        tab.meta["time_unit"] = unit
    return _zoh_from_table(tab, t0, T, n), tab


# ---------------------------------------------------------------------------------- load


def load(
    path: PathLike,
    input: PathLike | None = None,
    *,
    T: float | None = None,
    noise_std: float | None = None,
) -> Dataset:
    """Read a data file (and its input) into a :class:`Dataset`.

    Parameters
    ----------
    path : str or Path
        The data file (``.csv`` or ``.npz``), see the module notes for the format.
    input : str or Path, optional
        The input file, unless the data file has a ``u`` column.
    T : float, optional
        Nominal sampling interval in the file's time unit; needed with an index column ``k``
        when the metadata do not give it. Must agree with the metadata if both are given.
    noise_std : float, optional
        Measurement-noise std (y units), overriding the metadata's ``noise_std``.

    Returns
    -------
    Dataset

    Raises
    ------
    DataFileError
        For every malformed file, naming the file, the line or index and the column.
    """
    tab = _read(path, "data")
    _require_columns(tab, _DATA_COLUMNS, "data", "'k' or 't', 'y' and optionally 'u'")
    if "y" not in tab.columns:
        raise tab.fail(
            f"no output column 'y' (found {list(tab.columns)}); name the output column 'y'"
        )
    meta_T = tab.meta.get("T")
    if T is not None:
        try:
            T = float(T)
        except (TypeError, ValueError):
            raise DataFileError(f"T must be a number; got {T!r}") from None
        if not (math.isfinite(T) and T > 0):
            raise DataFileError(f"T must be finite and > 0; got {T!r}")
        if meta_T is not None and abs(meta_T - T) > 1e-9 * T:
            raise tab.fail(f"T = {T:g} was given but the metadata say T = {meta_T:g}; keep one")
    T_file = T if T is not None else meta_T
    unit = str(tab.meta.get("time_unit", "s"))
    t0, T_s = _grid(tab, T_file, TIME_UNITS[unit])
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
        u: Input = PiecewiseConstant(T_s * np.arange(n + 1.0), tab.columns["u"])
        u_unit = str(tab.meta.get("u_unit", ""))
    elif input is None:
        raise tab.fail(
            "has no input column 'u' and no input file was given; give the input file "
            "(--input INPUT) or add a 'u' column (the input held on the same grid)"
        )
    else:
        u, itab = _input(input, t0, T_s, n, unit)
        sources.append(Source("input", str(itab.path), _sha256(itab.path)))
        u_unit = str(itab.meta.get("u_unit", tab.meta.get("u_unit", "")))
    noise = noise_std if noise_std is not None else tab.meta.get("noise_std")
    if noise is not None and not (math.isfinite(float(noise)) and float(noise) >= 0):
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
    return Dataset(data=data, t0=t0, units=units, metadata=dict(tab.meta), sources=tuple(sources))


# ---------------------------------------------------------------------------------- save


def _write(path: Path, columns: Mapping[str, FloatArray], meta: Mapping[str, Any]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".npz":
        arrays: dict[str, Any] = {k: np.asarray(v, float) for k, v in columns.items()}
        arrays["metadata"] = np.array(json.dumps(dict(meta)))
        np.savez(path, **arrays)
        return path
    if path.suffix.lower() != ".csv":
        raise ValueError(f"path must end in .csv or .npz; got {path.name!r}")
    lines = ["# jitterid data format 1"]
    for key, value in meta.items():
        text = str(value)
        if "\n" in text:
            raise ValueError(f"metadata {key!r} must fit on one line")
        lines.append(f"# {key}: {value!r}" if isinstance(value, float) else f"# {key}: {text}")
    names = list(columns)
    lines.append(",".join(names))
    cols = [np.asarray(columns[n], float) for n in names]
    for row in zip(*cols, strict=True):
        lines.append(",".join(_fmt(v) for v in row))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _fmt(v: float) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 2**53 else repr(float(v))


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
        Target file; parent directories are created.
    data : SampledData
        The samples; ``data.T`` is written as metadata ``T`` (seconds).
    t0 : float
        File time of the first sample (s).
    index : bool
        Write the nominal index ``k`` (True) or the nominal time ``t`` (False, default).
    metadata : mapping, optional
        Extra metadata (e.g. ``y_unit``); ``T`` and ``time_unit`` are always written.
        ``noise_std`` is written only if given here, since real data rarely know it.

    Returns
    -------
    Path
        The file written. The input is saved separately with :func:`save_input`.
    """
    if not isinstance(data, SampledData):
        raise TypeError(f"data must be a SampledData; got {type(data).__name__}")
    meta: dict[str, Any] = {"T": float(data.T), "time_unit": "s"}
    meta.update(dict(metadata or {}))
    k = np.arange(data.N, dtype=float)
    cols = {"k": k + round(t0 / data.T)} if index else {"t": t0 + data.T * k}
    if index and abs(t0 - round(t0 / data.T) * data.T) > 1e-12 * max(1.0, abs(t0)):
        raise ValueError("with index=True, t0 must be a multiple of T")
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
        Target file.
    u : PiecewiseConstant
        The input (library time, origin at the first sample).
    t0 : float
        File time of the library's t = 0 (s).
    T : float, optional
        If given, the input must be a zero-order hold on the grid k T (as from
        :func:`jitterid.zoh_input`) and is written as columns ``t,u``; otherwise as switch
        times ``time,level`` with metadata ``end``.
    metadata : mapping, optional
        Extra metadata such as ``u_unit``.

    Returns
    -------
    Path
    """
    if not isinstance(u, PiecewiseConstant):
        raise TypeError(
            f"only piecewise-constant inputs can be saved; got {type(u).__name__}. "
            "Sample a multisine on a grid and save it as a zero-order hold"
        )
    meta: dict[str, Any] = {"time_unit": "s"}
    if T is None:
        meta["end"] = float(u.end + t0)
        meta.update(dict(metadata or {}))
        return _write(Path(path), {"time": u.times[:-1] + t0, "level": u.levels}, meta)
    steps = np.diff(u.times)
    if np.max(np.abs(steps - T)) > 1e-9 * T or abs(u.times[0] / T - round(u.times[0] / T)) > 1e-9:
        raise ValueError("u is not a zero-order hold on the grid k T; omit T to save switch times")
    meta["T"] = float(T)
    meta.update(dict(metadata or {}))
    return _write(Path(path), {"t": u.times[:-1] + t0, "u": u.levels}, meta)
