"""Jitter-meter study: bias, std and RMSE of the jitter std from a sine record, side by side.

On the same simulated records, the jitter std estimated by

- ``jitterid``: ``jitterid.measure_jitter(y, T, frequency=None).jitter_std`` (the exact
  likelihood meter; skipped with a note while it does not exist on this branch);
- ``adctoolbox``: ``adctoolbox.analyze_error_by_phase`` (``benchmarks/peers.py`` says what
  it computes; skipped with a note when the ``bench`` extra is not installed);
- ``ieee1057``: the IEEE 1057 / 1241 slope regression after a four-parameter fit
  (:mod:`jitterid.metrology.sinefit`),

all blind to the frequency, across ``theta = 2 pi f0 sigma`` from 0.005 to 1 rad, noise std
from 1e-4 to 1e-1 of the amplitude, N = 10^3 and 10^5, and three jitter laws of the same
std: Gaussian, uniform, and a dual-Dirac mixture (+-delta with probability 1/2 each plus
Gaussian random jitter of std sigma/3, the DJ+RJ model of serial-link testing) -- the
latter two outside a Gaussian model family. Next to them, ``sqrt(CRB)`` of the jitter std
from ``jitterid.crb`` with a sampled Fisher information (see :func:`_crb_std` for the
call; skipped with a note otherwise).

Records are made here with numpy: ``y_k = A sin(2 pi f0 (k T + tau_k) + phi) + c + v_k``
with ``A = 1``, ``c = 0.1``, ``T = 1 ns``, ``f0 T`` uniform in (0.07, 0.43) (non-coherent),
``phi`` uniform, and each record's seed derived from its setting and index, so a record
is the same whatever grid it is run in.

Each (record, method) result goes to an sqlite file as soon as it is computed
(``benchmarks/results/jitter_meter.sqlite``, ``..._quick.sqlite`` with ``--quick``); a
rerun skips what is there (``--fresh`` starts over). The table gives, per setting and
method, the bias, std and RMSE of the estimate divided by the true sigma; the figure
plots RMSE / sigma against theta, one panel per (N, noise), with sqrt(CRB) / sigma.

    python benchmarks/jitter_meter.py --quick            # N = 1000, 10 records a setting
    python benchmarks/jitter_meter.py                    # the full study (long)
    python benchmarks/jitter_meter.py --records 200 --sizes 1000 --methods ieee1057 adctoolbox
    python benchmarks/jitter_meter.py --instrument       # issue 26: N = 2^16, 1 GHz at 7 GS/s
    python benchmarks/jitter_meter.py --shapes           # the fast route, 4 laws

``--instrument`` runs the instrument-scale comparison of issue 26 instead (no sqlite, one
run, the peer in the same process): N = 2^16, a coherent ~1 GHz tone (J prime to N) at
7 GS/s, amplitude 0.49, Gaussian jitter of 1 fs .. 10 ps, with no additive noise and with
50 uV; per setting the bias, RMSE and 95 % coverage of ``measure_jitter(y, T,
method="gaussian")`` and the RMSE of ``adctoolbox.analyze_error_by_phase``, and the CPU
seconds per record of each (``time.process_time``, the same records, alternating).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sqlite3
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

os.environ.setdefault("MPLBACKEND", "Agg")  # adctoolbox imports pyplot

sys.path.insert(0, str(Path(__file__).resolve().parent))
from peers import adctoolbox_jitter, adctoolbox_version, ieee1057_jitter

import jitterid

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
T = 1e-9
AMPLITUDE, OFFSET = 1.0, 0.1
LAWS = {"gaussian": 0, "uniform": 1, "dual_dirac": 2}
METHODS = ("jitterid", "adctoolbox", "ieee1057")

FULL = {
    "thetas": [0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0],
    "noises": [1e-4, 1e-3, 1e-2, 1e-1],
    "sizes": [1000, 100_000],
    "records": 50,
}
QUICK = {
    "thetas": [0.005, 0.05, 0.5, 1.0],
    "noises": [1e-4, 1e-2, 1e-1],
    "sizes": [1000],
    "records": 10,
}


# ----------------------------------------------------------------------------- records


def _seed(law: str, n: int, theta: float, noise: float, rep: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(
        [20261201, LAWS[law], n, round(theta * 1e6), round(noise * 1e9), rep]
    )


def draw_jitter(rng: np.random.Generator, law: str, sigma: float, n: int) -> np.ndarray:
    """``n`` jitter values (s) of std ``sigma`` from ``law``."""
    if law == "gaussian":
        return rng.normal(0.0, sigma, n)
    if law == "uniform":
        half = math.sqrt(3.0) * sigma
        return rng.uniform(-half, half, n)
    if law == "dual_dirac":
        rj = sigma / 3.0
        delta = math.sqrt(sigma**2 - rj**2)
        return delta * rng.choice([-1.0, 1.0], n) + rng.normal(0.0, rj, n)
    raise ValueError(f"unknown law {law!r}; choose from {sorted(LAWS)}")


def make_record(
    law: str, n: int, theta: float, noise: float, rep: int
) -> tuple[np.ndarray, float, float]:
    """One record ``y`` with its frequency f0 (Hz) and true jitter std sigma (s)."""
    rng = np.random.default_rng(_seed(law, n, theta, noise, rep))
    f0 = rng.uniform(0.07, 0.43) / T
    sigma = theta / (2 * math.pi * f0)
    phi = rng.uniform(-math.pi, math.pi)
    tau = draw_jitter(rng, law, sigma, n)
    k = np.arange(n)
    y = AMPLITUDE * np.sin(2 * math.pi * f0 * (k * T + tau) + phi) + OFFSET
    y += rng.normal(0.0, noise * AMPLITUDE, n)
    return y, f0, sigma


# ----------------------------------------------------------------------------- methods


def _jitterid_method() -> Callable[[np.ndarray], tuple[float, float]] | None:
    meter = getattr(jitterid, "measure_jitter", None)
    if meter is None:
        return None

    def run(y: np.ndarray) -> tuple[float, float]:
        res = meter(y, T, frequency=None)
        return float(res.jitter_std), float(getattr(res, "jitter_std_stderr", math.nan))

    return run


def available_methods(wanted: list[str]) -> dict[str, Callable[[np.ndarray], tuple[float, float]]]:
    """The runnable methods among ``wanted``; prints a note for each one skipped."""
    out: dict[str, Callable[[np.ndarray], tuple[float, float]]] = {}
    for name in wanted:
        if name == "jitterid":
            fn = _jitterid_method()
            if fn is None:
                print(
                    "# note: jitterid.measure_jitter does not exist on this branch: column skipped"
                )
                continue
            out[name] = fn
        elif name == "adctoolbox":
            if adctoolbox_version() is None:
                print(
                    "# note: adctoolbox is not installed (pip install 'jitterid[bench]'): column "
                    "skipped"
                )
                continue
            out[name] = lambda y: (adctoolbox_jitter(y, T), math.nan)
        elif name == "ieee1057":
            out[name] = lambda y: (ieee1057_jitter(y, T), math.nan)
        else:
            raise SystemExit(f"unknown method {name!r}; choose from {METHODS}")
    return out


#: law -> (family, its parameter from the jitter std, d std / d parameter): the laws whose
#: family the meter fits; the dual-Dirac records are outside it (no bound printed).
_FAMILIES = {
    "gaussian": (jitterid.GaussianFamily, 1.0),
    "uniform": (jitterid.UniformFamily, math.sqrt(3.0)),
}


def _crb_function() -> Callable[..., float] | None:
    """``jitterid.crb`` (sampled Fisher information: the mean outer product of the exact
    scores over simulated records, ``crb(..., draws=, rng=)``)."""
    return getattr(jitterid, "crb", None)


def _crb_std(law: str, n: int, f0: float, sigma: float, noise: float) -> float | None:
    """sqrt(CRB) of the jitter std (s) for the blind problem (jitter law's scale, noise std,
    amplitude, phase, frequency and offset all unknown), at ``f0`` and ``sigma``, from
    ``jitterid.crb`` with the Fisher information sampled over max(1, 20000 // n) records
    (about 1 % relative error); None for a law outside the fitted families."""
    if law not in _FAMILIES:
        return None
    family, per_std = _FAMILIES[law]
    truth = [sigma * per_std, AMPLITUDE, 0.0, f0, OFFSET]
    cov = jitterid.crb(
        jitterid.SineWave(),
        family(),
        None,
        T,
        n,
        noise * AMPLITUDE,
        truth,
        estimate_noise=True,
        draws=max(1, 20000 // n),
        rng=0,
    )
    return float(math.sqrt(cov[0, 0]) / per_std)


# ----------------------------------------------------------------------------- storage

SCHEMA = """
CREATE TABLE IF NOT EXISTS results (
    law TEXT, n INTEGER, theta REAL, noise REAL, rep INTEGER, method TEXT,
    truth REAL, frequency REAL, estimate REAL, stderr REAL, seconds REAL, error TEXT,
    PRIMARY KEY (law, n, theta, noise, rep, method)
)
"""


def _open(path: Path, fresh: bool) -> sqlite3.Connection:
    path.parent.mkdir(parents=True, exist_ok=True)
    if fresh and path.exists():
        path.unlink()
    con = sqlite3.connect(path)
    con.execute(SCHEMA)
    return con


def _done(con: sqlite3.Connection, key: tuple[str, int, float, float, int]) -> set[str]:
    rows = con.execute(
        "SELECT method FROM results WHERE law=? AND n=? AND theta=? AND noise=? AND rep=?", key
    )
    return {r[0] for r in rows}


def run_cell(
    con: sqlite3.Connection,
    methods: dict[str, Callable[[np.ndarray], tuple[float, float]]],
    law: str,
    n: int,
    theta: float,
    noise: float,
    records: int,
    with_crb: bool,
) -> int:
    """Compute and store what is missing for one setting; returns the (record, method) pairs run."""
    ran = 0
    for rep in range(records):
        key = (law, n, theta, noise, rep)
        todo = [m for m in methods if m not in _done(con, key)]
        want_crb = with_crb and "sqrt_crb" not in _done(con, key)
        if not todo and not want_crb:
            continue
        y, f0, sigma = make_record(law, n, theta, noise, rep)
        for name in todo:
            t0 = time.perf_counter()
            try:
                est, se = methods[name](y)
                err = None
            except Exception as exc:  # noqa: BLE001 - a failed fit is a result too
                est, se, err = math.nan, math.nan, f"{type(exc).__name__}: {exc}"[:500]
            secs = time.perf_counter() - t0
            con.execute(
                "INSERT OR REPLACE INTO results VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
                (*key, name, sigma, f0, est, se, secs, err),
            )
            ran += 1
        if want_crb:
            crb = _crb_std(law, n, f0, sigma, noise)
            con.execute(
                "INSERT OR REPLACE INTO results VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
                (*key, "sqrt_crb", sigma, f0, crb, math.nan, 0.0, None),
            )
        con.commit()
    return ran


# ----------------------------------------------------------------------------- summary


def summarize(
    con: sqlite3.Connection,
    law: str,
    n: int,
    theta: float,
    noise: float,
    method: str,
    records: int,
) -> dict[str, float]:
    rows = con.execute(
        "SELECT truth, estimate, seconds, error FROM results WHERE law=? AND n=? AND theta=? "
        "AND noise=? AND method=? AND rep<?",
        (law, n, theta, noise, method, records),
    ).fetchall()
    if not rows:
        return {}
    truth = np.array([r[0] for r in rows])
    est = np.array([math.nan if r[1] is None else r[1] for r in rows], dtype=float)
    ok = np.isfinite(est)
    rel = est[ok] / truth[ok]
    out = {"n": float(len(rows)), "failed": float((~ok).sum())}
    if rel.size:
        out.update(
            bias=float(rel.mean() - 1.0),
            std=float(rel.std(ddof=1)) if rel.size > 1 else math.nan,
            rmse=float(np.sqrt(np.mean((rel - 1.0) ** 2))),
            ms=float(np.median([r[2] for r in rows]) * 1e3),
        )
    return out


def print_table(con, methods, grid, laws, records, with_crb) -> None:  # type: ignore[no-untyped-def]
    print(
        f"\n{'law':<10} {'N':>6} {'theta':>6} {'noise':>7} {'method':<10} {'ok':>5} "
        f"{'bias/s':>8} {'std/s':>8} {'rmse/s':>8} {'sqrtCRB/s':>9} {'ms':>7}"
    )
    for law in laws:
        for n in grid["sizes"]:
            for noise in grid["noises"]:
                for theta in grid["thetas"]:
                    crb = (
                        summarize(con, law, n, theta, noise, "sqrt_crb", records)
                        if with_crb
                        else {}
                    )
                    crb_txt = f"{crb['bias'] + 1:9.3g}" if "bias" in crb else f"{'n/a':>9}"
                    for name in methods:
                        s = summarize(con, law, n, theta, noise, name, records)
                        if not s:
                            continue
                        ok = f"{int(s['n'] - s['failed'])}/{int(s['n'])}"
                        if "bias" in s:
                            nums = f"{s['bias']:+8.3f} {s['std']:8.3f} {s['rmse']:8.3f}"
                            ms = f"{s['ms']:7.1f}"
                        else:
                            nums, ms = f"{'-':>8} {'-':>8} {'-':>8}", f"{'-':>7}"
                        print(
                            f"{law:<10} {n:>6} {theta:>6g} {noise:>7g} {name:<10} {ok:>5} "
                            f"{nums} {crb_txt} {ms}"
                        )


def make_figure(con, methods, grid, laws, records, with_crb, path: Path) -> None:  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes, noises = grid["sizes"], grid["noises"]
    fig, axes = plt.subplots(
        len(sizes),
        len(noises),
        figsize=(4.2 * len(noises) + 2.6, 3.4 * len(sizes)),
        squeeze=False,
        sharex=True,
        sharey=True,
    )
    colours = {"jitterid": "C0", "adctoolbox": "C1", "ieee1057": "C2"}
    styles = {"gaussian": "-", "uniform": "--", "dual_dirac": ":"}
    markers = {"jitterid": "^", "adctoolbox": "o", "ieee1057": "s"}
    thetas = np.array(grid["thetas"])
    for i, n in enumerate(sizes):
        for j, noise in enumerate(noises):
            ax = axes[i, j]
            for law in laws:
                for name in methods:
                    rmse = [
                        summarize(con, law, n, th, noise, name, records).get("rmse", math.nan)
                        for th in thetas
                    ]
                    ax.loglog(
                        thetas,
                        rmse,
                        styles[law],
                        color=colours[name],
                        marker=markers[name],
                        ms=3,
                        label=f"{name} {law}" if (i, j) == (0, 0) else None,
                    )
                if with_crb:
                    crb = [
                        summarize(con, law, n, th, noise, "sqrt_crb", records).get("bias", math.nan)
                        + 1
                        for th in thetas
                    ]
                    ax.loglog(
                        thetas,
                        crb,
                        styles[law],
                        color="k",
                        lw=1,
                        label=f"sqrt(CRB) {law}" if (i, j) == (0, 0) else None,
                    )
            ax.set_title(f"N = {n}, noise = {noise:g} A", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            if i == len(sizes) - 1:
                ax.set_xlabel("theta = 2 pi f0 sigma (rad)")
            if j == 0:
                ax.set_ylabel("RMSE / sigma")
    # one legend to the right of the panels, outside them (law = line style, method = colour)
    fig.tight_layout(rect=(0, 0, 1 - 2.6 / fig.get_figwidth(), 1))
    fig.legend(loc="center right", fontsize=7, frameon=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    print(f"# figure: {path}")


# ----------------------------------------------------------------------------- main


def instrument_study(records: int, sizes: list[int]) -> None:
    """Issue 26's instrument-scale comparison (see the module doc, ``--instrument``)."""
    fs = 7e9
    Ti = 1 / fs
    have_peer = adctoolbox_version() is not None
    print(
        f"# instrument scale: fs = 7 GS/s, amplitude 0.49, {records} records a setting; "
        f"adctoolbox {adctoolbox_version() or 'absent'}"
    )
    print(
        f"{'N':>7} {'sigma':>7} {'noise':>6} {'ji bias':>8} {'ji rmse':>8} {'cover':>6} "
        f"{'peer bias':>9} {'peer rmse':>9} {'rmse ratio':>10} {'ji ms':>7} {'peer ms':>7} "
        f"{'cpu ratio':>9}"
    )
    for n in sizes:
        J = round(1e9 * n * Ti) | 1
        while math.gcd(J, n) != 1:
            J += 2
        f0 = J / (n * Ti)
        for sigma in (1e-15, 10e-15, 100e-15, 1e-12, 10e-12):
            for noise in (0.0, 50e-6):
                est, cover, peer, t_ji, t_peer = [], 0, [], 0.0, 0.0
                for rep in range(records):
                    rng = np.random.default_rng(
                        [26, n, round(sigma * 1e18), round(noise * 1e9), rep]
                    )
                    tau = rng.normal(0.0, sigma, n)
                    phi = rng.uniform(-math.pi, math.pi)
                    y = 0.49 * np.sin(2 * math.pi * f0 * (np.arange(n) * Ti + tau) + phi)
                    y = y + rng.normal(0.0, noise, n) if noise else y
                    c0 = time.process_time()
                    m = jitterid.measure_jitter(y, Ti, method="gaussian")
                    c1 = time.process_time()
                    lo, hi = m.interval()
                    est.append(m.jitter_std / sigma)
                    cover += lo <= sigma <= hi
                    t_ji += c1 - c0
                    if have_peer:
                        c0 = time.process_time()
                        peer.append(adctoolbox_jitter(y, Ti) / sigma)
                        t_peer += time.process_time() - c0
                e = np.array(est)
                rmse = float(np.sqrt(np.mean((e - 1) ** 2)))
                if have_peer:
                    p = np.array(peer)
                    prmse = float(np.sqrt(np.mean((p - 1) ** 2)))
                    peer_txt = (
                        f"{p.mean() - 1:+9.4f} {prmse:9.4f} {rmse / prmse:10.3f} "
                        f"{1e3 * t_ji / records:7.1f} {1e3 * t_peer / records:7.1f} "
                        f"{t_ji / t_peer:9.2f}"
                    )
                else:
                    peer_txt = f"{'-':>9} {'-':>9} {'-':>10} {1e3 * t_ji / records:7.1f}"
                print(
                    f"{n:>7} {sigma:>7.0e} {noise:>6.0e} {e.mean() - 1:+8.4f} {rmse:8.4f} "
                    f"{cover / records:6.2f} {peer_txt}"
                )


def _shape_draw(law: str, rng: np.random.Generator, s: float, n: int) -> np.ndarray:
    """Phase jitter (rad) of std ``s`` for :func:`shapes_study`."""
    if law == "uniform":
        return rng.uniform(-s * math.sqrt(3), s * math.sqrt(3), n)
    if law == "dual_dirac":
        rj = s / 3
        return math.sqrt(s * s - rj * rj) * rng.choice([-1.0, 1.0], n) + rj * rng.normal(0, 1, n)
    if law == "scale_mixture":  # two Gaussians of std ratio 0.6 : 1.28, kurtosis 4.2
        sc = np.where(rng.random(n) < 0.5, 0.6, 1.28) / math.sqrt((0.36 + 1.28**2) / 2)
        return s * sc * rng.normal(0, 1, n)
    return s * rng.normal(0, 1, n)


def shapes_study(records: int, n: int) -> None:
    """The fast route on non-Gaussian laws (``--shapes``): bias and coverage of
    ``measure_jitter(y, T, method="gaussian")`` (default laws: law-free on the moments up
    to ~0.2 rad of phase spread, the likelihood beyond), a 123 Hz tone at T = 1 ms,
    amplitude 1, offset 0.1, noise 1e-2, frequency unknown."""
    Ts, F = 1e-3, 123.0
    print(f"# fast route (method='gaussian', default laws), N = {n}, {records} records a cell")
    print(f"{'law':<14} {'theta':>6} {'bias':>8} {'rmse':>7} {'cover':>6} {'flagged':>7}")
    for law in ("uniform", "dual_dirac", "gaussian", "scale_mixture"):
        for theta in (0.05, 0.3, 0.6, 1.0):
            sig = theta / (2 * math.pi * F)
            est, cover, flagged = [], 0, 0
            for rep in range(records):
                rng = np.random.default_rng([27, LAWS.get(law, 3), round(theta * 100), rep])
                t = np.arange(n) * Ts + _shape_draw(law, rng, theta, n) / (2 * math.pi * F)
                y = np.sin(2 * math.pi * F * t + rng.uniform(0, 2 * math.pi)) + 0.1
                y = y + rng.normal(0, 1e-2, n)
                m = jitterid.measure_jitter(y, Ts, method="gaussian")
                lo, hi = m.interval()
                est.append(m.jitter_std / sig)
                cover += lo <= sig <= hi
                flagged += bool(m.findings)
            e = np.array(est)
            print(
                f"{law:<14} {theta:>6g} {e.mean() - 1:+8.4f} {np.sqrt(np.mean((e - 1) ** 2)):7.4f} "
                f"{cover / records:6.2f} {flagged:>7d}"
            )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="N = 1000 only, few records")
    ap.add_argument("--records", type=int, help="records per setting")
    ap.add_argument("--sizes", type=int, nargs="+", help="record lengths N")
    ap.add_argument("--thetas", type=float, nargs="+", help="2 pi f0 sigma values (rad)")
    ap.add_argument("--noises", type=float, nargs="+", help="noise std / amplitude values")
    ap.add_argument("--laws", nargs="+", choices=sorted(LAWS), default=list(LAWS))
    ap.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    ap.add_argument("--db", type=Path, help="sqlite file of per-record results")
    ap.add_argument("--figure", type=Path, help="PNG path ('none' for no figure)")
    ap.add_argument("--fresh", action="store_true", help="discard stored results first")
    ap.add_argument(
        "--shapes",
        action="store_true",
        help="the law-free moment route on uniform, dual-Dirac, Gaussian, mixture jitter",
    )
    ap.add_argument(
        "--instrument",
        action="store_true",
        help="issue 26's instrument-scale comparison (N = 2^16, 1 GHz at 7 GS/s) instead",
    )
    args = ap.parse_args(argv)
    if args.instrument:
        instrument_study(args.records or 16, args.sizes or [2**16])
        return
    if args.shapes:
        shapes_study(args.records or 100, (args.sizes or [1000])[0])
        return

    grid = dict(QUICK if args.quick else FULL)
    for name in ("records", "sizes", "thetas", "noises"):
        if getattr(args, name) is not None:
            grid[name] = getattr(args, name)
    stem = "jitter_meter_quick" if args.quick else "jitter_meter"
    db = args.db or RESULTS / f"{stem}.sqlite"
    figure = args.figure or RESULTS / f"{stem}.png"

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# jitter meter study on {platform.node()} ({platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load {load:.1f}), {time.strftime('%Y-%m-%d %H:%M')}; "
        f"adctoolbox {adctoolbox_version() or 'absent'}"
    )
    print(
        f"# {'quick' if args.quick else 'full'}: N in {grid['sizes']}, theta in {grid['thetas']}, "
        f"noise in {grid['noises']}, laws {args.laws}, {grid['records']} records a setting; "
        f"results in {db}"
    )
    methods = available_methods(args.methods)
    with_crb = _crb_function() is not None
    if not with_crb:
        print("# note: jitterid.crb does not exist on this branch: sqrt(CRB) column skipped")

    con = _open(db, args.fresh)
    t0 = time.perf_counter()
    ran = 0
    for n in grid["sizes"]:
        for law in args.laws:
            for noise in grid["noises"]:
                for theta in grid["thetas"]:
                    ran += run_cell(con, methods, law, n, theta, noise, grid["records"], with_crb)
    print(
        f"# computed {ran} (record, method) results in {time.perf_counter() - t0:.1f} s "
        f"(the rest were stored)"
    )
    print_table(con, methods, grid, args.laws, grid["records"], with_crb)
    if str(figure).lower() != "none":
        make_figure(con, methods, grid, args.laws, grid["records"], with_crb, figure)
    con.close()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"# load at the end {load:.1f}")


if __name__ == "__main__":
    main()
