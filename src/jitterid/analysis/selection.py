"""Model order selection: fit several structures to one data set and compare them.

What MATLAB users do with ``tfest`` over several (np, nz), ``aic`` and ``compare``:
:func:`select_order` fits each candidate structure with :func:`jitterid.fit` (the same data,
jitter model, method and options for all) and returns an immutable :class:`OrderSelection`,
a table with one row per candidate and the row chosen, with a sentence saying why.

What AIC and BIC are computed from (the same for every candidate, so they compare):

* ``method="ml"``: the exact log-likelihood at the estimate, l = -V / 2 with V the ML
  criterion -2 sum_k ln p(y_k | theta) (notes 4, (L1)).
* every other method: the Gaussian log-likelihood of the samples under the fitted model,

      l = -1/2 sum_k [ (y_k - m_k)^2 / w_k + ln w_k + ln 2 pi ],   w_k = Var_k + sigma_v^2,

  with m_k, Var_k the fitted model's sample means and variances under the fitted (or known)
  jitter law (Lemmas 1-2 in the time domain, :func:`jitterid.sample_moments`), and sigma_v
  the known noise std, the fit's own estimate (``gaussian``, ``asml``), or else its
  maximum-likelihood value given the residuals and the variances. For ``method="gaussian"``
  this is -(V + N ln 2 pi) / 2, V the fit's criterion. For a criterion that is not a
  likelihood (``bcls``, ...) the estimate does not maximise l, so l is lower than the
  Gaussian fit's would be; it is still the same yardstick for every candidate.

k counts every estimated parameter: jitter-family, system, and sigma_v when it is not known
(estimated by the fit or plugged in from the residuals). AIC = -2 l + 2 k,
BIC = -2 l + k ln N.

A candidate is *trustworthy* when its fit converged (``FitStatus.CONVERGED``; a failed search,
a parameter on its bound, an unidentified or unstable model are not) and it shows no sign of
an over-order model: a pole and a zero that cancel (|p - z| at most ``CANCEL_REL`` |p|, or
within ``CANCEL_SE`` standard errors of |p - z| by the delta method through the covariance),
or a pole or zero indistinguishable from infinity (its reciprocal within ``CANCEL_SE``
standard errors of 0, or |p| T above ``FAST_POLE``: the cancellation against a zero at
infinity, an extra relative degree the samples cannot see). Only a trustworthy candidate is
chosen when one exists; a fit that raised (a memory refusal, an unstable model) is a row with
its error, never a crash.
"""

from __future__ import annotations

import inspect
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from ..data import SampledData
from ..estimation.checks import (
    CANCEL_REL,
    CANCEL_SE,
    FAST_POLE,
    check_arguments,
    check_method_jitter,
    over_order_symptom,
)
from ..estimation.covariance import noise_variance_ml
from ..estimation.estimators import Estimator, as_estimator
from ..estimation.fit import fit
from ..estimation.result import FitResult, FitStatus
from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.sample import sample_moments
from ..params import count_params
from ..systems.model import Model
from ..systems.structures import Delayed, KnownSystem, ModelStructure, PolePairGain, RationalModel
from ..systems.tf import TransferFunction
from .diagnostics import input_correlation_test, ljung_box, standardized_residuals

__all__ = [
    "CANCEL_REL",
    "CANCEL_SE",
    "FAST_POLE",
    "NestedTest",
    "OrderRow",
    "OrderSelection",
    "select_order",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: the criteria :func:`select_order` ranks by
CRITERIA = ("aic", "bic", "validation")
#: errors of one candidate's fit that become its row (the selection goes on)
_FIT_ERRORS = (ValueError, TypeError, ArithmeticError, MemoryError)
_LN_2PI = math.log(2 * math.pi)


@dataclass(frozen=True, eq=False)
class OrderRow:
    """One candidate of an :class:`OrderSelection`.

    Attributes
    ----------
    label : str
        ``tf:NZ,NP`` for ``RationalModel(NZ, NP)`` (the command line's spelling),
        ``polepair``, or the structure's repr.
    structure : Model
        The candidate.
    n_params : int
        k of AIC and BIC (module notes: sigma_v counts when it is not known).
    status : FitStatus or None
        How the fit ended; None when it raised (``error`` says why).
    error : str
        The fit's error message, empty when it returned.
    cost : float
        The fit's own criterion value (NaN when it raised).
    loglik, aic, bic : float
        The log-likelihood of the module notes and the criteria from it (NaN when it raised).
    validation_fit_pct : float or None
        100 (1 - ||y - y_hat|| / ||y - mean y||) on the validation data (tfest's
        ``compare``), y_hat = :meth:`FitResult.predict`; None without validation data.
    whiteness_pvalue, input_pvalue : float or None
        Ljung-Box and residual-input independence p-values of the standardised residuals on
        the estimation data (:func:`jitterid.ljung_box`,
        :func:`jitterid.input_correlation_test`); None where they cannot be computed.
    over_order : str
        Empty, or the cancellation that marks an over-order model, with the numbers.
    notes : tuple of str
        Warnings raised during the fit and diagnostics skipped, with the reason.
    result : FitResult or None
        The fit itself.
    """

    label: str
    structure: Model = field(repr=False)
    n_params: int
    status: FitStatus | None
    error: str = ""
    cost: float = float("nan")
    loglik: float = float("nan")
    aic: float = float("nan")
    bic: float = float("nan")
    validation_fit_pct: float | None = None
    whiteness_pvalue: float | None = None
    input_pvalue: float | None = None
    over_order: str = ""
    notes: tuple[str, ...] = ()
    result: FitResult | None = field(default=None, repr=False)

    @property
    def success(self) -> bool:
        """The fit converged and passed the fit's own checks."""
        return self.status is not None and self.status.success

    @property
    def trustworthy(self) -> bool:
        """Converged, with a finite log-likelihood and no sign of an over-order model."""
        return self.success and not self.over_order and math.isfinite(self.loglik)

    @property
    def problem(self) -> str:
        """Why the row is not trustworthy (empty if it is)."""
        if self.status is None:
            return f"the fit raised an error: {self.error}"
        if self.over_order and self.status in (FitStatus.CONVERGED, FitStatus.OVER_ORDER):
            return f"over-order model: {self.over_order}"
        if not self.status.success:
            return f"{self.status.name}: {self.status.value}"
        if not math.isfinite(self.loglik):
            return "the log-likelihood could not be computed" + (
                f" ({self.notes[-1]})" if self.notes else ""
            )
        return ""

    @property
    def flag(self) -> str:
        """A short word for the table: ``ok``, ``error``, ``over-order`` or the status name."""
        if self.status is None:
            return "error"
        if self.status is FitStatus.OVER_ORDER or (self.status.success and self.over_order):
            return "over-order"
        if not self.status.success:
            return self.status.name
        return "ok" if math.isfinite(self.loglik) else "no log-lik"

    def value(self, criterion: str) -> float:
        """The row's value of ``criterion`` (NaN where there is none)."""
        if criterion == "validation":
            return float("nan") if self.validation_fit_pct is None else self.validation_fit_pct
        return float(getattr(self, criterion))

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible values (non-finite numbers as None)."""
        res = self.result
        params: dict[str, Any] = {}
        stderr: dict[str, Any] = {}
        poles: list[list[float | None]] = []
        zeros: list[list[float | None]] = []
        if res is not None:
            params = {k: _num(v) for k, v in res.params.items()}
            stderr = {k: _num(v) for k, v in res.stderr.items()}
            if res.system is not None:
                poles = [[_num(p.real), _num(p.imag)] for p in res.system.poles]
                zeros = [[_num(z.real), _num(z.imag)] for z in res.system.zeros]
        return {
            "label": self.label,
            "structure": repr(self.structure),
            "n_params": self.n_params,
            "status": None if self.status is None else self.status.name,
            "success": self.success,
            "trustworthy": self.trustworthy,
            "problem": self.problem,
            "error": self.error,
            "cost": _num(self.cost),
            "loglik": _num(self.loglik),
            "aic": _num(self.aic),
            "bic": _num(self.bic),
            "validation_fit_pct": _num(self.validation_fit_pct),
            "whiteness_pvalue": _num(self.whiteness_pvalue),
            "input_pvalue": _num(self.input_pvalue),
            "over_order": self.over_order,
            "notes": list(self.notes),
            "parameters": params,
            "stderr": stderr,
            "poles_rad_per_s": poles,
            "zeros_rad_per_s": zeros,
        }


@dataclass(frozen=True)
class NestedTest:
    """A likelihood-ratio test of a smaller candidate nested in a larger one.

    LR = 2 (l_larger - l_smaller), referred to chi-square with ``dof`` = the difference in
    parameter counts: an asymptotic reference (and for a rational model reached by a
    pole-zero cancellation an approximate one: the cancelled pair is not identified under
    the smaller model). A small p-value says the larger model fits significantly better.
    """

    smaller: str
    larger: str
    statistic: float
    dof: int
    pvalue: float
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "smaller": self.smaller,
            "larger": self.larger,
            "statistic": _num(self.statistic),
            "dof": self.dof,
            "pvalue": _num(self.pvalue),
            "note": self.note,
        }


@dataclass(frozen=True, eq=False)
class OrderSelection:
    """The outcome of :func:`select_order`, immutable.

    Attributes
    ----------
    rows : tuple of OrderRow
        One per candidate, in the order given.
    chosen : int or None
        Index of the chosen row; None only when no candidate could be fitted at all.
    reason : str
        One sentence: why that row (and which rows were set aside).
    criterion : str
        ``"aic"``, ``"bic"`` (lowest wins) or ``"validation"`` (highest fit % wins).
    method : str
        The estimator every candidate was fitted with.
    loglik_kind : str
        ``"exact"`` (``ml``: the exact likelihood) or ``"gaussian"`` (module notes).
    N : int
        Samples of the estimation data (the n of BIC's ln n).
    noise_counted : bool
        Whether sigma_v was estimated, and so counted in every row's k.
    tests : tuple of NestedTest
        Likelihood-ratio tests between consecutive nested candidates (``ml`` and
        ``gaussian`` only: the other criteria do not maximise a likelihood).

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> candidates = [ji.RationalModel(0, 1), ji.RationalModel(1, 2)]
    >>> sel = ji.select_order(data, candidates, ji.Uniform(0.05))
    >>> sel.labels, sel.best.label
    (('tf:0,1', 'tf:1,2'), 'tf:0,1')
    """

    rows: tuple[OrderRow, ...]
    chosen: int | None
    reason: str
    criterion: str
    method: str
    loglik_kind: str
    N: int
    noise_counted: bool
    tests: tuple[NestedTest, ...] = ()

    @property
    def best(self) -> OrderRow | None:
        """The chosen row."""
        return None if self.chosen is None else self.rows[self.chosen]

    @property
    def result(self) -> FitResult | None:
        """The chosen row's fit."""
        best = self.best
        return None if best is None else best.result

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(r.label for r in self.rows)

    def row(self, label: str) -> OrderRow:
        """The row of ``label``.

        Parameters
        ----------
        label : str
            The candidate's label, as in the table.
        """
        for r in self.rows:
            if r.label == label:
                return r
        raise KeyError(f"label {label!r} is not a candidate; the labels are {list(self.labels)}")

    def basis(self) -> str:
        """What AIC/BIC are computed from, in one sentence."""
        ll = (
            "the exact log-likelihood (ml)"
            if self.loglik_kind == "exact"
            else "the Gaussian log-likelihood with the model's variances Var_k + sigma_v^2"
        )
        noise = "sigma_v estimated, counted in k" if self.noise_counted else "sigma_v known"
        return f"AIC/BIC from {ll}, N = {self.N}, {noise}"

    def summary(self) -> str:
        """A readable table; the chosen row is marked ``*``."""
        has_val = any(r.validation_fit_pct is not None for r in self.rows)
        w = max(9, *(len(r.label) for r in self.rows))
        head = (
            f"  {'candidate':<{w}} {'k':>3} {'status':<16} {'log-lik':>11} {'AIC':>11} {'BIC':>11}"
            + (f" {'val fit %':>9}" if has_val else "")
            + f" {'LB p':>7} {'input p':>7}"
        )
        lines = [
            f"order selection, method {self.method!r}, by {self.criterion.upper()}; {self.basis()}",
            head,
        ]
        for i, r in enumerate(self.rows):
            mark = "*" if i == self.chosen else " "
            line = (
                f"{mark} {r.label:<{w}} {r.n_params:>3} {r.flag:<16} {_fmt(r.loglik, 11, '.6g')} "
                f"{_fmt(r.aic, 11, '.6g')} {_fmt(r.bic, 11, '.6g')}"
                + (f" {_fmt(r.validation_fit_pct, 9, '.2f')}" if has_val else "")
                + f" {_fmt(r.whiteness_pvalue, 7, '.3g')} {_fmt(r.input_pvalue, 7, '.3g')}"
            )
            lines.append(line)
        for r in self.rows:
            if r.problem:
                lines.append(f"  {r.label}: {r.problem}")
        if self.tests:
            lines.append("  likelihood-ratio tests (asymptotic chi-square, dof = difference in k):")
            for t in self.tests:
                lines.append(
                    f"    {t.smaller} within {t.larger}: LR = {t.statistic:.4g}, dof {t.dof}, "
                    f"p = {t.pvalue:.3g}" + (f" ({t.note})" if t.note else "")
                )
        lines.append(f"  chosen: {self.reason}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible values (non-finite numbers as None)."""
        best = self.best
        return {
            "method": self.method,
            "criterion": self.criterion,
            "loglik_kind": self.loglik_kind,
            "basis": self.basis(),
            "N": self.N,
            "noise_counted": self.noise_counted,
            "chosen": None if best is None else best.label,
            "chosen_index": self.chosen,
            "reason": self.reason,
            "rows": [r.to_dict() for r in self.rows],
            "likelihood_ratio_tests": [t.to_dict() for t in self.tests],
        }


# ------------------------------------------------------------------------------ helpers


def _num(v: Any) -> float | None:
    if v is None:
        return None
    f = float(v)
    return f if math.isfinite(f) else None


def _fmt(v: float | None, width: int, spec: str) -> str:
    if v is None or not math.isfinite(v):
        return f"{'-':>{width}}"
    return f"{v:>{width}{spec}}"


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def label(structure: Model) -> str:
    """``tf:NZ,NP``, ``polepair``, ``known`` (each with ``+delay`` when delayed) or the
    structure's repr."""
    if isinstance(structure, RationalModel):
        return f"tf:{structure.num_order},{structure.den_order}"
    if isinstance(structure, PolePairGain) and structure == PolePairGain():
        return "polepair"
    if isinstance(structure, KnownSystem):
        return "known"
    if isinstance(structure, Delayed):
        return f"{label(structure.structure)}+delay"
    return repr(structure)


def _labels(structures: Sequence[Model]) -> list[str]:
    """:func:`label` of each, made unique (``#i`` appended to a repeated one)."""
    labels = [label(s) for s in structures]
    return [f"{lab}#{i}" if labels.count(lab) > 1 else lab for i, lab in enumerate(labels)]


def _check_candidates(candidates: object) -> list[Model]:
    if isinstance(candidates, (str, bytes, Mapping)) or not isinstance(candidates, Sequence):
        raise TypeError(
            "candidates must be a list of model structures, e.g. [ji.RationalModel(0, 1), "
            f"ji.RationalModel(1, 2)]; got {type(candidates).__name__}"
        )
    if len(candidates) == 0:
        raise ValueError(
            "candidates is empty: give the model structures to compare, e.g. "
            "[ji.RationalModel(0, 1), ji.RationalModel(0, 2)]"
        )
    out: list[Model] = []
    for i, c in enumerate(candidates):
        if isinstance(c, TransferFunction):
            c = KnownSystem(c)
        if not isinstance(c, Model):
            raise TypeError(
                f"candidates[{i}] must be a model structure (ji.RationalModel(m, n), "
                "ji.PolePairGain(), a signal model) or a known TransferFunction; got "
                f"{type(c).__name__} {c!r}"
            )
        for j, prev in enumerate(out):
            if c is prev or (type(c) is type(prev) and _equal(c, prev)):
                raise ValueError(
                    f"candidates[{i}] repeats candidates[{j}] ({label(c)}); give each structure "
                    "once"
                )
        out.append(c)
    kinds = {bool(c.uses_input) for c in out}
    if len(kinds) > 1:
        lti = [label(c) for c in out if c.uses_input]
        sig = [label(c) for c in out if not c.uses_input]
        raise ValueError(
            "candidates mix LTI structures driven by the input "
            f"({', '.join(lti)}) with signal models that have none ({', '.join(sig)}); "
            "their likelihoods are not of the same model of the data: compare one kind at a time"
        )
    return out


def _equal(a: object, b: object) -> bool:
    try:
        return bool(a == b)
    except (ValueError, TypeError):  # a dataclass holding arrays
        return False


#: jitterid.fit's keyword arguments that select_order passes through
_FIT_OPTIONS = tuple(
    n
    for n in inspect.signature(fit).parameters
    if n not in ("data", "system", "jitter", "method", "start")
)


def _check_options(fit_kwargs: dict[str, Any]) -> None:
    if "start" in fit_kwargs:
        raise ValueError(
            "start: the candidates have different parameters, so one start cannot serve them "
            "all; select without start (each fit uses its default starts), then refit the "
            "chosen structure from a start if needed"
        )
    unknown = sorted(set(fit_kwargs) - set(_FIT_OPTIONS))
    if unknown:
        raise TypeError(
            f"select_order() got unexpected keyword arguments {unknown}; the fit options are "
            f"{list(_FIT_OPTIONS)}"
        )
    if fit_kwargs.get("noise") is not None:
        raise ValueError(
            "noise: order selection compares output-error fits with white noise; fit the "
            "Box-Jenkins candidates one by one (jitterid.fit(..., noise=...)) and compare them"
        )


# ------------------------------------------------------------------------------ log-likelihood


def _loglik(
    data: SampledData, res: FitResult, exact: bool, noise_known: float | None
) -> tuple[float, bool]:
    """(l, whether sigma_v was plugged in from the residuals) of the module notes."""
    if exact:
        return -0.5 * float(res.cost), False
    mom = sample_moments(res.signal(data.u), res.jitter_law, data.T, data.N)
    r = data.y - mom.mean
    var = np.asarray(mom.var, dtype=float)
    plugged = False
    if "noise_std" in res.names and res.noise_std is not None:
        s2 = float(res.noise_std) ** 2
    elif noise_known is not None and noise_known > 0:
        s2 = float(noise_known) ** 2
    else:
        s2 = noise_variance_ml(r, var)
        plugged = True
    w = var + s2
    if not np.all(w > 0):
        raise ValueError("the model's sample variances vanish; the log-likelihood is not finite")
    return float(-0.5 * np.sum(r * r / w + np.log(w) + _LN_2PI)), plugged


def _noise_counted(res: FitResult, plugged: bool) -> bool:
    return plugged or "noise_std" in res.names


# ------------------------------------------------------------------------------ over-order


def over_order(res: FitResult, T: float) -> str:
    """The over-order symptom of a fitted LTI model (module notes), or "": the predicate
    :func:`jitterid.estimation.checks.over_order_symptom` (also a check of every single
    fit), on the fit's system block and its covariance.

    Parameters
    ----------
    res : FitResult
        The fit.
    T : float
        The sampling interval (s).
    """
    structure = res.structure
    if res.system is None or not isinstance(structure, ModelStructure):
        return ""
    sl = res.layout.slice("system")
    return over_order_symptom(
        structure, np.asarray(res.x[sl], dtype=float), np.asarray(res.cov[sl, sl], dtype=float), T
    )


# ------------------------------------------------------------------------------ nesting


def _nested(small: Model, big: Model) -> bool:
    """Whether every model of ``small`` is one of ``big`` (a pole-zero pair added)."""
    if isinstance(small, PolePairGain):
        small = RationalModel(0, 2)
    if isinstance(small, RationalModel) and isinstance(big, RationalModel):
        extra = big.den_order - small.den_order
        return extra >= 0 and big.num_order - small.num_order >= extra and small != big
    return False


def _tests(rows: Sequence[OrderRow]) -> tuple[NestedTest, ...]:
    order = sorted(range(len(rows)), key=lambda i: rows[i].n_params)
    out: list[NestedTest] = []
    for pos, b in enumerate(order):
        big = rows[b]
        smaller = [
            a
            for a in order[:pos]
            if rows[a].n_params < big.n_params and _nested(rows[a].structure, big.structure)
        ]
        if not smaller:
            continue
        small = rows[max(smaller, key=lambda a: rows[a].n_params)]
        if not (math.isfinite(small.loglik) and math.isfinite(big.loglik)):
            continue
        lr = 2.0 * (big.loglik - small.loglik)
        dof = big.n_params - small.n_params
        notes = []
        if lr < 0:
            notes.append("negative: the larger fit ended below the smaller one's likelihood")
        if not (small.success and big.success):
            notes.append("a fit did not converge")
        out.append(
            NestedTest(
                small.label,
                big.label,
                lr,
                dof,
                float(stats.chi2.sf(max(lr, 0.0), dof)),
                "; ".join(notes),
            )
        )
    return tuple(out)


# ------------------------------------------------------------------------------ the selection


def _fit_row(
    lab: str,
    data: SampledData,
    structure: Model,
    jitter: JitterLaw | JitterFamily,
    method: str | Estimator,
    exact: bool,
    noise_known: float | None,
    validation: SampledData | None,
    fit_kwargs: dict[str, Any],
) -> tuple[OrderRow, bool]:
    """One candidate: its fit, log-likelihood, diagnostics; (row, sigma_v counted)."""
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # recorded in the row, never raised mid-selection
        try:
            res = fit(data, structure, jitter, method, **fit_kwargs)
        except _FIT_ERRORS as exc:
            res, error = None, _one_line(exc)
        else:
            error = ""
    _warned(notes, "the fit", caught)
    if res is None:
        n_jit = count_params(jitter)
        k = n_jit + len(structure.param_names)
        return OrderRow(lab, structure, k, None, error=error, notes=tuple(notes)), False
    loglik, counted = float("nan"), False
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            loglik, plugged = _loglik(data, res, exact, noise_known)
            counted = _noise_counted(res, plugged)
        except _FIT_ERRORS as exc:
            notes.append(f"log-likelihood skipped: {_one_line(exc)}")
        white = indep = fit_pct = None
        try:
            z = standardized_residuals(data, res)
            white = ljung_box(z).pvalue
            if data.u is not None and structure.uses_input:
                indep = input_correlation_test(z, np.asarray(data.u(data.t_nominal), float)).pvalue
        except _FIT_ERRORS as exc:
            notes.append(f"residual tests skipped: {_one_line(exc)}")
        if validation is not None:
            try:
                fit_pct = validation_fit(validation, res)
            except _FIT_ERRORS as exc:
                notes.append(f"validation skipped: {_one_line(exc)}")
        try:
            over = over_order(res, data.T)
        except _FIT_ERRORS as exc:
            over = ""
            notes.append(f"over-order check skipped: {_one_line(exc)}")
    _warned(notes, "the diagnostics", caught)
    n_params = len(res.names) + (1 if counted and "noise_std" not in res.names else 0)
    aic = -2 * loglik + 2 * n_params
    bic = -2 * loglik + n_params * math.log(data.N)
    return (
        OrderRow(
            lab,
            structure,
            n_params,
            res.status,
            cost=float(res.cost),
            loglik=loglik,
            aic=aic,
            bic=bic,
            validation_fit_pct=fit_pct,
            whiteness_pvalue=white,
            input_pvalue=indep,
            over_order=over,
            notes=tuple(notes),
            result=res,
        ),
        counted,
    )


def _warned(notes: list[str], where: str, caught: list[warnings.WarningMessage]) -> None:
    if caught:
        first = " ".join(str(caught[0].message).split())
        notes.append(
            f"{len(caught)} warning(s) in {where}, e.g. {caught[0].category.__name__}: {first}"
        )


def validation_fit(validation: SampledData, result: FitResult) -> float:
    """tfest's ``compare`` fit: 100 (1 - ||y - y_hat|| / ||y - mean y||), y_hat =
    :meth:`FitResult.predict` (E y_k under the fitted model and jitter law)."""
    y = np.asarray(validation.y, float)
    yhat = result.predict(validation)
    spread = float(np.linalg.norm(y - y.mean()))
    if spread == 0:
        raise ValueError("validation.y is constant: the fit % is not defined")
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / spread))


def _choose(rows: Sequence[OrderRow], criterion: str) -> tuple[int | None, str]:
    sign = -1.0 if criterion == "validation" else 1.0  # lowest AIC/BIC, highest fit %
    name = "validation fit" if criterion == "validation" else criterion.upper()
    unit = " %" if criterion == "validation" else ""

    def finite(i: int) -> bool:
        return math.isfinite(rows[i].value(criterion))

    tiers = [
        ("trustworthy", [i for i, r in enumerate(rows) if r.trustworthy and finite(i)]),
        ("converged", [i for i, r in enumerate(rows) if r.success and finite(i)]),
        ("fitted", [i for i, r in enumerate(rows) if r.result is not None and finite(i)]),
    ]
    tier, pool = next(((t, p) for t, p in tiers if p), ("", []))
    if not pool:
        failed = "; ".join(f"{r.label}: {r.problem}" for r in rows)
        return None, f"no candidate could be fitted and scored ({failed})"
    pool = sorted(pool, key=lambda i: sign * rows[i].value(criterion))
    best = pool[0]
    r = rows[best]
    best_text = "highest" if criterion == "validation" else "lowest"
    text = f"{r.label} has the {best_text} {name} ({r.value(criterion):.6g}{unit})"
    others = len(pool) - 1
    text += f" of the {len(pool)} {tier} candidates" if others else f", the only {tier} candidate"
    if others:
        nxt = rows[pool[1]]
        gap = abs(nxt.value(criterion) - r.value(criterion))
        side = "lower" if criterion == "validation" else "higher"
        text += f"; next {nxt.label}, {gap:.3g}{unit} {side}"
        if criterion == "bic":
            text += " (a BIC gap above 6 is strong evidence, above 10 very strong)"
    aside = [rows[i] for i in range(len(rows)) if i not in pool]
    if aside:
        text += "; set aside: " + "; ".join(f"{a.label} ({_short(a, criterion)})" for a in aside)
    if tier != "trustworthy":
        text = f"no candidate can be trusted, so this choice is not either: {text}"
    return best, text


def _short(row: OrderRow, criterion: str) -> str:
    if row.status is None:
        return "the fit raised an error"
    if row.status is FitStatus.OVER_ORDER or (row.success and row.over_order):
        return "over-order"
    if not row.success:
        return row.status.name
    if not math.isfinite(row.value(criterion)):
        return f"no {criterion} value"
    return "not trustworthy"


def select_order(
    data: SampledData,
    candidates: Sequence[Model | TransferFunction],
    jitter: JitterLaw | JitterFamily,
    method: str | Estimator = "bcls",
    *,
    criterion: str = "bic",
    validation: SampledData | None = None,
    **fit_kwargs: Any,
) -> OrderSelection:
    """Fit every candidate structure to ``data`` and choose one (MATLAB: ``tfest`` over
    several (np, nz), then ``aic`` and ``compare``).

    Parameters
    ----------
    data : SampledData
        The estimation data; every candidate is fitted to it.
    candidates : sequence of Model or TransferFunction
        The structures to compare, e.g. ``[ji.RationalModel(0, 1), ji.RationalModel(1, 2),
        ji.RationalModel(0, 2), ji.RationalModel(1, 3)]``; all LTI structures driven by the
        input, or all signal models (a mix is refused), each given once.
    jitter : JitterLaw or JitterFamily
        The one jitter model of every fit.
    method : str or Estimator
        The one estimator of every fit (:func:`jitterid.fit`).
    criterion : {"bic", "aic", "validation"}
        What ranks the trustworthy candidates: the lowest BIC (default; consistent: it
        picks the true order with probability -> 1 as N grows), the lowest AIC (leans to
        larger models), or the highest fit % on ``validation``.
    validation : SampledData, optional
        Second data set for the ``validation_fit_pct`` column (tfest's ``compare``).
    **fit_kwargs
        Passed to every :func:`jitterid.fit` (``noise_std``, ``max_nfev``, ``cov_type``,
        ``freqs``); ``start`` is refused (the candidates' parameters differ) and so is
        ``noise`` (white-noise fits only).

    Returns
    -------
    OrderSelection
        A row per candidate (see the module notes for what l, AIC and BIC are computed
        from), the chosen row and why; with ``method`` ``"ml"`` or ``"gaussian"``, the
        likelihood-ratio tests between consecutive nested candidates.

    Raises
    ------
    ValueError, TypeError
        Naming the argument: ``candidates`` empty, repeated, not structures, or mixing LTI
        structures with signal models; ``criterion`` unknown or ``"validation"`` without
        ``validation``; a ``method`` or fit option that :func:`jitterid.fit` would refuse
        for every candidate. A single candidate's failure is its row, never an error.

    Examples
    --------
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=2000, noise_std=0.01, rng=2)
    >>> candidates = [jid.RationalModel(0, 1), jid.RationalModel(1, 2)]
    >>> sel = jid.select_order(data, candidates, jid.Uniform(0.05))
    >>> sel.best.label
    'tf:0,1'
    """
    if not isinstance(data, SampledData):
        raise TypeError(
            "data must be a SampledData (see jitterid.simulate, jitterid.load); got "
            f"{type(data).__name__}"
        )
    structures = _check_candidates(candidates)
    if not isinstance(jitter, (JitterLaw, JitterFamily)):
        raise TypeError(
            "jitter must be a jitter law (Uniform(a), Gaussian(sigma), ...) or a family "
            f"(UniformFamily(), ...), the same for every candidate; got {type(jitter).__name__}"
        )
    est = as_estimator(method)  # ValueError naming method, before any fit
    check_method_jitter(est.ignores_jitter, est.name, jitter)  # fit would refuse every one
    est.check_cov_type(fit_kwargs.get("cov_type"))
    if not isinstance(criterion, str) or criterion.lower() not in CRITERIA:
        raise ValueError(f"criterion must be one of {list(CRITERIA)}; got {criterion!r}")
    criterion = criterion.lower()
    if validation is not None and not isinstance(validation, SampledData):
        raise TypeError(
            f"validation must be a SampledData (a second data set); got {type(validation).__name__}"
        )
    if criterion == "validation" and validation is None:
        raise ValueError(
            "criterion 'validation' needs validation data: pass validation=SampledData(...)"
        )
    if validation is not None and structures[0].uses_input and validation.u is None:
        raise ValueError(
            "validation has no input: the candidates are driven by one; give validation.u"
        )
    _check_options(fit_kwargs)
    check_arguments(fit_kwargs.get("noise_std"), fit_kwargs.get("max_nfev", 2000))
    noise_known = fit_kwargs.get("noise_std")
    if noise_known is None:
        noise_known = data.noise_std
    exact = est.exact_likelihood
    rows: list[OrderRow] = []
    counted: list[bool] = []
    for lab, s in zip(_labels(structures), structures, strict=True):
        row, c = _fit_row(lab, data, s, jitter, method, exact, noise_known, validation, fit_kwargs)
        rows.append(row)
        if row.result is not None and math.isfinite(row.loglik):
            counted.append(c)
    # k counts sigma_v the same way in every row: estimated (or plugged in) for one, all.
    noise_counted = any(counted)
    if noise_counted:
        rows = [_with_noise_counted(r, data.N) for r in rows]
    chosen, reason = _choose(rows, criterion)
    tests = _tests(rows) if est.is_likelihood else ()
    return OrderSelection(
        rows=tuple(rows),
        chosen=chosen,
        reason=reason,
        criterion=criterion,
        method=est.name,
        loglik_kind="exact" if exact else "gaussian",
        N=data.N,
        noise_counted=noise_counted,
        tests=tests,
    )


def _with_noise_counted(row: OrderRow, N: int) -> OrderRow:
    """``row`` with sigma_v in k (a row whose fit raised, or did not estimate it, gets it)."""
    res = row.result
    if res is None:
        return replace(row, n_params=row.n_params + 1)
    k = len(res.names) + (0 if "noise_std" in res.names else 1)
    return replace(
        row, n_params=k, aic=-2 * row.loglik + 2 * k, bic=-2 * row.loglik + k * math.log(N)
    )
