"""Physical quantities of a fitted LTI model with confidence intervals.

:func:`physical_quantities` turns the system parameters of a fit (and their block of the
covariance C, ``FitResult.cov``) into what a control engineer reads off a model:

- the poles and zeros, one entry per real root and one per complex pair (the root with
  Im > 0): real part in 1/s, imaginary part in rad/s (s = sigma + i omega is in rad/s);
- the DC gain G(0);
- per real stable pole p the time constant -1/p (s); per complex pair the natural
  frequency |p| / (2 pi) in **Hz** (``wn_hz``) and the damping ratio zeta = -Re p / |p|;
- the -3 dB bandwidth (Hz): the first frequency at which |G(i 2 pi f)| drops below
  10^(-3/20) = 0.708 of |G(0)| (MATLAB's ``bandwidth``, there in rad/s), found as the
  smallest positive root of the polynomial |N(i w)|^2 - 0.708^2 |G(0)|^2 |D(i w)|^2 in
  w^2. NaN, with a note, where |G| never drops 3 dB below DC (a high-pass, a lead) or
  |G(0)| is 0 or infinite.

Names carry their unit (``tau_s``, ``wn_hz``, ``bandwidth_hz``, ``pole_re_per_s``,
``pole_im_rad_per_s``); with several modes (roots, a pair counting once) the names are
numbered from the slowest mode, |p| ascending: ``pole1_re_per_s``, ``wn2_hz``, ``tau1_s``.

Two routes, as :func:`jitterid.bode_band`:

- ``"delta"``: se^2 = g^T C g with g the derivative of the quantity with respect to the
  system parameters (:func:`jitterid.finite_diff.derivative`; steps at most a twentieth of
  each parameter's standard error). The roots at a perturbed parameter are matched to the
  estimate's roots by nearest distance (an assignment), never by ``np.roots``' order, so a
  quantity follows its own mode. Intervals are q -+ z se, except for the positive
  quantities (time constants, natural frequencies, the bandwidth), whose intervals are on
  the log scale, q exp(-+ z se / q) (positive and asymmetric); ``Quantity.scale`` says
  which.
- ``"sampling"``: draws theta^(r) ~ N(x, C) (draws outside the structure's bounds, or
  that give no valid system, are discarded; at least 90 % must remain), the quantity at each
  draw (roots matched as above), and the (1 - level)/2 and (1 + level)/2 quantiles;
  ``stderr`` is then 1.4826 x the draws' median absolute deviation (the standard
  deviation for normal draws, not inflated by the rare draw near a pole at 0).

A system parameter without a variance (on or next to its bound, ``cov_type="none"``) gives
NaN standard errors and intervals for every quantity that depends on it, with the reason
in ``Quantity.note``; the others are conditional on it, as in the fit's own covariance.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats
from scipy.optimize import linear_sum_assignment

from .. import finite_diff
from .._checks import count, generator
from ..systems.structures import ModelStructure
from ..systems.tf import TransferFunction
from .uncertainty import _evaluate_draws, _Fit, _indices, _is_fit, _level, _normal_draws

__all__ = ["PhysicalQuantities", "Quantity", "bandwidth_hz", "physical_quantities"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

DROP_3DB = 10.0 ** (-3.0 / 20.0)  # 0.7079: "-3 dB" as MATLAB's bandwidth() reads it
_METHODS = ("delta", "sampling")


class _Invalid(ValueError):
    """A parameter vector at which the quantities cannot be matched to the estimate's."""


# ---------------------------------------------------------------------------- the table


@dataclass(frozen=True)
class Quantity:
    """One physical quantity of a fitted system with its interval.

    Attributes
    ----------
    name : str
        E.g. ``"wn_hz"``, ``"zeta"``, ``"tau1_s"``, ``"pole_re_per_s"``.
    value : float
        At the estimate.
    stderr : float
        Delta-method standard error (``"delta"``) or the draws' robust spread
        (``"sampling"``); NaN with a reason in ``note``; 0 for a known system.
    low, high : float
        The interval at the table's level.
    unit : str
        ``"s"``, ``"Hz"``, ``"1/s"``, ``"rad/s"``, ``"y/u"`` (output unit per input unit) or
        ``""`` (dimensionless).
    scale : str
        How the interval was made: ``"linear"`` (q -+ z se), ``"log"`` (q exp(-+ z se/q)),
        ``"quantiles"`` (of the sampled quantity), ``"known"`` (no uncertainty).
    note : str
        Why a value or an interval is NaN, or what it is conditional on; ``""`` if nothing.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05))
    >>> q = ji.physical_quantities(res)["tau_s"]
    >>> q.name, q.unit, round(q.value, 1), bool(q.low < q.value < q.high)
    ('tau_s', 's', 0.5, True)
    """

    name: str
    value: float
    stderr: float
    low: float
    high: float
    unit: str
    scale: str = "linear"
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "stderr": self.stderr,
            "low": self.low,
            "high": self.high,
            "unit": self.unit,
            "scale": self.scale,
            "note": self.note,
        }


@dataclass(frozen=True, eq=False)
class PhysicalQuantities:
    """The physical quantities of a fit (:func:`physical_quantities`), immutable.

    Index by name (``pq["zeta"]``, a :class:`Quantity`), iterate over the rows, ``len``,
    ``in``; :meth:`summary` is a text table, :meth:`to_dict` JSON-ready values (NaN kept as
    float NaN).

    Parameters
    ----------
    quantities : tuple of Quantity
        The rows.
    level : float
        Coverage of the intervals, in (0, 1).
    method : str
        How the intervals were computed: ``"delta"`` or ``"sampling"``.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> pq = ji.physical_quantities(ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05)))
    >>> pq.names
    ('pole_re_per_s', 'dc_gain', 'bandwidth_hz', 'tau_s')
    >>> round(pq["dc_gain"].value, 1)
    1.0
    """

    quantities: tuple[Quantity, ...]
    level: float
    method: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "quantities", tuple(self.quantities))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(q.name for q in self.quantities)

    def __getitem__(self, name: str) -> Quantity:
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"no quantity {name!r}; this fit has {list(self.names)}")

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __iter__(self) -> Iterator[Quantity]:
        return iter(self.quantities)

    def __len__(self) -> int:
        return len(self.quantities)

    def summary(self) -> str:
        """A text table: name, estimate, standard error, interval, unit; notes below."""
        pct = f"{100 * self.level:g}%"
        logs = [q.name for q in self.quantities if q.scale == "log"]
        how = {
            "delta": "delta method"
            + (f"; log-scale intervals for {', '.join(logs)}" if logs else ""),
            "sampling": "quantiles of parameter draws",
        }[self.method]
        lines = [
            f"physical quantities ({how}):",
            f"  {'quantity':<18} {'estimate':>11} {'std err':>10} {pct + ' interval':>26}  unit",
        ]
        for q in self.quantities:
            lines.append(
                f"  {q.name:<18} {q.value:>11.5g} {q.stderr:>10.3g}   "
                f"[{q.low:>10.5g}, {q.high:>10.5g}]  {q.unit or '-'}"
            )
        by_note: dict[str, list[str]] = {}
        for q in self.quantities:
            if q.note:
                by_note.setdefault(q.note, []).append(q.name)
        lines += [f"  {', '.join(names)}: {note}" for note, names in by_note.items()]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_dict(self) -> dict[str, Any]:
        """``{"level", "method", "quantities": {name: {value, stderr, low, high, unit,
        scale, note}}}``."""
        return {
            "level": self.level,
            "method": self.method,
            "quantities": {q.name: q.to_dict() for q in self.quantities},
        }


# ---------------------------------------------------------------------------- formulas


def _abs2_poly(c: FloatArray) -> FloatArray:
    """|c(i w)|^2 as a polynomial in x = w^2 (highest power first).

    c(s) c(-s) is even in s; at s = i w its s^(2j) coefficient m_2j gives m_2j (-1)^j x^j.
    """
    c = np.asarray(c, float)
    d = c.size - 1
    flip = c * (-1.0) ** (d - np.arange(d + 1))
    m = np.convolve(c, flip)[0::2]  # powers 2d, 2d - 2, ..., 0 of s
    return np.asarray(m * (-1.0) ** (d - np.arange(d + 1)), float)


def bandwidth_hz(system: TransferFunction, drop: float = DROP_3DB) -> tuple[float, str]:
    """The first frequency (Hz) where |G(i 2 pi f)| falls below ``drop`` x |G(0)|, and a note.

    The smallest positive root x = w^2 of |N(i w)|^2 - drop^2 |G(0)|^2 |D(i w)|^2 (at x = 0
    it is positive), polished by two Newton steps. Returns (NaN, why) where there is none.
    """
    num, den = np.asarray(system.num, float), np.asarray(system.den, float)
    if den[-1] == 0:
        return math.nan, "a pole at s = 0: |G(0)| is infinite, so there is no -3 dB bandwidth"
    g0 = abs(num[-1] / den[-1])
    if g0 == 0:
        return math.nan, "|G(0)| = 0 (a zero at s = 0, e.g. a high-pass): no -3 dB bandwidth"
    a, b = _abs2_poly(num), (drop * g0) ** 2 * _abs2_poly(den)
    poly = np.zeros(max(a.size, b.size))
    poly[poly.size - a.size :] += a
    poly[poly.size - b.size :] -= b
    nz = np.flatnonzero(poly)
    poly = poly[nz[0] :] if nz.size else poly
    roots = np.roots(poly) if poly.size > 1 else np.zeros(0, complex)
    real = roots.real[(np.abs(roots.imag) <= 1e-10 * np.abs(roots)) & (roots.real > 0)]
    if not real.size:
        return math.nan, "|G| never drops 3 dB below its DC value (e.g. a high-pass or a lead)"
    x = float(real.min())
    dpoly = np.polyder(poly)
    for _ in range(2):
        slope = float(np.polyval(dpoly, x))
        if slope != 0:
            x -= float(np.polyval(poly, x)) / slope
    return math.sqrt(max(x, 0.0)) / (2 * math.pi), ""


def _representatives(roots: ComplexArray) -> tuple[ComplexArray, list[tuple[int, bool]]]:
    """The roots sorted (|p| ascending, then Im), and one (index, is_pair) per mode: each
    real root, and the Im > 0 member of each complex pair."""
    order = np.lexsort((roots.imag, np.abs(roots)))
    r = roots[order]
    tol = 1e-10 * np.maximum(np.abs(r), 1e-300)
    modes = [(i, bool(r[i].imag > tol[i])) for i in range(r.size) if r[i].imag >= -tol[i]]
    return r, modes


def _match(ref: ComplexArray, new: ComplexArray) -> ComplexArray:
    """``new`` reordered so that entry i is the root nearest ``ref[i]`` (an assignment)."""
    if new.size != ref.size:
        raise _Invalid(f"{new.size} roots where the estimate has {ref.size}")
    if not ref.size:
        return new
    _, col = linear_sum_assignment(np.abs(ref[:, None] - new[None, :]))
    return new[col]


@dataclass(frozen=True)
class _Row:
    name: str
    unit: str
    positive: bool  # log-scale delta intervals


class _Layout:
    """The rows of the table for the estimate's system, and the map from any system to the
    row values (roots matched to the estimate's)."""

    def __init__(self, system: TransferFunction) -> None:
        self.poles, self.pole_modes = _representatives(system.poles)
        self.zeros, self.zero_modes = _representatives(system.zeros)
        self.rows: list[_Row] = []
        for kind, modes in (("pole", self.pole_modes), ("zero", self.zero_modes)):
            for k, (_, pair) in enumerate(modes, start=1):
                tag = str(k) if len(modes) > 1 else ""
                self.rows.append(_Row(f"{kind}{tag}_re_per_s", "1/s", False))
                if pair:
                    self.rows.append(_Row(f"{kind}{tag}_im_rad_per_s", "rad/s", False))
        self.rows += [_Row("dc_gain", "y/u", False), _Row("bandwidth_hz", "Hz", True)]
        for k, (_, pair) in enumerate(self.pole_modes, start=1):
            tag = str(k) if len(self.pole_modes) > 1 else ""
            if pair:
                self.rows += [_Row(f"wn{tag}_hz", "Hz", True), _Row(f"zeta{tag}", "", False)]
            else:
                self.rows.append(_Row(f"tau{tag}_s", "s", True))
        self.names = tuple(r.name for r in self.rows)

    def values(self, system: TransferFunction) -> tuple[FloatArray, dict[str, str]]:
        """The row values of ``system`` and the notes of those that are NaN."""
        out: list[float] = []
        notes: dict[str, str] = {}
        poles = _match(self.poles, system.poles)
        zeros = _match(self.zeros, system.zeros)
        for roots, modes in ((poles, self.pole_modes), (zeros, self.zero_modes)):
            for i, pair in modes:
                out.append(float(roots[i].real))
                if pair:
                    out.append(float(abs(roots[i].imag)))
        den0 = float(system.den[-1])
        out.append(float(system.num[-1]) / den0 if den0 != 0 else math.nan)
        if den0 == 0:
            notes["dc_gain"] = "a pole at s = 0 (an integrator): the DC gain is infinite"
        bw, why = bandwidth_hz(system)
        out.append(bw)
        if why:
            notes["bandwidth_hz"] = why
        for i, pair in self.pole_modes:
            p = poles[i]
            if pair:
                mag = abs(p)
                out += [mag / (2 * math.pi), -p.real / mag if mag > 0 else math.nan]
            elif p.real < 0:
                out.append(-1.0 / p.real)
            else:
                out.append(math.nan)
                notes[self.names[len(out) - 1]] = (
                    f"the pole {p.real:.4g} 1/s is not stable: no decay time constant"
                )
        return np.array(out, float), notes


# ---------------------------------------------------------------------------- the fit's block


@dataclass(frozen=True, eq=False)
class _SystemBlock:
    """What the bands of an LTI fit need: the structure, its parameters at the estimate,
    their covariance block, bounds, and the parameters without a variance (with why)."""

    structure: ModelStructure
    system: TransferFunction
    theta: FloatArray
    cov: FloatArray
    bounds: tuple[tuple[float, float], ...]
    names: tuple[str, ...]
    missing: dict[str, str]

    def steps(self) -> list[float]:
        """Difference steps: the rule's own, at most a twentieth of a standard error."""
        out = []
        for i in range(self.theta.size):
            h = finite_diff.step(self.theta, i)
            se = math.sqrt(abs(self.cov[i, i])) if np.isfinite(self.cov[i, i]) else 0.0
            out.append(min(h, se / 20) if se > 0 else h)
        return out

    def jacobian(self, fun: Callable[[FloatArray], FloatArray], f0: FloatArray) -> FloatArray:
        """d fun / d theta (rows: fun's entries), NaN columns where a step is invalid."""
        jac = np.full((f0.size, self.theta.size), np.nan)
        for i, h in enumerate(self.steps()):
            try:
                jac[:, i] = finite_diff.derivative(fun, self.theta, i, self.bounds[i], f0=f0, h=h)
            except ValueError:
                continue
        return jac

    def free_cov(self) -> FloatArray:
        """The covariance with the parameters without a variance held fixed (zero rows)."""
        cov = np.array(self.cov, float)
        bad = ~np.isfinite(np.diag(cov))
        cov[bad, :] = 0.0
        cov[:, bad] = 0.0
        return np.nan_to_num(cov, nan=0.0)

    def draws(self, rng: Any, draws: int) -> FloatArray:
        """``draws`` parameter vectors from N(theta, C), those inside the bounds kept."""
        gen, n = generator(rng, "rng"), count(draws, "draws", minimum=100)
        lo, hi = np.array(self.bounds, dtype=float).reshape(-1, 2).T
        samples = _normal_draws(gen, self.theta, self.free_cov(), n)
        return samples[np.all((samples >= lo) & (samples <= hi), axis=1)]

    def dependence_notes(self, jac: FloatArray, values: FloatArray) -> list[str]:
        """Per row, "" or why its standard error is NaN: it depends on a parameter without a
        variance, or its derivative is not defined."""
        reasons = set(self.missing.values())
        if len(self.missing) == len(self.names) and len(reasons) == 1:  # e.g. cov_type="none"
            return [f"no standard error: {reasons.pop()}"] * values.size
        out = []
        scale = np.maximum(np.abs(self.theta), 1e-2)
        for g, v in zip(jac, values, strict=True):
            why = ""
            for j, name in enumerate(self.names):
                if name not in self.missing:
                    continue
                if not np.isfinite(g[j]) or abs(g[j]) * scale[j] > 1e-7 * max(abs(v), 1e-300):
                    why = f"depends on {name}, which has no standard error ({self.missing[name]})"
                    break
            if not why and not np.all(np.isfinite(g[[n not in self.missing for n in self.names]])):
                why = "not differentiable here: a perturbed parameter gives no valid value"
            out.append(why)
        return out


def _system_block(result: _Fit, what: str) -> _SystemBlock:
    """The fit's system block, or a ValueError for a fit with no transfer function."""
    if not _is_fit(result):
        raise TypeError(
            f"result must be a FitResult from jitterid.fit; got {type(result).__name__}"
        )
    structure = result.structure
    if result.system is None or not isinstance(structure, ModelStructure):
        raise ValueError(
            f"{what} needs an LTI fit (a transfer function); this fit is of a signal model "
            f"({type(structure).__name__}), which has no poles or responses: use its params, "
            "conf_int() and predict() instead"
        )
    names = tuple(structure.param_names)
    idx = _indices(result, names, "structure")
    theta = np.asarray(result.x, float)[idx]
    cov = np.asarray(result.cov, float)[np.ix_(idx, idx)]
    bad = [n for n, v in zip(names, np.diag(cov), strict=True) if not np.isfinite(v)]
    missing: dict[str, str] = {}
    if bad:
        cov_type = getattr(result, "cov_type", "")
        notes = {} if cov_type == "none" else dict(getattr(result, "stderr_notes", {}) or {})
        for n in bad:
            missing[n] = notes.get(n) or (
                "the fit has no covariance (cov_type='none')"
                if cov_type == "none"
                else "NaN in the covariance"
            )
    bounds = tuple((float(a), float(b)) for a, b in structure.bounds)
    return _SystemBlock(structure, result.system, theta, cov, bounds, names, missing)


# ---------------------------------------------------------------------------- the function


def physical_quantities(
    result: _Fit,
    level: float = 0.95,
    *,
    method: str = "delta",
    draws: int = 4000,
    rng: np.random.Generator | int | None = None,
) -> PhysicalQuantities:
    """Poles, zeros, DC gain, time constants, natural frequencies (Hz), damping ratios and
    the -3 dB bandwidth (Hz) of an LTI fit, with intervals (module docstring).

    Parameters
    ----------
    result : FitResult
        A fit of an LTI structure (``result.system`` a TransferFunction).
    level : float
        Confidence level in (0, 1).
    method : {"delta", "sampling"}
        Linearisation through the one finite-difference rule, or quantiles over parameter
        draws from N(x, C) restricted to the structure's bounds.
    draws : int
        Number of parameter draws for ``"sampling"`` (at least 100).
    rng : numpy.random.Generator or int
        Source of randomness, required for ``"sampling"``.

    Returns
    -------
    PhysicalQuantities

    Raises
    ------
    ValueError
        For a signal-model fit (no transfer function); a bad ``level`` or ``method``; for
        ``"sampling"``, if fewer than 90 % of the draws give a valid system inside the
        structure's bounds (the normal approximation is then too poor).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=2000, noise_std=0.01, rng=2)
    >>> res = jid.fit(data, jid.RationalModel(0, 1), jid.Uniform(0.05))
    >>> pq = jid.physical_quantities(res)
    >>> pq.names
    ('pole_re_per_s', 'dc_gain', 'bandwidth_hz', 'tau_s')
    >>> round(pq["tau_s"].value, 1)
    0.5
    """
    level = _level(level)
    if method not in _METHODS:
        raise ValueError(f"method must be 'delta' or 'sampling'; got {method!r}")
    block = _system_block(result, "physical_quantities")
    layout = _Layout(block.system)
    with np.errstate(all="ignore"):
        values, notes = layout.values(block.system)
        if not block.theta.size:
            rows = [
                Quantity(
                    r.name,
                    float(v),
                    0.0 if np.isfinite(v) else math.nan,
                    float(v),
                    float(v),
                    r.unit,
                    "known",
                    notes.get(r.name, "the system is known, not estimated"),
                )
                for r, v in zip(layout.rows, values, strict=True)
            ]
            return PhysicalQuantities(tuple(rows), level, method)

        def at(theta: FloatArray) -> FloatArray:
            return layout.values(block.structure.system(theta))[0]

        jac = block.jacobian(at, values)
        why = block.dependence_notes(jac, values)
        if method == "delta":
            rows = _delta_rows(layout, values, notes, jac, why, block.free_cov(), level)
        else:
            rows = _sampling_rows(layout, values, notes, why, block, at, level, rng, draws)
    return PhysicalQuantities(tuple(rows), level, method)


def _delta_rows(
    layout: _Layout,
    values: FloatArray,
    notes: dict[str, str],
    jac: FloatArray,
    why: list[str],
    cov: FloatArray,
    level: float,
) -> list[Quantity]:
    z = float(stats.norm.ppf(0.5 + level / 2))
    rows = []
    for r, v, g, w in zip(layout.rows, values, jac, why, strict=True):
        note = notes.get(r.name, "") or w
        if not np.isfinite(v) or w:
            rows.append(
                Quantity(r.name, float(v), math.nan, math.nan, math.nan, r.unit, "linear", note)
            )
            continue
        se = math.sqrt(max(float(g @ cov @ g), 0.0))
        if r.positive and v > 0:
            f = math.exp(min(z * se / v, 700.0))
            rows.append(Quantity(r.name, float(v), se, v / f, v * f, r.unit, "log", note))
        else:
            rows.append(
                Quantity(r.name, float(v), se, v - z * se, v + z * se, r.unit, "linear", note)
            )
    return rows


def _sampling_rows(
    layout: _Layout,
    values: FloatArray,
    notes: dict[str, str],
    why: list[str],
    block: _SystemBlock,
    at: Callable[[FloatArray], FloatArray],
    level: float,
    rng: Any,
    draws: int,
) -> list[Quantity]:
    Q = _evaluate_draws(at, block.draws(rng, draws), draws)
    q = [0.5 - level / 2, 0.5 + level / 2]
    rows = []
    for j, (r, v, w) in enumerate(zip(layout.rows, values, why, strict=True)):
        note = notes.get(r.name, "") or w
        col = Q[:, j]
        ok = np.isfinite(col)
        if not np.isfinite(v) or w:
            rows.append(
                Quantity(r.name, float(v), math.nan, math.nan, math.nan, r.unit, "quantiles", note)
            )
            continue
        if ok.mean() < 0.99:
            note = f"not defined in {100 * (1 - ok.mean()):.3g}% of the parameter draws"
            rows.append(
                Quantity(r.name, float(v), math.nan, math.nan, math.nan, r.unit, "quantiles", note)
            )
            continue
        col = col[ok]
        lo, hi = np.quantile(col, q)
        se = 1.4826 * float(np.median(np.abs(col - np.median(col))))
        rows.append(Quantity(r.name, float(v), se, float(lo), float(hi), r.unit, "quantiles", note))
    return rows
