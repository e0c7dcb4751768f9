"""The results store: one SQLite file per experiment, one transaction per realization.

Each finished realization (all its estimators) is committed in a single transaction, and
marked done in the same transaction, so a kill at any moment leaves either the whole
realization or none of it; ``--resume`` then runs exactly the realizations not marked done.
Primary keys make a duplicate impossible. The file remembers the fingerprint of the
experiment definition and refuses to mix results of a different one.
"""

from __future__ import annotations

import csv
import json
import math
import sqlite3
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Self

from .. import __version__
from .config import Experiment

__all__ = ["Estimate", "Store", "StoreError"]

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
"""


class StoreError(RuntimeError):
    """The store cannot be used as asked (exists without --resume, or another definition)."""


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


class Store:
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
        self.path = Path(path)
        self.experiment = experiment
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(self.path)
        self._db.execute("PRAGMA synchronous = FULL")
        with self._db:
            self._db.executescript(_SCHEMA)
        meta = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
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
        with self._db:
            for k, v in (("experiment", experiment.name), ("fingerprint", fp)):
                self._db.execute("INSERT OR IGNORE INTO meta VALUES (?, ?)", (k, v))
            self._db.execute("INSERT OR REPLACE INTO meta VALUES ('jitterid_version', ?)",
                             (__version__,))
            self._db.execute(
                "INSERT OR REPLACE INTO meta VALUES ('definition', ?)",
                (json.dumps(_definition(experiment), sort_keys=True),),
            )

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def count_done(self) -> int:
        return int(self._db.execute("SELECT COUNT(*) FROM realizations").fetchone()[0])

    def done(self) -> set[tuple[str, int]]:
        """The finished (case name, realization index) pairs."""
        rows = self._db.execute("SELECT case_name, realization FROM realizations")
        return {(c, int(r)) for c, r in rows}

    def add_realization(self, rows: Sequence[Estimate], elapsed_s: float) -> None:
        """Commit all estimates of one realization, and mark it done, in one transaction."""
        if not rows or len({(e.case_name, e.realization) for e in rows}) != 1:
            raise ValueError("rows must be the estimates of exactly one realization")
        first = rows[0]
        with self._db:
            self._db.execute(
                "INSERT INTO realizations VALUES (?, ?, ?)",
                (first.case_name, first.realization, elapsed_s),
            )
            self._db.executemany(
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

    def estimates(self, runs: int | None = None) -> list[Estimate]:
        """Stored estimates of realizations ``0..runs-1`` (all if None), in a stable order."""
        limit = -1 if runs is None else runs
        cur = self._db.execute(
            "SELECT case_name, realization, method, params, stderr, jitter_std, noise_std, cost, "
            "success, status, message, nfev, elapsed_s FROM estimates "
            "WHERE ? < 0 OR realization < ? ORDER BY case_name, realization, method",
            (limit, limit),
        )
        return [
            Estimate(
                c,
                int(r),
                m,
                json.loads(p),
                json.loads(s),
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
        with out.open("w", newline="", encoding="utf-8") as fh:
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
        return out


def _f(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _cell(x: float | None) -> str:
    return "" if x is None else repr(float(x))


def _definition(exp: Experiment) -> dict[str, object]:
    return asdict(exp)
