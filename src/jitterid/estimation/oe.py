"""The white-noise route of :func:`jitterid.fit`: OE (2a) and JOE (2c), every estimator,
the exact likelihood included (:mod:`jitterid.estimation.route` lists the hooks).

The search follows Section 4.5: an ordinary output-error fit that ignores the jitter gives
the system's starting point; for a free jitter law a small grid of starting values is tried
with the estimator's first stage (:meth:`Estimator.first_stage`, BCLS for the paper's
second-stage estimators), whose estimate starts the estimator itself. Each search goes
through the estimator's adapter (:func:`jitterid.estimation.search.run_search`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .._checks import real_array
from ..data import SampledData
from ..jitter.laws import JitterFamily, JitterLaw, NoJitter
from ..params import count_params
from ..systems.model import Model
from ..systems.structures import ModelStructure
from .checks import (
    SCREEN_SAMPLES,
    PostContext,
    Scaling,
    check_data,
    check_method_jitter,
    lowest_below,
)
from .covariance import covariance, noise_variance_ml
from .estimators import LS, Estimator
from .problem import Problem, default_frequencies, free_moment_plans
from .resources import check_fit as check_fit_resources
from .result import FitResult
from .route import Staged
from .search import Outcome, Walks, criterion_or_inf, run_search
from .status import FitStatus

__all__ = ["OutputErrorRoute", "noise_from_residuals"]

FloatArray = NDArray[np.float64]
_BAD = 1e10  # residual returned where the model cannot be evaluated (e.g. unstable)
#: a search from a given start that ended so is restarted (OutputErrorRoute._restart)
_STOPPED = (FitStatus.OPTIMISER_FAILED, FitStatus.NOT_FINITE, FitStatus.MAX_EVALUATIONS)


def _oe_start(data: SampledData, structure: Model) -> tuple[FloatArray, float]:
    """Ordinary output-error fit ignoring jitter (time domain); returns (theta, rms residual)."""
    t = data.t_nominal
    if not structure.param_names:
        r0 = data.y - structure.signal((), data.u)(t)
        return np.zeros(0), float(np.sqrt(np.mean(r0**2)))

    # The samples at kT are the moments of a point-mass jitter: the same O(N) path and
    # analytic Jacobian as the jitter-aware criteria (jitterid.estimation.jacobians).
    oe = Problem(data, structure, NoJitter(), LS(), default_frequencies(data.N, data.T), None)

    def resid(x: FloatArray) -> FloatArray:
        try:
            return data.y - oe.derivatives(x)[0].mean  # with the Jacobian: one pass
        except ValueError:
            return np.full(data.N, _BAD)

    def jac(x: FloatArray) -> FloatArray:
        try:
            return -oe.derivatives(x)[2].T
        except ValueError:  # only where resid failed too; such a step is never taken
            return np.zeros((data.N, x.size))

    lo, hi = np.array(structure.bounds).T
    # Score every start by one evaluation; search from the best only (a start with the
    # right time scale is what matters, and each full search costs ~30 evaluations).
    gains = list(structure.gain_params)
    scored = []
    for x0 in structure.initial_points(data):
        x0 = np.clip(x0, lo, hi)
        try:
            s = oe.moments(x0).mean
        except ValueError:  # e.g. unstable: last resort only
            scored.append((np.inf, x0))
            continue
        if gains and np.dot(s, s) > 0:  # give each start its least-squares gain
            # s is linear in the gain parameters: the scaled start's output is c s
            c = np.dot(data.y, s) / np.dot(s, s)
            scaled = x0.copy()
            scaled[gains] *= c
            if np.all((scaled >= lo) & (scaled <= hi)):  # a bounded gain keeps its start
                x0, s = scaled, c * s
        scored.append((float(np.sum((data.y - s) ** 2)), x0))
    x0 = min(scored, key=lambda item: item[0])[1]
    sol = least_squares(resid, x0, jac=jac, bounds=(lo, hi), x_scale="jac", max_nfev=200)
    return sol.x, float(np.sqrt(2 * sol.cost / data.N))


def noise_from_residuals(first: Problem, x: FloatArray) -> float:
    """Plug-in sigma_v from a first-stage (BCLS) fit: E|Y - mu|^2 = R(f, f) =
    sum_k Var s_k + N sigma_v^2 (notes 2)."""
    r = first.residuals(x)
    power = float(np.sum(r**2)) / first.freqs.size
    signal_var = float(np.sum(first.moments(x).var))
    return float(np.sqrt(max(power - signal_var, 1e-12 * power) / first.data.N))


def _best_scored(problem: Problem, starts: Sequence[FloatArray]) -> list[FloatArray]:
    """Of the starts at each value of the jitter family's scale, the one with the lowest
    criterion (one evaluation each; the first of the group where none can be evaluated):
    the first stage's starts where it only starts another estimator's search (Table 1,
    BCLS from the best-scored start per scale against all six: within 1e-9 in 22 of 24
    fits, 0.04 % higher in the others)."""
    scale = getattr(problem.jitter, "scale_index", None)
    values = [criterion_or_inf(problem, x) for x in starts]
    groups: dict[float, list[int]] = {}
    for k, x in enumerate(starts):
        groups.setdefault(float(x[scale]) if scale is not None else 0.0, []).append(k)
    return [starts[min(ks, key=lambda k: (values[k], k))] for ks in groups.values()]


def _off_zero_jitter(
    problem: Problem, x0: FloatArray, jstarts: Sequence[Sequence[float]]
) -> tuple[FloatArray, int]:
    """The Newton-searched criteria are even in a jitter family's scale, so their gradient
    vanishes where the BCLS stage collapsed the scale onto zero (its boundary minimum): a
    search from there never leaves. In that case each of the family's default starts (with
    the BCLS system) is scored by one criterion value and the best start searched. Elsewhere
    the BCLS point is kept as it is. Returns the start and the evaluations used."""
    jitter = problem.jitter
    scale = getattr(jitter, "scale_index", None)
    lay = problem.layout
    if not lay.jitter or scale is None or x0[scale] >= 1e-3 * problem.data.T:
        return x0, 0
    lo, hi = lay.lower_upper()
    best, best_v, n = x0, np.inf, 0
    for cand in [x0] + [lay.replace(x0, "jitter", js) for js in jstarts]:
        cand = np.clip(cand, lo, hi)
        n += 1
        try:
            v = problem.objective(cand)
        except ValueError:
            continue
        if np.isfinite(v) and v < best_v:
            best, best_v = cand, v
    return best, n


class OutputErrorRoute:
    """White measurement noise: the problem is :class:`~jitterid.estimation.problem
    .Problem` (module docstring)."""

    def __init__(
        self,
        data: SampledData,
        structure: Model,
        jitter: JitterLaw | JitterFamily,
        estimator: Estimator,
        *,
        freqs: ArrayLike | None,
        noise_std: float | None,
        max_nfev: int,
        restart: bool = True,
    ) -> None:
        est = estimator
        self.restart = restart
        check_method_jitter(est.ignores_jitter, est.name, jitter)
        if est.ignores_jitter and not structure.param_names:
            raise ValueError(f"method {est.name!r} with a known system has nothing to estimate")
        n_jit = count_params(jitter)
        check_data(data, n_jit + len(structure.param_names), structure.uses_input, jitter)
        check_fit_resources(data, structure, jitter, est)  # memory up front (resources.py)
        f = (
            default_frequencies(data.N, data.T)
            if freqs is None
            else np.atleast_1d(real_array(freqs, "freqs"))
        )
        if f.size < 1:
            raise ValueError("freqs must hold at least one frequency")
        noise = data.noise_std if noise_std is None else noise_std
        if est.exact_likelihood and noise is not None and not noise > 0:
            raise ValueError(
                f"method {est.name!r} needs measurement noise: the exact likelihood of "
                f"noise-free samples is singular (noise_std = {noise!r}); pass a positive "
                "noise_std"
            )
        # The search runs on y / sy and u / su (powers of two near their rms; checks.Scaling)
        # so that the optimisers' absolute tolerances do not depend on the data's units;
        # every parameter, the criterion and the covariance map back exactly.
        self.orig = data
        self.scaling = Scaling.build(data, structure, n_jit)
        self.data = self.scaling.data(data)
        self.structure = structure
        self.jitter = jitter
        self.estimator = est
        self.freqs = f
        self.max_nfev = max_nfev
        # the user's noise std in the search's units (a plug-in may replace it, search())
        self.given_noise = None if noise is None else noise / self.scaling.sy
        self.jstarts: Sequence[Sequence[float]] = (
            jitter.default_starts(self.data.T) if isinstance(jitter, JitterFamily) else [()]
        )
        self._oe: tuple[FloatArray, float] | None = None  # the ordinary OE fit, once

    # ------------------------------------------------------------------ helpers
    def make(
        self, est: Estimator, noise_std: float | None, weights_at: FloatArray | None = None
    ) -> Problem:
        return Problem(
            self.data,
            self.structure,
            self.jitter,
            est,
            self.freqs,
            noise_std,
            weights_at=weights_at,
        )

    def oe(self) -> tuple[FloatArray, float]:
        """The ordinary output-error fit (theta, rms residual), computed once."""
        if self._oe is None:
            self._oe = _oe_start(self.data, self.structure)
        return self._oe

    def _plugin_noise(self, first: Estimator) -> float:
        pre = self.make(first, None)
        _, out = run_search(
            pre, np.r_[np.asarray(self.jstarts[0], float), self.oe()[0]], self.max_nfev
        )
        return noise_from_residuals(pre, out.x)

    # ------------------------------------------------------------------ 1. starts, search
    def search(self, start: ArrayLike | FitResult | None) -> Staged:
        """The starts of Section 4.5 and the search (``start``: a vector in the result's
        ``names`` order, a first-stage FitResult, or None)."""
        est, first = self.estimator, self.estimator.first_stage()
        single = first is est  # its own first stage (ls, bcls)
        # a criterion that needs the noise variance but cannot estimate it (wbcls) plugs in
        # the first stage's estimate when none is given
        plug = est.needs_noise and not est.estimates_noise
        noise = self.given_noise
        max_nfev = self.max_nfev
        prefit = start if isinstance(start, FitResult) else None
        vector = None if isinstance(start, FitResult) else start
        nfev = 0
        rms: float | None = None
        compared = False
        if vector is not None:
            if plug and noise is None:
                noise = self._plugin_noise(first)
            problem = self.make(est, noise if est.needs_noise else None)
            x0 = np.atleast_1d(real_array(vector, "start"))
            if x0.size != len(problem.names):
                raise ValueError(
                    f"start must have {len(problem.names)} values {problem.names}; got {x0.size}"
                )
            x0 = self.scaling.to_scaled(x0)
            problem, best = run_search(problem, x0, max_nfev)
            nfev = best.nfev
            lower = None
            # (fit's restart=False: the search's end as it is, no comparison, no restart)
            if (
                self.restart
                and best.status is FitStatus.CONVERGED
                and self._defaults_apply(problem)
            ):
                lower, n = self._lower_default(problem, best)
                nfev += n
                # (none lower: the post-search check need not evaluate them again)
                compared = lower is None
                if lower is not None:
                    # the search again from the lower point first: a stationary point that
                    # is not a maximum (a scale mixture's rho = 0, where the likelihood,
                    # even in rho, has no slope) is left from there, where the restart's
                    # first stage may have nothing to tell (a tone's bcls collapses its
                    # jitter, and the likelihood's step from there went to the scale's
                    # bound: 3 GB and over 7 CPU-min on a 1024-sample record)
                    again, n = self._from_lower_default(problem, best, "the given start")
                    nfev += n
                    if again.status is FitStatus.CONVERGED and again.cost < best.cost:
                        best, lower = again, None
            if self.restart and (best.status in _STOPPED or lower is not None):
                problem, best, n = self._restart(problem, best, x0, noise)
                nfev += n
        else:
            pre = self.make(first, None)
            found: Outcome | None = None
            if prefit is not None:
                _check_prefit(
                    prefit,
                    pre
                    if self.scaling.identity
                    else Problem(self.orig, self.structure, self.jitter, first, self.freqs, None),
                )
                found = Outcome(
                    self.scaling.to_scaled(prefit.x),
                    prefit.cost,
                    prefit.status,
                    prefit.message,
                    prefit.nfev,
                )
                nfev = prefit.nfev
            else:
                theta_sys, rms = self.oe()
                starts = [np.r_[np.asarray(js, float), theta_sys] for js in self.jstarts]
                held = None
                kinked = pre.layout.kinked()
                if len(starts) > 1 and kinked and not single:
                    # A family with kinks is searched piece by piece, the shape scanned
                    # over its kinks from where each search stops (search.piecewise). As
                    # the estimate itself (bcls) every start is, the criterion being
                    # multimodal in the shape. As the start of another estimator's search,
                    # one start per scale is (_best_scored), with the kinked shape held at
                    # the start's: the first stage's criterion is all but flat in it (BCLS
                    # ends anywhere in n), the second stage scans it anyway, and a walk
                    # over its pieces cost the first stage 40-50 evaluations a start
                    starts = _best_scored(pre, starts)
                    nfev += len(self.jstarts)
                    held = np.ones(len(pre.names), bool)
                    held[list(kinked)] = False
                free = held if held is not None else np.ones(len(pre.names), bool)
                walks = Walks()  # (walks that meet end alike: search.Walks)
                for x_start in starts:
                    with pre.pinned(x_start, free):  # (a held shape: its derivatives not made)
                        _, out = run_search(pre, x_start, max_nfev, free=held, walks=walks)
                    nfev += out.nfev
                    if found is None or out.cost < found.cost:
                        found = out
            assert found is not None
            best = found
            problem = pre
            if not single:
                if plug and noise is None:
                    noise = noise_from_residuals(pre, best.x)
                problem, best, n = self._second_stage(pre, best.x, noise, rms)
                nfev += n
                # (a family's second stage compared its end with the default starts)
                compared = len(self.jstarts) > 1
        return Staged(
            problem,
            best._replace(nfev=nfev),
            noise,
            {"single": single, "start": start, "prefit": prefit, "compared": compared},
        )

    def _second_stage(
        self, pre: Problem, x_pre: FloatArray, noise: float | None, rms: float | None
    ) -> tuple[Problem, Outcome, int]:
        """The estimator searched from the first stage's estimate ``x_pre`` (Section 4.5):
        an estimated noise std starts where :meth:`Estimator.noise_start` says, and a
        criterion searched by Newton steps is moved off a jitter scale collapsed onto zero
        (:func:`_off_zero_jitter`). Returns the problem, the outcome and the evaluations
        used (the scored starts included)."""
        est = self.estimator
        problem = self.make(est, noise if est.needs_noise else None)
        if problem.estimates_noise:
            if rms is None:
                rms = self.oe()[1]
            noise0 = est.noise_start(rms, lambda: noise_from_residuals(pre, x_pre))
            x0 = np.r_[x_pre, noise0]
        else:
            x0 = x_pre
        nfev = 0
        if not est.least_squares and not est.scores_own_starts:
            x0, nfev = _off_zero_jitter(problem, x0, self.jstarts)
        problem, best = run_search(problem, x0, self.max_nfev)
        nfev += best.nfev
        if len(self.jstarts) > 1 and best.status is FitStatus.CONVERGED:
            best, n = self._from_lower_default(problem, best)
            nfev += n
        return problem, best, nfev

    def default_starts(self, problem: Problem) -> list[FloatArray]:
        """The default starts of Section 4.5 in ``problem``'s layout (search units): each of
        the jitter starts with the ordinary output-error system (and its rms residual as the
        noise std where the criterion estimates it), inside the bounds."""
        th, rms = self.oe()
        out = [np.r_[np.asarray(js, float), th] for js in self.jstarts]
        if problem.estimates_noise:
            out = [np.r_[v, max(rms, 1e-6)] for v in out]
        lo, hi = problem.layout.lower_upper()
        return [np.clip(v, lo, hi) for v in out]

    def _defaults_apply(self, problem: Problem) -> bool:
        """Whether the default starts are points of ``problem`` to compare an end with (not
        where there are no parameters, nor one empty start: a known law with a known
        system)."""
        return bool(problem.names) and (bool(self.structure.param_names) or len(self.jstarts) > 1)

    def _shape_starts(self, problem: Problem, x: FloatArray) -> list[FloatArray]:
        """Each default start's jitter shape at the jitter std of ``x``, with x's system and
        noise std, inside the bounds (those that differ from x): a jitter family's modes at
        the std the data fix. Table 1, case 2, realization 88: the exact Gaussian criterion's
        walk from the BCLS estimate ended at n = 1.19, a = 0.437; at n = 0 and the same std
        (a = 0.295) the criterion is 3.5 lower, and the default starts themselves ((0, 0.25),
        (0, 0.5), ...) are higher than the end."""
        fam = problem.jitter
        if not isinstance(fam, JitterFamily) or fam.scale_index is None:
            return []
        lay = problem.layout
        lo, hi = lay.lower_upper()
        out: list[FloatArray] = []
        try:
            std = fam.law(lay.block(x, "jitter").tolist()).std
            for js in self.jstarts:
                shape = fam.at_std(np.asarray(js, float), std)
                cand = np.clip(lay.replace(x, "jitter", shape), lo, hi)
                if not any(np.allclose(cand, c, rtol=1e-9, atol=0) for c in [x, *out]):
                    out.append(cand)
        except ValueError:
            return out
        return out

    def _lower_default(
        self, problem: Problem, best: Outcome
    ) -> tuple[tuple[float, FloatArray, str] | None, int]:
        """The default start, or default start's shape at the end's jitter std
        (:meth:`_shape_starts`), with the lowest criterion where that is lower than at
        ``best`` (one evaluation each; on a long record a start clearly worse on its leading
        samples is not evaluated in full): (criterion, point, label), else None; and the
        evaluations used."""
        starts = self.default_starts(problem)
        points = starts + self._shape_starts(problem, best.x)
        j, v, n = lowest_below(points, problem.criterion_at, best.x, best.cost, _screen(problem))
        if j is None:
            return None, n
        label = "the default start" if j < len(starts) else "a default start's shape at its std"
        return (v, points[j], label), n

    def _from_lower_default(
        self, problem: Problem, best: Outcome, origin: str = "the first stage's estimate"
    ) -> tuple[Outcome, int]:
        """A jitter family's second stage searched from one start (the first stage's
        estimate): where the criterion at a default start (:meth:`_lower_default`) is lower
        than at the search's end, the search again from the lowest, its end kept where lower
        (with the message saying so). A criterion multimodal in the family's shape at
        different jitter stds (Table 1, the exact Gaussian criterion: n = 2.3 with a on its
        bound T/2 against n = 0 at a std 9 % lower, -2 ln L 3.6 apart) has modes that the
        walk's scan at a fixed std does not connect: the default starts are the multi-start
        that the first stage ran. ``origin``: where the search started, for the message.
        Returns the outcome and the evaluations used."""
        lowest, n = self._lower_default(problem, best)
        if lowest is None:
            return best, n
        _, again = run_search(problem, lowest[1], self.max_nfev)
        n += again.nfev
        if not again.cost < best.cost:
            return best, n
        start = np.round(lowest[1], 6).tolist()
        return again._replace(
            message=(
                f"{again.message} (searched again from {lowest[2]} {start}, in the "
                f"search's units, where the criterion was lower than at the end of the search "
                f"from {origin}: {best.cost:.6g} there, {best.message})"
            )
        ), n

    def _restart(
        self, problem: Problem, failed: Outcome, x0: FloatArray, noise: float | None
    ) -> tuple[Problem, Outcome, int]:
        """After the search from a given start ``x0`` (search units) stopped without
        converging (``failed``: a status of ``_STOPPED``), or converged where the criterion
        is higher than at a default start (:meth:`_lower_default`: a flat stretch far from
        the optimum, e.g. poles far beyond the Nyquist rate; the evaluation budget is per
        search, as on the default route): the first stage from that start, and the estimator
        from its estimate, as the default route does from its own starts. A criterion far from its
        optimum may give the estimator's search no way out (the exact likelihood with the
        poles far beyond the Nyquist rate is flat in them) where the first stage's least
        squares still finds the way. The lower criterion is kept; where the restart does not
        lower it, the failure stays, its message naming the fix. Returns the problem, the
        outcome (``nfev``: the restart's evaluations only) and those evaluations."""
        est = self.estimator
        first = est.first_stage()
        fix = (
            "fit without start (the default starts of Section 4.5), or from a start nearer "
            "the optimum"
        )
        if failed.status is FitStatus.MAX_EVALUATIONS:
            fix = f"{fix}, or with a larger max_nfev"
        pre = self.make(first, None)
        if first is est or not set(pre.names) <= set(problem.names):
            return problem, failed._replace(nfev=0, message=f"{failed.message}; {fix}"), 0
        x_first = np.array([x0[problem.names.index(name)] for name in pre.names])
        _, found = run_search(pre, x_first, self.max_nfev)
        nfev = found.nfev
        again: tuple[Problem, Outcome] | None = None
        if np.isfinite(found.cost):
            again_problem, again_best, n = self._second_stage(pre, found.x, noise, None)
            nfev += n
            again = again_problem, again_best
        why = (
            f"the search from the given start stopped ({failed.status.name}: {failed.message})"
            if failed.status in _STOPPED
            else f"the search from the given start ended ({failed.message}) where the criterion "
            "is higher than at a default start"
        )
        if again is not None and again[1].cost < failed.cost:
            _release(problem)
            msg = (
                f"{again[1].message} (after a restart: {why}; the {first.name} fit from that "
                f"start, {found.status.name}, started the {est.name} search)"
            )
            if again[1].status in _STOPPED:  # lower, and still not converged: say the fix
                msg = f"{msg}; {fix}"
            return again[0], again[1]._replace(message=msg, nfev=nfev), nfev
        if again is None:
            tried = f"the {first.name} fit from that start ended {found.status.name}"
        else:
            _release(again[0])
            tried = (
                f"a restart from the {first.name} fit from that start ended "
                f"{again[1].status.name} at a criterion no lower ({again[1].cost:.6g} against "
                f"{failed.cost:.6g}, with y and u scaled as in the search)"
            )
        return (
            problem,
            failed._replace(message=f"{failed.message}; {tried}: {fix}", nfev=nfev),
            nfev,
        )

    # ------------------------------------------------------------------ 2. covariance
    def covariance(self, staged: Staged, cov_type: str) -> tuple[FloatArray, str | None, str]:
        """(covariance, why it could not be computed or None, a note for the message); the
        white-noise std the covariance used goes to ``staged.noise_std``."""
        problem, x = staged.problem, staged.outcome.x
        noise = staged.noise_std
        staged.extra["cov_requested"] = cov_type != "none"  # an all-NaN one is then a failure
        staged.extra["cov_type"] = cov_type
        cov = np.full((x.size, x.size), np.nan)
        noise_rec: float | None = None
        try:
            if problem.uses_noise:
                noise_rec = problem.split(x)[2]
            elif noise is not None:
                noise_rec = float(noise)
            elif cov_type == "sandwich":  # the covariance needs sigma_v: its ML value
                mom = problem.moments(x)
                noise_rec = float(np.sqrt(noise_variance_ml(self.data.y - mom.mean, mom.var)))
            staged.noise_std = noise_rec
            cov = covariance(problem, x, cov_type, noise_rec)
        except ValueError as exc:  # e.g. an unstable model: the checks say why
            staged.noise_std = noise_rec
            return cov, str(exc), ""
        return cov, None, ""

    # ------------------------------------------------------------------ 3. checks
    def post_context(self, staged: Staged, cov: FloatArray, cov_error: str | None) -> PostContext:
        problem, x = staged.problem, staged.outcome.x
        est, structure = self.estimator, self.structure
        extra = staged.extra

        def default_starts() -> list[FloatArray]:
            # A search that already ran from every default start (the first stage) has
            # nothing to compare, nor has one whose end was compared with them already (a
            # family's second stage, _from_lower_default; a given start's search, none
            # lower), nor a known system with a known law (no start);
            # after a given start or another second stage, the criterion at the default
            # starts must not be lower than at the estimate.
            if (
                (extra["start"] is None and extra["single"])
                or extra["prefit"] is not None
                or extra.get("compared")
                or not self._defaults_apply(problem)
            ):
                return []
            return self.default_starts(problem)

        known_variance: Callable[[FloatArray], FloatArray] | None = None
        given = self.given_noise
        # (a noise std of 0, e.g. noise-free simulated data, leaves nothing to standardise by)
        if given and not est.ignores_jitter and not problem.estimates_noise:
            known_noise = float(given)

            def known_variance(v: FloatArray) -> FloatArray:
                # Var y_k plus the spread of the fitted mean, dm_k^T Cov dm_k: an inefficient
                # estimator (bcls) leaves residuals of many noise stds where Var s_k is tiny
                mom, _, dm, _ = problem.derivatives(v)
                spread = np.einsum("pk,pq,qk->k", dm, np.nan_to_num(cov), dm)
                return np.asarray(mom.var + known_noise**2 + spread, dtype=float)

        return PostContext(
            data=self.data,
            y_scale=self.scaling.sy,
            structure=structure,
            jitter=self.jitter,
            names=problem.names,
            bounds=problem.bounds,
            x=x,
            cost=float(staged.outcome.cost),
            cov=cov,
            objective=problem.criterion_at,
            model_mean=lambda v: problem.moments(v).mean,
            oe_system=lambda: self.oe()[0],
            starts=default_starts,
            cov_error=cov_error,
            known_variance=known_variance,
            screen=_screen(problem),
            cov_requested=extra.get("cov_requested"),
            scores=_scores(problem) if extra.get("cov_type") == "oim" else None,
        )

    # ------------------------------------------------------------------ 4. units
    def to_data_units(self, staged: Staged, x: FloatArray) -> Problem:
        """The problem in the data's units at the estimate ``x`` (already mapped back)."""
        problem = staged.problem
        sc = self.scaling
        if sc.identity:
            return problem
        staged.noise_std = None if staged.noise_std is None else staged.noise_std * sc.sy
        w = problem.weights_at
        problem.release()
        if problem.likelihood is not None:  # its rule, before the next one is designed
            problem.likelihood.release()
            free_moment_plans(self.data.N)  # and the moment plans of the checks
        return Problem(
            self.orig,
            self.structure,
            self.jitter,
            self.estimator,
            self.freqs,
            None if problem.noise_std is None else problem.noise_std * sc.sy,
            weights_at=None if w is None else sc.to_original(w),
        )

    # ------------------------------------------------------------------ 5. result
    def result_fields(self, problem: Any, x: FloatArray, staged: Staged) -> dict[str, Any]:
        problem.release()  # a fresh signal for the result, without the criterion's caches
        law = problem.jitter_law(x)
        theta = problem.layout.block(x, "system")
        structure = self.structure
        fitted = structure.system(theta) if isinstance(structure, ModelStructure) else None
        problem.release()
        return {
            "system": fitted,
            "jitter_law": law,
            "noise_std": staged.noise_std,
            "structure": structure,
            "jitter_model": self.jitter,
        }


def _release(problem: Problem) -> None:
    """Drop a discarded search's caches and its likelihood's rule (if any)."""
    problem.release()
    if problem.likelihood is not None:
        problem.likelihood.release()


def _scores(problem: Problem) -> Callable[[FloatArray], FloatArray] | None:
    """The exact likelihood's per-sample scores at a point, shape (N, p), for the check of
    the information equality (``PostContext.scores``); None for the other criteria."""
    lik = problem.likelihood
    if lik is None:
        return None
    y = problem.data.y

    def scores(v: FloatArray) -> FloatArray:
        lik.serve(v)
        return np.asarray(lik.scores(v, y)[1], dtype=float)

    return scores


def _screen(problem: Problem) -> Callable[[FloatArray], FloatArray] | None:
    """The exact likelihood's -2 ln p_k over the first ``SCREEN_SAMPLES`` samples, for the
    checks' first look at far points (``PostContext.screen``), on records of at least four
    times as many samples (None otherwise, and for the other criteria)."""
    lik = problem.likelihood
    if lik is None or lik.N < 4 * SCREEN_SAMPLES:
        return None
    head = lik.leading(SCREEN_SAMPLES)
    y = problem.data.y[:SCREEN_SAMPLES]

    def screen(v: FloatArray) -> FloatArray:
        head.serve(v)  # (the points screened lie far apart)
        return -2 * head.logpdf(v, y)

    return screen


def _check_prefit(prefit: FitResult, pre: Problem) -> None:
    """A ``start`` FitResult must be the first-stage fit of this very problem (same data,
    structure, jitter model, frequencies and estimator): its cost, re-evaluated here, must
    match."""
    made_by = getattr(prefit, "estimator", None) or prefit.method
    same = made_by == pre.estimator if not isinstance(made_by, str) else made_by == pre.method
    if not same or prefit.names != pre.names:
        raise ValueError(
            f"start: a FitResult passed as start must come from fit(..., method={pre.method!r}) "
            f"with parameters {pre.names}; got method {prefit.method!r} with {prefit.names}"
        )
    # A search that ended (converged, then flagged by the checks after it: a jitter scale
    # collapsed onto its bound, an unidentified shape, ...) is a valid start: the next stage
    # is what repairs it. A search that did not end is not.
    if prefit.status.name in ("MAX_EVALUATIONS", "NOT_FINITE", "OPTIMISER_FAILED"):
        raise ValueError(
            f"start: the {pre.method} fit passed as start did not converge ({prefit.status.name}); "
            "fit without it, or from a parameter vector"
        )
    cost = pre.objective(prefit.x)
    if (
        prefit.freqs.shape != pre.freqs.shape
        or not np.allclose(prefit.freqs, pre.freqs)
        or not np.isclose(cost, prefit.cost, rtol=1e-9, atol=0.0)
    ):
        raise ValueError(
            "start: the FitResult passed as start was fitted to other data, jitter model or "
            "frequencies (its cost does not match this problem); fit it to the same data first"
        )
