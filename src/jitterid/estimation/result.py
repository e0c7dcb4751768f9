"""The immutable result of :func:`jitterid.fit`.

A :class:`FitResult` keeps what it was fitted with (the system structure, the jitter law or
family, the noise model) and its covariance, computed when :func:`~jitterid.fit` returns.
It holds no reference to the data or to the criterion, so it pickles to a few KB, and
:meth:`FitResult.to_json` / :meth:`FitResult.from_json` round-trip it through JSON.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from .. import _serial
from .._checks import count, nesting_depth
from ..data import SampledData
from ..inputs import Input
from ..jitter.laws import JitterFamily, JitterLaw
from ..moments.sample import sample_moments
from ..noise.models import NoiseModel, NoiseStructure
from ..params import ParamLayout
from ..systems.model import Model, Signal
from ..systems.tf import TransferFunction
from .estimators import Estimator, as_estimator
from .hooks import analysis
from .status import FitStatus

__all__ = ["COV_TYPES", "FitResult", "FitStatus"]

FloatArray = NDArray[np.float64]

COV_TYPES = ("sandwich", "robust", "oim", "none")
DISCRETE_METHODS = ("zoh", "foh", "bilinear", "euler", "backward_diff", "impulse")


@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of one estimation, immutable.

    Attributes
    ----------
    method : str
        The estimator's name (``"ls"``, ``"bcls"``, ``"wbcls"``, ``"asml"``,
        ``"asml-diag"``, ``"gaussian"``, ``"ml"``).
    names : tuple of str
        Parameter names in vector order (:class:`jitterid.params.ParamLayout`): jitter-family
        parameters, system parameters, noise-model parameters, then ``noise_std`` if it was
        estimated.
    x : ndarray
        The estimate as a vector in ``names`` order.
    cost : float
        The criterion value at ``x``.
    status : FitStatus
        How the search ended; ``status.value`` says what to do on failure.
    message : str
        The search's own message.
    nfev : int
        Criterion evaluations used by the search (all starts and stages).
    system : TransferFunction or None
        The fitted system G_theta; None for a signal model with no input.
    jitter_law : JitterLaw
        The jitter law: the known one, or the fitted member of the family.
    noise_std : float or None
        The white measurement-noise standard deviation: known, estimated (then also in
        ``params``), or for a criterion that does not use it, its plug-in estimate from the
        residuals that the covariance used; None where no estimate was needed (``ls``).
    freqs : ndarray
        The frequency set (Hz) of the frequency-domain criteria.
    cov : ndarray
        Covariance of ``x`` (see ``cov_type``); NaN rows and columns for parameters on a
        bound, all NaN for ``cov_type="none"``.
    cov_type : str
        ``"sandwich"``: the delta-method covariance H^{-1} G diag(w) G^T H^{-1} with the
        model's sample variances w_k = Var s(kT + tau) + noise_std^2
        (:mod:`jitterid.estimation.covariance`); ``"robust"``: the same with squared
        residuals for w_k (Huber-White; for ``ml``, the sandwich of the per-sample scores),
        honest under a misspecified jitter law; ``"oim"``: the inverse observed
        information (``ml``, ``gaussian``); ``"none"``: not computed.
    structure : Model
        The model fitted: an LTI structure (a known system is a ``KnownSystem``) or a signal
        model.
    jitter_model : JitterLaw or JitterFamily
        The jitter law or family passed to :func:`~jitterid.fit`.
    noise_structure : NoiseStructure or None
        The coloured-noise structure (Box-Jenkins), None for white noise.
    noise_model : NoiseModel or None
        The fitted coloured-noise model, None for white noise.
    estimator : Estimator
        The estimator object that made the fit, with its options (``method`` is its name);
        by default the registered estimator of ``method``.
    layout : ParamLayout
        The parameter layout the search used (blocks, names, bounds); by default rebuilt
        from the structure, jitter model and noise structure.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05))
    >>> res.success, res.names
    (True, ('b0', 'a0'))
    >>> {name: round(value, 1) for name, value in res.params.items()}
    {'b0': 2.0, 'a0': 2.0}
    """

    method: str
    names: tuple[str, ...]
    x: FloatArray
    cost: float
    status: FitStatus
    message: str
    nfev: int
    system: TransferFunction | None
    jitter_law: JitterLaw
    noise_std: float | None
    freqs: FloatArray = field(repr=False)
    cov: FloatArray = field(repr=False)
    cov_type: str
    structure: Model = field(repr=False)
    jitter_model: JitterLaw | JitterFamily = field(repr=False)
    noise_structure: NoiseStructure | None = field(default=None, repr=False)
    noise_model: NoiseModel | None = field(default=None, repr=False)
    estimator: Estimator = field(default=None, repr=False)  # type: ignore[assignment]
    layout: ParamLayout = field(default=None, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.estimator is None:
            object.__setattr__(self, "estimator", as_estimator(self.method))
        if self.layout is None:
            object.__setattr__(
                self,
                "layout",
                ParamLayout.build(
                    self.jitter_model,
                    self.structure,
                    self.noise_structure,
                    noise_std="noise_std" in self.names,
                ),
            )
        x = np.asarray(self.x, float).reshape(-1)
        cov = np.asarray(self.cov, float)
        if cov.shape != (x.size, x.size):
            raise ValueError(f"cov must be {x.size} x {x.size}; got {cov.shape}")
        if self.cov_type not in COV_TYPES:
            raise ValueError(f"cov_type must be one of {COV_TYPES}; got {self.cov_type!r}")
        for a in (x, cov):
            a.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "cov", cov)
        object.__setattr__(self, "names", tuple(self.names))

    # ------------------------------------------------------------------ values
    @property
    def success(self) -> bool:
        return self.status.success

    @property
    def params(self) -> dict[str, float]:
        """``{name: value}``."""
        return {n: float(v) for n, v in zip(self.names, self.x, strict=True)}

    @property
    def stderr(self) -> dict[str, float]:
        """``{name: sqrt(cov[i, i])}``; NaN for a parameter on a bound (see :meth:`summary`)."""
        se = np.sqrt(np.abs(np.diag(self.cov)))
        return {n: float(v) for n, v in zip(self.names, se, strict=True)}

    @property
    def jitter(self) -> JitterLaw:
        """Deprecated alias of :attr:`jitter_law`."""
        warnings.warn(
            "FitResult.jitter is deprecated; use FitResult.jitter_law", DeprecationWarning, 2
        )
        return self.jitter_law

    @property
    def ignored_jitter(self) -> str:
        """Why the jitter law given was not used, or ``""``: a method that ignores the jitter
        (``ls``) fits as if there were none, whatever law it was given, so its estimates carry
        the bias that law causes (the gain seen as |G| |phi(f)|)."""
        given = self.jitter_model
        if isinstance(given, JitterLaw) and given.std > 0 and self.jitter_law.std == 0:
            return (
                f"method {self.method!r} ignores the jitter law given, {given!r}: it fits as if "
                "there were no jitter, so its estimates carry the bias that law causes (the "
                "gain is seen as |G| |phi(f)|); use bcls, asml, gaussian or ml to account for it"
            )
        return ""

    @property
    def jitter_std(self) -> float:
        """Standard deviation of the (fitted) jitter law; for the family (26) it equals
        a / sqrt(3 (n + 1)), the paper's sigma."""
        return float(self.jitter_law.std)

    @property
    def jitter_std_stderr(self) -> float:
        """Standard error of :attr:`jitter_std`, by the delta method through the family.

        With ``g = d std / d theta_j`` (central differences of the law's std as a function of
        the jitter-family parameters, one-sided at a bound) it is ``sqrt(g^T C g)`` with
        ``C`` the jitter block of :attr:`cov`. A jitter parameter without a standard error
        (on or next to its bound, see :attr:`stderr_notes`) is held fixed, as the covariance
        holds it fixed for every other parameter; NaN when no jitter parameter has one
        (``cov_type="none"``). 0.0 for a known law, whose std is not estimated.
        """
        if not isinstance(self.jitter_model, JitterFamily):
            return 0.0
        sl = self.layout.slice("jitter")
        theta = self.x[sl]
        C = self.cov[sl, sl]
        free = np.isfinite(np.diag(C))
        if not free.any():
            return float("nan")
        g = self.jitter_model.std_gradient(theta)[free]
        var = float(g @ C[np.ix_(free, free)] @ g)
        return float(np.sqrt(max(var, 0.0)))

    @property
    def stderr_notes(self) -> dict[str, str]:
        """Why a parameter has no standard error: ``{name: reason}`` for every NaN in
        :attr:`stderr` (empty when all are finite).

        The covariance differentiates the criterion with steps of ``2e-4 max(|x|, 0.01)``
        inside the bounds, so a parameter on its bound, or nearer to it than that step, is
        held fixed: it gets no standard error, and the others' are conditional on it.
        """
        se = self.stderr
        missing = [n for n in self.names if not np.isfinite(se[n])]
        if not missing:
            return {}
        if self.cov_type == "none":
            return {n: "not computed (cov_type='none')" for n in missing}
        lo, hi = self.layout.lower_upper()
        notes: dict[str, str] = {}
        for i, n in enumerate(self.names):
            if n not in missing:
                continue
            v = float(self.x[i])
            step = 2e-4 * max(abs(v), 1e-2)
            if v <= lo[i] or v >= hi[i]:
                b = lo[i] if v <= lo[i] else hi[i]
                notes[n] = (
                    f"on its bound {b:g}: held fixed, so no standard error (the others are "
                    "conditional on it)"
                )
            elif v - step < lo[i] or v + step > hi[i]:  # covariance.py's rule: x +- 2h inside
                b = lo[i] if v - step < lo[i] else hi[i]
                notes[n] = (
                    f"next to its bound {b:g}: held fixed, so no standard error (the others "
                    "are conditional on it)"
                )
            elif (
                isinstance(self.jitter_model, JitterFamily)
                and i < len(self.layout.jitter)
                and i != self.jitter_model.scale_index
                and len(missing) < len(self.names)
            ):
                if self.layout.at_kink(self.x)[i]:
                    notes[n] = (
                        "at a kink of the jitter family (no second derivative there): held "
                        "fixed, so no standard error (the others are conditional on it)"
                    )
                else:
                    notes[n] = (
                        "not identified by the data (the criterion is flat along the family at "
                        "a fixed jitter std): held fixed, so no standard error (the others, "
                        "jitter_std_stderr included, are conditional on it)"
                    )
            else:
                notes[n] = "the information matrix is singular: the parameter is not identified"
        return notes

    def conf_int(
        self, level: float = 0.95, scale: str = "linear"
    ) -> dict[str, tuple[float, float]]:
        """Normal-approximation confidence intervals ``{name: (low, high)}``, never outside
        the parameter's bounds.

        Parameters
        ----------
        level : float
            Coverage, in (0, 1).
        scale : {"linear", "log"}
            ``"linear"`` (default): ``theta +- z se``, then intersected with the parameter's
            bounds. The bounds are the admissible set, which holds the truth, so the cut
            never lowers the coverage: it stays that of the symmetric interval, which the
            library's Monte Carlo tests check. A standard deviation (``noise_std``, a
            jitter scale ``a`` / ``sigma``) or any parameter with a lower bound >= 0
            therefore never gets a negative end: an interval that reached below 0 starts at
            the bound (``1e-12`` for a scale, ``0`` for the shape ``n``), which says that the
            data do not exclude a value near zero. :meth:`conf_int_notes` names the
            parameters cut. ``"log"``: for a parameter with a positive lower bound, the
            delta-method interval of ``ln theta`` mapped back, ``theta exp(+-z se / theta)``
            (positive and asymmetric); the others as ``"linear"``. The log scale covers as
            well where the estimator is nearly unbiased (Table 2's setting with
            ``"gaussian"``: 0.95 for ``noise_std`` over 64 data sets, against 0.94) but
            worse where it is biased (``asml-diag``'s ``noise_std`` there: 0.22 against
            0.41), hence not the default.

        Returns
        -------
        dict of str to (float, float)
            NaN where :attr:`stderr` is NaN (see :attr:`stderr_notes`).
        """
        if not 0 < level < 1:
            raise ValueError(f"level must be in (0, 1); got {level}")
        if scale not in ("linear", "log"):
            raise ValueError(f"scale must be 'linear' or 'log'; got {scale!r}")
        return self._intervals(level, scale)[0]

    def _intervals(
        self, level: float, scale: str
    ) -> tuple[dict[str, tuple[float, float]], list[str]]:
        """The intervals of :meth:`conf_int` and the names of those cut at a bound."""
        z = float(stats.norm.ppf(0.5 + level / 2))
        se = self.stderr
        lo, hi = self.layout.lower_upper() if self.x.size else (np.zeros(0), np.zeros(0))
        out: dict[str, tuple[float, float]] = {}
        cut: list[str] = []
        for i, (n, v) in enumerate(self.params.items()):
            s = se[n]
            if not np.isfinite(s):
                out[n] = (float("nan"), float("nan"))
                continue
            if scale == "log" and lo[i] > 0 and v > 0:
                f = float(np.exp(min(z * s / v, 700.0)))
                a, b = v / f, v * f
            else:
                a, b = v - z * s, v + z * s
            if a < lo[i] or b > hi[i]:
                cut.append(n)
            out[n] = (float(max(a, lo[i])), float(min(b, hi[i])))
        return out, cut

    def conf_int_notes(self, level: float = 0.95) -> dict[str, str]:
        """``{name: note}`` for the parameters whose :meth:`conf_int` at ``level`` is cut at
        a bound (e.g. a standard deviation whose symmetric interval would reach below 0).

        Parameters
        ----------
        level : float
            Coverage, in (0, 1).
        """
        if not 0 < level < 1:
            raise ValueError(f"level must be in (0, 1); got {level}")
        if not self.x.size:
            return {}
        ci, cut = self._intervals(level, "linear")
        lo, hi = self.layout.lower_upper()
        notes: dict[str, str] = {}
        for n in cut:
            i = self.names.index(n)
            ends = [b for b, at in ((lo[i], ci[n][0] == lo[i]), (hi[i], ci[n][1] == hi[i])) if at]
            where = " and ".join(f"{b:g}" for b in ends)
            notes[n] = (
                f"interval cut at its bound {where}: the symmetric interval leaves the admissible "
                "set, so the data do not exclude the bound"
            )
        return notes

    # ------------------------------------------------------------------ the model's output
    def _check_data(self, data: SampledData) -> None:
        if not isinstance(data, SampledData):
            raise TypeError(
                f"data must be a SampledData (see jitterid.simulate, jitterid.load); got "
                f"{type(data).__name__}"
            )

    def signal(self, u: Input | None = None) -> Signal:
        """The fitted signal s(t; theta) (:class:`jitterid.systems.model.Signal`): the fitted
        system's response to the input ``u``, or the fitted signal model (``u`` unused).

        Parameters
        ----------
        u : Input, optional
            The input; not needed for a signal model.
        """
        if self.system is not None:
            if u is None:
                raise ValueError("u: the fitted system is driven by an input; give the input")
            return self.system.response(u)
        return self.structure.signal(self.layout.block(self.x, "system"), u)

    def predict(self, data: SampledData) -> FloatArray:
        """E y_k = E s(kT + tau) under the fitted model and jitter law, for ``data``'s input
        and grid (Lemma 1 in the time domain).

        Parameters
        ----------
        data : SampledData
            The data whose input and sampling grid to use.
        """
        self._check_data(data)
        mom = sample_moments(self.signal(data.u), self.jitter_law, data.T, data.N)
        return np.asarray(mom.mean, dtype=float)

    def residuals(self, data: SampledData) -> FloatArray:
        """y_k - E y_k for ``data`` (see :meth:`predict`).

        Parameters
        ----------
        data : SampledData
            The measured data.
        """
        return np.asarray(data.y - self.predict(data), dtype=float)

    def bode_band(self, f_hz: Any, level: float = 0.95, **kwargs: Any) -> Any:
        """Bode magnitude and phase with pointwise confidence bands at ``f_hz`` (Hz); see
        :func:`jitterid.bode_band` for the options.

        Parameters
        ----------
        f_hz : array_like
            Frequencies in Hz.
        level : float, optional
            Coverage of the band, in (0, 1).
        **kwargs
            Further options of :func:`jitterid.bode_band`.
        """
        bode_band = analysis("bode_band")

        return bode_band(self, f_hz, level, **kwargs)

    def jitter_pdf_band(self, tau_s: Any, rng: Any, **kwargs: Any) -> Any:
        """The fitted jitter density at ``tau_s`` (s) with a pointwise band; see
        :func:`jitterid.jitter_pdf_band`.

        Parameters
        ----------
        tau_s : array_like
            Jitter values in s.
        rng : numpy.random.Generator or int
            Source of randomness for the parameter draws.
        **kwargs
            Further options of :func:`jitterid.jitter_pdf_band`.
        """
        jitter_pdf_band = analysis("jitter_pdf_band")

        return jitter_pdf_band(self, tau_s, rng, **kwargs)

    def physical_quantities(self, level: float = 0.95, **kwargs: Any) -> Any:
        """Poles, zeros, DC gain, time constants (s), natural frequencies (Hz), damping ratios
        and the -3 dB bandwidth (Hz) with intervals; see :func:`jitterid.physical_quantities`
        for the options (``method="delta"`` or ``"sampling"``, ``draws``, ``rng``).

        Parameters
        ----------
        level : float, optional
            Coverage of the band, in (0, 1).
        **kwargs
            Further options of :func:`jitterid.physical_quantities`.
        """
        physical_quantities = analysis("physical_quantities")

        return physical_quantities(self, level, **kwargs)

    def step_response(self, t_s: Any, level: float = 0.95, **kwargs: Any) -> Any:
        """The unit-step response at ``t_s`` (s) with a pointwise band; see
        :func:`jitterid.step_response`.

        Parameters
        ----------
        t_s : array_like
            Times in s.
        level : float, optional
            Coverage of the band, in (0, 1).
        **kwargs
            Further options of :func:`jitterid.step_response`.
        """
        step_response = analysis("step_response")

        return step_response(self, t_s, level, **kwargs)

    def impulse_response(self, t_s: Any, level: float = 0.95, **kwargs: Any) -> Any:
        """The impulse response at ``t_s`` (s) with a pointwise band; see
        :func:`jitterid.impulse_response`.

        Parameters
        ----------
        t_s : array_like
            Times in s.
        level : float, optional
            Coverage of the band, in (0, 1).
        **kwargs
            Further options of :func:`jitterid.impulse_response`.
        """
        impulse_response = analysis("impulse_response")

        return impulse_response(self, t_s, level, **kwargs)

    # ------------------------------------------------------------------ reports
    def summary(self) -> str:
        """A readable table of the estimate.

        Intervals are :meth:`conf_int`'s at 95%: symmetric and cut at the parameter's
        bounds, so a standard deviation's never goes negative; a line under the table names
        every interval cut (:meth:`conf_int_notes`) and every parameter without a standard
        error, with the reason (:attr:`stderr_notes`). The jitter law's std is given with its
        standard error (:attr:`jitter_std_stderr`).
        """
        ci = self.conf_int()
        se = self.stderr
        lines = [
            f"jitterid fit, method {self.method!r}: {self.status.value}",
            f"  search: {self.message} ({self.nfev} evaluations), criterion {self.cost:.6g}",
            f"  covariance: {self.cov_type}",
            f"  {'parameter':<10} {'estimate':>12} {'std err':>12} {'95% interval':>27}",
        ]
        for n, v in self.params.items():
            lines.append(
                f"  {n:<10} {v:>12.6g} {se[n]:>12.4g}   [{ci[n][0]:>11.5g}, {ci[n][1]:>11.5g}]"
            )
        lines += [f"  {n}: {why}" for n, why in self.conf_int_notes().items()]
        if self.cov_type != "none":
            lines += [f"  {n}: {why}" for n, why in self.stderr_notes.items()]
        if isinstance(self.jitter_model, JitterFamily):
            sd = f"std {self.jitter_std:.4g} ± {self.jitter_std_stderr:.2g}"
        else:
            sd = f"std {self.jitter_std:.4g}, known"
        lines.append(f"  jitter law {self.jitter_law}  ({sd})")
        ignored = self.ignored_jitter
        if ignored:
            lines.append(f"  note: {ignored}")
        fixed = getattr(self.structure, "fixed", None)
        if fixed:  # a Constrained structure: values held, not estimated
            lines.append(
                "  fixed (not estimated): " + ", ".join(f"{k} = {v:.6g}" for k, v in fixed.items())
            )
        if self.system is not None:
            lines.append(f"  system {self.system}")
            if getattr(self.structure, "delay_index", None) is not None:
                lines.append(
                    "  delay_s is estimated with the jitter's mean held at "
                    f"{self.jitter_law.mean:.4g} "
                    "s: the samples identify only delay_s - mean jitter "
                    f"= {self.system.delay_s - self.jitter_law.mean:.4g} s"
                )
        else:
            lines.append(f"  signal model {type(self.structure).__name__}")
        if self.system is not None:
            lines += self._quantities_lines()
        if self.noise_model is not None:
            lines.append(f"  noise model {self.noise_model}")
        if self.noise_std is None:
            lines.append("  noise std: not used")
        else:
            how = "estimated" if "noise_std" in self.names else "given, or the residuals' plug-in"
            lines.append(f"  noise std {self.noise_std:.4g} ({how})")
        return "\n".join(lines)

    def _quantities_lines(self) -> list[str]:
        """The physical-quantities table of :meth:`summary`, indented; one line saying why
        where it cannot be computed (summary() never raises)."""
        try:
            table = self.physical_quantities()
            return ["  " + line for line in table.summary().splitlines()]
        except Exception as exc:  # noqa: BLE001 - summary() never fails for a derived table
            why = " ".join(str(exc).split()) or type(exc).__name__
            return [f"  physical quantities: skipped ({why})"]

    def __str__(self) -> str:
        return self.summary()

    # ------------------------------------------------------------------ export
    def to_scipy(self, pade_order: int | None = None) -> Any:
        """The fitted G(s) as a ``scipy.signal.lti`` (transfer-function form; s in rad/s).

        Parameters
        ----------
        pade_order : int, optional
            For a fit with an input-output delay (:class:`jitterid.Delayed`), which scipy's
            ``lti`` cannot hold: the order of the Pade approximation of e^{-s delay_s}
            multiplied in. Without it such a fit is refused (``result.system.undelayed``
            is the rational part alone).
        """
        from scipy import signal

        return signal.lti(*self._rational(pade_order))

    def _rational(self, pade_order: int | None) -> tuple[FloatArray, FloatArray]:
        """(num, den) of the fitted G, its delay replaced by a Pade approximation."""
        tf = self._transfer_function()
        if not tf.delay_s:
            return np.asarray(tf.num, float), np.asarray(tf.den, float)
        if pade_order is None:
            raise ValueError(
                f"the fitted G has an input-output delay of {tf.delay_s:g} s, which a rational "
                "transfer function cannot hold: pass pade_order (e.g. 3) for a Pade "
                "approximation of the delay, or export result.system.undelayed (the rational "
                "part) and add the delay in your tool"
            )
        n = count(pade_order, "pade_order", minimum=1)
        # Pade [n/n] of e^{-x}: q(x) = sum_k c_k x^k, c_k = (2n - k)! n! / ((2n)! k! (n - k)!),
        # e^{-x} ~ q(-x) / q(x), with x = s delay_s (coefficients highest power first).
        c = np.array(
            [
                math.factorial(2 * n - k)
                * math.factorial(n)
                / (math.factorial(2 * n) * math.factorial(k) * math.factorial(n - k))
                * tf.delay_s**k
                for k in range(n, -1, -1)
            ]
        )
        sign = (-1.0) ** np.arange(n, -1, -1)
        return np.polymul(tf.num, sign * c), np.polymul(tf.den, c)

    def to_control(self, pade_order: int | None = None) -> Any:
        """The fitted G(s) as a python-control ``TransferFunction`` (s in rad/s).

        Needs the optional extra: ``pip install 'jitterid[control]'``. A delay needs
        ``pade_order``, as in :meth:`to_scipy`.

        Parameters
        ----------
        pade_order : int, optional
            Order of the Pade approximation of a delay; required when the model has one.
        """
        try:
            import control
        except ImportError as exc:
            raise ImportError(
                "to_control() needs python-control, an optional dependency; install it with "
                "pip install 'jitterid[control]' (or pip install control)"
            ) from exc
        num, den = self._rational(pade_order)
        return control.tf(num.tolist(), den.tolist())

    def to_discrete(self, T: float, method: str = "zoh") -> Any:
        """The fitted G(s) discretised with sampling interval ``T`` (s), as a
        ``scipy.signal.dlti`` (transfer-function form in z, ``dt = T``), through
        ``scipy.signal.cont2discrete``.

        Parameters
        ----------
        T : float
            Sampling interval (s) in s, > 0.
        method : str
            ``"zoh"`` (default: the input held between samples, exact for a
            piecewise-constant input switching at multiples of T), ``"foh"``,
            ``"bilinear"`` (Tustin), ``"euler"``, ``"backward_diff"`` or ``"impulse"``.
        """
        from scipy import signal

        tf = self._transfer_function()
        if isinstance(T, bool) or not isinstance(T, (int, float, np.integer, np.floating)):
            raise TypeError(f"T must be the sampling interval in s, a number; got {T!r}")
        if not (math.isfinite(float(T)) and float(T) > 0):
            raise ValueError(f"T must be the sampling interval in s, finite and > 0; got {T!r}")
        if method not in DISCRETE_METHODS:
            raise ValueError(f"method must be one of {DISCRETE_METHODS}; got {method!r}")
        # A delay of m whole periods is z^-m, exactly; a fraction of a period is refused
        # (its exact hold equivalent needs the modified z-transform).
        m = tf.delay_s / float(T)
        if abs(m - round(m)) > 1e-9 * max(1.0, abs(m)) or m < 0:
            raise ValueError(
                f"the fitted delay {tf.delay_s:g} s is not a whole number of periods T = {T!r} "
                "s: choose a T that divides it, or discretise result.system.undelayed and "
                "add the delay in your tool"
            )
        numd, dend, _ = signal.cont2discrete((tf.num, tf.den), float(T), method=method)
        dend = np.r_[np.ravel(dend), np.zeros(round(m))]
        num = np.ravel(numd)
        # A strictly proper G gives a ZOH numerator whose leading coefficient is 0 up to
        # rounding; drop such leading terms (relative 1e-12) as scipy would, but silently.
        big = float(np.max(np.abs(num))) if num.size else 0.0
        lead = int(np.argmax(np.abs(num) > 1e-12 * big)) if big > 0 else num.size - 1
        return signal.dlti(num[lead:], np.ravel(dend), dt=float(T))

    def _transfer_function(self) -> TransferFunction:
        if self.system is None:
            raise ValueError(
                f"this fit is of a signal model ({type(self.structure).__name__}), which has no "
                "transfer function to export; use params and predict()"
            )
        return self.system

    def to_dict(self) -> dict[str, Any]:
        """Every field as JSON-compatible values (the inverse is :meth:`from_dict`)."""
        out: dict[str, Any] = {}
        for name in self.__dataclass_fields__:
            v = getattr(self, name)
            if name == "estimator" and not type(v).__module__.startswith("jitterid."):
                v = None  # a user's estimator class: by name (method) only
            out[name] = v.name if isinstance(v, FitStatus) else _serial.encode(v)
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FitResult:
        """A FitResult from :meth:`to_dict`'s output.

        Parameters
        ----------
        d : dict
            The dictionary :meth:`to_dict` returned (e.g. after a JSON round trip).

        Raises
        ------
        ValueError
            ``d`` is not such a dictionary: not a mapping, a field missing or unknown, a
            value of the wrong kind, or a class that is not one of jitterid's value objects.
        """
        if not isinstance(d, dict):
            raise TypeError(
                f"d must be the dictionary FitResult.to_dict() writes; got {type(d).__name__}"
            )
        fields = {f.name: f for f in dataclasses.fields(cls)}
        required = [
            n
            for n, f in fields.items()
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        ]
        missing = [n for n in required if n not in d]
        unknown = sorted(str(k) for k in d if k not in fields)
        if missing or unknown:
            raise ValueError(
                "not a FitResult: "
                + "; ".join(
                    (["missing field(s) " + ", ".join(missing)] if missing else [])
                    + (["unknown field(s) " + ", ".join(unknown)] if unknown else [])
                )
            )
        kw = {k: _serial.decode(v) for k, v in d.items()}
        status = d["status"]
        if not (isinstance(status, str) and status in FitStatus.__members__):
            raise ValueError(f"status must be one of {[s.name for s in FitStatus]}; got {status!r}")
        kw["status"] = FitStatus[status]
        kinds: dict[str, tuple[type, ...]] = {
            "structure": (Model,),
            "jitter_model": (JitterLaw, JitterFamily),
            "jitter_law": (JitterLaw,),
            "system": (TransferFunction, type(None)),
            "noise_structure": (NoiseStructure, type(None)),
            "noise_model": (NoiseModel, type(None)),
            "method": (str,),
            "cov_type": (str,),
            "message": (str,),
            "names": (list, tuple),
        }
        for k, kind in kinds.items():
            if k in kw and not isinstance(kw[k], kind):
                raise ValueError(
                    f"not a FitResult: {k} must be a {' or '.join(t.__name__ for t in kind)}; "
                    f"got {type(kw[k]).__name__}"
                )
        try:
            for k in ("x", "freqs"):
                kw[k] = np.asarray(kw[k], float)
            kw["cov"] = np.asarray(kw["cov"], float).reshape(len(kw["x"]), len(kw["x"]))
            return cls(**kw)
        except (TypeError, ValueError, AttributeError, IndexError) as exc:
            raise ValueError(f"not a FitResult: {exc}") from None

    def to_json(self) -> str:
        """The result as a JSON string (:meth:`from_json` reads it back)."""
        return json.dumps(self.to_dict())

    @classmethod
    def from_json(cls, text: str) -> FitResult:
        """A FitResult from :meth:`to_json`'s output.

        Parameters
        ----------
        text : str
            The JSON text :meth:`to_json` returned.

        Raises
        ------
        ValueError
            ``text`` is not JSON (``json.JSONDecodeError``), is nested more deeply than a
            result can be, or is not a result (see :meth:`from_dict`).
        """
        if not isinstance(text, (str, bytes, bytearray)):
            raise TypeError(f"text must be the JSON to_json() wrote; got {type(text).__name__}")
        plain = text if isinstance(text, str) else text.decode("utf-8", "replace")
        if nesting_depth(plain) > _serial.MAX_DEPTH:
            raise ValueError(
                f"not a FitResult: the JSON is nested more than {_serial.MAX_DEPTH} levels deep"
            )
        d = json.loads(plain)
        if isinstance(d, dict):
            return cls.from_dict(d)
        raise ValueError(
            f"not a FitResult: the JSON holds {type(d).__name__}, not the object to_json() writes"
        )
