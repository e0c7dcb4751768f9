"""Confidence bands from a fit's covariance: the Bode response and the jitter density.

Both are as honest as the covariance C (``FitResult.cov``): for ``ml`` the inverse observed
information, for the moment estimators the sandwich covariance
(:mod:`jitterid.estimation.covariance`).

:func:`bode_band` offers two routes from the estimate x and the system parameters' block of C:

- ``"delta"`` (default): se(f)^2 = J C J^T with J the derivative of log G(i 2 pi f; theta)
  (central differences, relative step 1e-6); the magnitude band is |G| exp(-+ z se_log)
  (computed on log |G|, so it stays positive) and the phase band arg G -+ z se_phase, z the
  normal quantile of ``level``.
- ``"sampling"``: draw theta^(r) ~ N(x, C) (draws outside the structure's bounds are
  discarded) and take pointwise (1 - level)/2 and (1 + level)/2 quantiles of |G| and of the
  phase. It needs no linearisation, so where the two differ the delta band is not to be
  trusted.

:func:`jitter_pdf_band` draws the jitter family's parameters the same way and takes pointwise
quantiles of the densities. Frequencies are in Hz; phases in degrees.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from .._checks import count, generator, real_array
from ..jitter.laws import JitterFamily
from ..systems.structures import ModelStructure

__all__ = ["BodeBand", "PdfBand", "bode_band", "jitter_pdf_band"]

FloatArray = NDArray[np.float64]


class _Fit(Protocol):
    """What a band needs of a :class:`~jitterid.FitResult` (a protocol, so that this module
    does not import the result, whose methods call it)."""

    @property
    def names(self) -> tuple[str, ...]: ...
    @property
    def x(self) -> FloatArray: ...
    @property
    def cov(self) -> FloatArray: ...
    @property
    def system(self) -> Any: ...
    @property
    def structure(self) -> Any: ...
    @property
    def jitter_law(self) -> Any: ...
    @property
    def jitter_model(self) -> Any: ...


def _is_fit(obj: object) -> bool:
    return all(hasattr(obj, a) for a in ("names", "x", "cov", "system", "structure", "jitter_law"))


def _level(level: float) -> float:
    if not isinstance(level, (int, float, np.floating)) or not 0 < float(level) < 1:
        raise ValueError(f"level must be a number in (0, 1), e.g. 0.95; got {level!r}")
    return float(level)


def _normal_draws(
    gen: np.random.Generator, x: FloatArray, cov: FloatArray, size: int
) -> FloatArray:
    """Draws from N(x, cov) through a clipped eigendecomposition: a sandwich covariance may
    be slightly indefinite from rounding, which multivariate_normal would warn about."""
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    root = (v * np.sqrt(np.maximum(w, 0.0))).T
    return x + gen.standard_normal((size, x.size)) @ root


def _evaluate_draws(
    at: Callable[[FloatArray], Any], samples: FloatArray, draws: int
) -> NDArray[Any]:
    """``at(theta)`` for every parameter draw (one row each), skipping a draw that gives no
    valid model (``at`` raises ValueError: an unstable draw, roots that cannot be matched);
    refused when fewer than 90 % of the ``draws`` asked for remain."""
    got = []
    for th in samples:
        try:
            got.append(at(th))
        except ValueError:
            continue
    if len(got) < 0.9 * draws:
        raise ValueError(
            f"only {len(got)} of {draws} parameter draws give a valid model inside the "
            "structure's bounds: the normal approximation is poor here; use method='delta' "
            "with care"
        )
    return np.array(got)


@dataclass(frozen=True, eq=False)
class BodeBand:
    """Frequency response of a fit with pointwise confidence bands (:func:`bode_band`).

    Attributes
    ----------
    f : ndarray
        Frequencies (Hz).
    magnitude, magnitude_lo, magnitude_hi : ndarray
        |G(i 2 pi f)| at the estimate and its band.
    phase, phase_lo, phase_hi : ndarray
        Unwrapped phase in degrees and its band.
    level : float
        Confidence level; NaN bands mean the covariance was unavailable.

    Examples
    --------
    >>> import jitterid as ji
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> band = ji.bode_band(ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05)), [0.01, 1.0])
    >>> band.magnitude.shape, bool((band.magnitude_lo <= band.magnitude_hi).all())
    ((2,), True)
    """

    f: FloatArray
    magnitude: FloatArray
    magnitude_lo: FloatArray
    magnitude_hi: FloatArray
    phase: FloatArray
    phase_lo: FloatArray
    phase_hi: FloatArray
    level: float


def _indices(result: _Fit, names: tuple[str, ...], what: str) -> list[int]:
    missing = [n for n in names if n not in result.names]
    if missing:
        raise ValueError(
            f"the {what} does not match the fit: parameters {missing} are not among the fit's "
            f"{list(result.names)}; pass the structure or family that was given to fit()"
        )
    return [result.names.index(n) for n in names]


def bode_band(
    result: _Fit,
    f: ArrayLike,
    level: float = 0.95,
    *,
    method: str = "delta",
    draws: int = 4000,
    rng: np.random.Generator | int | None = None,
    structure: ModelStructure | None = None,
) -> BodeBand:
    """Bode magnitude and phase of a fit with pointwise confidence bands (module docstring).

    Parameters
    ----------
    result : FitResult
        A fit from :func:`jitterid.fit`.
    f : array_like
        Frequencies (Hz).
    level : float
        Confidence level in (0, 1).
    method : {"delta", "sampling"}
        Linearisation of log G, or quantiles over parameter draws from N(x, C).
    draws : int
        Number of parameter draws for ``"sampling"`` (at least 100).
    rng : numpy.random.Generator or int
        Source of randomness, required for ``"sampling"``.
    structure : ModelStructure, optional
        The structure given to :func:`jitterid.fit`, to rebuild G from parameters; default
        the one the result records (``result.structure``).

    Returns
    -------
    BodeBand
        NaN bands where the covariance is unavailable (a parameter on a bound); zero width
        for a known system.

    Raises
    ------
    ValueError
        For ``"sampling"``, if fewer than 90 % of the draws lie inside the structure's
        bounds: the normal approximation is then too poor for a band.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(200.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=2000, noise_std=0.01, rng=2)
    >>> res = jid.fit(data, jid.RationalModel(0, 1), jid.Uniform(0.05))
    >>> band = jid.bode_band(res, [0.1, 1.0])
    >>> band.magnitude.shape
    (2,)
    """
    level = _level(level)
    if not _is_fit(result):
        raise TypeError(
            f"result must be a FitResult from jitterid.fit; got {type(result).__name__}"
        )
    if method not in ("delta", "sampling"):
        raise ValueError(f"method must be 'delta' or 'sampling'; got {method!r}")
    if structure is None:
        structure = result.structure
    if not isinstance(structure, ModelStructure):
        raise TypeError(
            "structure must be the ModelStructure given to fit() (PolePairGain(), "
            f"RationalModel(m, n)); got {type(structure).__name__}"
        )
    freqs = np.atleast_1d(real_array(f, "f"))
    idx = _indices(result, tuple(structure.param_names), "structure")
    theta = result.x[idx]
    g0 = result.system.frequency_response(freqs)
    mag, phase = np.abs(g0), np.degrees(np.unwrap(np.angle(g0)))

    def band(m_lo: FloatArray, m_hi: FloatArray, p_lo: FloatArray, p_hi: FloatArray) -> BodeBand:
        return BodeBand(freqs, mag, m_lo, m_hi, phase, p_lo, p_hi, level)

    if not idx:
        return band(mag.copy(), mag.copy(), phase.copy(), phase.copy())
    cov = result.cov[np.ix_(idx, idx)]
    if not np.all(np.isfinite(cov)):
        nan = np.full_like(mag, np.nan)
        return band(nan, nan.copy(), nan.copy(), nan.copy())
    if method == "sampling":
        gen, n = generator(rng, "rng"), count(draws, "draws", minimum=100)
        lo, hi = np.array(structure.bounds, dtype=float).reshape(-1, 2).T
        samples = _normal_draws(gen, theta, cov, n)
        inside = samples[np.all((samples >= lo) & (samples <= hi), axis=1)]
        g = _evaluate_draws(lambda th: structure.system(th).frequency_response(freqs), inside, n)
        q = [0.5 - level / 2, 0.5 + level / 2]
        m_q = np.quantile(np.abs(g), q, axis=0)
        # Phase of each draw relative to the estimate's, so no draw wraps differently.
        p_q = phase + np.quantile(np.degrees(np.angle(g / g0)), q, axis=0)
        return band(m_q[0], m_q[1], p_q[0], p_q[1])
    jac = np.empty((freqs.size, len(idx)), complex)
    for i in range(len(idx)):
        h = 1e-6 * max(abs(theta[i]), 1e-3)
        g_side, h_side = [], []
        for step in (h, -h):  # one-sided where a step leaves the structure's domain
            th = theta.copy()
            th[i] += step
            try:
                g_side.append(structure.system(th).frequency_response(freqs))
                h_side.append(h)
            except ValueError:
                g_side.append(g0)
                h_side.append(0.0)
        jac[:, i] = np.log(g_side[0] / g_side[1]) / (h_side[0] + h_side[1])
    zq = float(stats.norm.ppf(0.5 + level / 2))
    se_log = np.sqrt(np.maximum(np.einsum("fi,ij,fj->f", jac.real, cov, jac.real), 0.0))
    se_ph = np.degrees(np.sqrt(np.maximum(np.einsum("fi,ij,fj->f", jac.imag, cov, jac.imag), 0.0)))
    return band(
        mag * np.exp(-zq * se_log),
        mag * np.exp(zq * se_log),
        phase - zq * se_ph,
        phase + zq * se_ph,
    )


@dataclass(frozen=True, eq=False)
class PdfBand:
    """Density of a (fitted) jitter law with a pointwise band.

    Attributes
    ----------
    tau : ndarray
        Jitter values (s).
    pdf, lo, hi : ndarray
        The fitted density and the pointwise band (equal to ``pdf`` for a known law).
    level : float
    fixed : tuple of str
        Family parameters held at their estimate because their variance was unavailable
        (e.g. on a bound); the band then understates the uncertainty.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(25.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Gaussian(0.03), T=0.1, N=200, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.GaussianFamily())
    >>> band = ji.jitter_pdf_band(res, [0.0, 0.03], rng=0, n_draws=100)
    >>> band.tau.tolist(), band.level, band.fixed
    ([0.0, 0.03], 0.95, ())
    """

    tau: FloatArray
    pdf: FloatArray
    lo: FloatArray
    hi: FloatArray
    level: float
    fixed: tuple[str, ...]


_FROM_RESULT: Any = object()


def jitter_pdf_band(
    result: _Fit,
    tau: ArrayLike,
    rng: np.random.Generator | int,
    *args: Any,
    level: float = 0.95,
    n_draws: int = 400,
    family: JitterFamily | None = _FROM_RESULT,
) -> PdfBand:
    """The fitted jitter density with a pointwise band from the parameters' covariance.

    Draws the family's parameters from N(x, C) restricted to the family's bounds (draws
    outside are discarded) and takes pointwise quantiles of the densities.

    Parameters
    ----------
    result : FitResult
        A fit; its jitter family (``result.jitter_model``) gives the band.
    tau : array_like
        Jitter values (s) at which to evaluate the density.
    rng : numpy.random.Generator or int
        Randomness for the draws (explicit).
    level : float
        Confidence level.
    n_draws : int
        Number of parameter draws.
    family : JitterFamily or None, optional
        Default: the result's own family (no band for a known law). ``None`` draws the
        estimate alone, without a band.

    Returns
    -------
    PdfBand

    Raises
    ------
    ValueError
        If fewer than 10 % of the draws lie inside the bounds: the normal approximation of
        the estimate is then too poor for a band.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(25.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Gaussian(0.03), T=0.1, N=200, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.GaussianFamily())
    >>> band = ji.jitter_pdf_band(res, [0.0, 0.03], rng=0, n_draws=100)
    >>> band.pdf.shape, bool(np.all(band.lo <= band.hi))
    ((2,), True)
    """
    if isinstance(tau, JitterFamily) or tau is None:  # the old order (result, family, tau, rng)
        warnings.warn(
            "jitter_pdf_band(result, family, tau, rng) is deprecated: the result knows its family; "
            "call jitter_pdf_band(result, tau, rng) (family=None for no band)",
            DeprecationWarning,
            stacklevel=2,
        )
        if not args:
            raise TypeError("jitter_pdf_band() missing the rng argument")
        family, tau, rng = tau, rng, args[0]
    elif args:
        raise TypeError(f"jitter_pdf_band() takes 3 positional arguments; got {3 + len(args)}")
    if family is _FROM_RESULT:
        model = getattr(result, "jitter_model", None)
        family = model if isinstance(model, JitterFamily) else None
    level = _level(level)
    if not _is_fit(result):
        raise TypeError(f"result must be a FitResult; got {type(result).__name__}")
    n_draws = count(n_draws, "n_draws", minimum=10)
    gen = generator(rng)
    t = np.atleast_1d(real_array(tau, "tau"))
    if result.jitter_law.std == 0:
        raise ValueError("the fit's jitter law has zero spread (no jitter); there is no density")
    pdf = np.asarray(result.jitter_law.pdf(t), float)
    if family is None:
        return PdfBand(t, pdf, pdf.copy(), pdf.copy(), level, ())
    if not isinstance(family, JitterFamily):
        raise TypeError(f"family must be a JitterFamily or None; got {type(family).__name__}")
    idx = _indices(result, tuple(family.param_names), "jitter family")
    x = result.x[idx]
    cov = result.cov[np.ix_(idx, idx)].copy()
    ok = np.isfinite(np.diag(cov))
    fixed = tuple(n for n, good in zip(family.param_names, ok, strict=True) if not good)
    cov[~ok, :] = 0.0
    cov[:, ~ok] = 0.0
    lo_b, hi_b = np.array(family.bounds, float).T
    draws = _normal_draws(gen, x, cov, 10 * n_draws)
    inside = draws[np.all((draws >= lo_b) & (draws <= hi_b), axis=1)]
    if inside.shape[0] < n_draws:
        raise ValueError(
            f"only {inside.shape[0]} of {10 * n_draws} draws of {family.param_names} from their "
            "normal approximation lie inside the family's bounds; the estimate is too uncertain "
            "for a density band (the standard errors are larger than the distance to a bound)"
        )
    dens = np.array([family.law(d).pdf(t) for d in inside[:n_draws]])
    q = (1 - level) / 2
    return PdfBand(
        t,
        pdf,
        np.quantile(dens, q, axis=0),
        np.quantile(dens, 1 - q, axis=0),
        level,
        fixed,
    )
