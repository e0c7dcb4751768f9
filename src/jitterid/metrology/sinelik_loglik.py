"""The record's log-likelihood of a jittered pure tone, :class:`SineLikelihood`: the sums
over the record (in chunks) of the per-sample rule of :mod:`jitterid.metrology.sinelik_rule`,
with its score and observed information, and the parameters' checks and bounds (the model:
:mod:`jitterid.metrology.sinelik`)."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike

from .._checks import positive, real_array
from ..jitter.laws import GaussianFamily, JitterFamily, UniformFamily
from ..jitter.regular import DualDiracFamily, GaussianScaleMixtureFamily
from ..systems.tones import SineWave
from .sinelik_rule import _CHUNK, FloatArray, _Chunk, _chunk, _components, _outer_sum

__all__ = ["SineLikelihood", "sine_ml_applies"]

_FAMILIES = (GaussianFamily, UniformFamily, DualDiracFamily, GaussianScaleMixtureFamily)


def sine_ml_applies(model: object, family: object) -> bool:
    """Whether :class:`SineLikelihood` handles this model and jitter family: a pure tone
    (:class:`~jitterid.systems.tones.SineWave`, one harmonic, polar form, estimated
    frequency) with a Gaussian, uniform, dual-Dirac or Gaussian scale-mixture family.

    Parameters
    ----------
    model : object
        The signal model.
    family : object
        The jitter family.
    """
    return (
        isinstance(model, SineWave)
        and model.harmonics == 1
        and model.form == "polar"
        and model.frequency_hz is None
        and isinstance(family, _FAMILIES)
    )


class SineLikelihood:
    """The exact log-likelihood (S1) of a pure tone under i.i.d. jitter, with its score.

    Parameters
    ----------
    y : array_like, shape (N,)
        The samples at the nominal instants kT.
    T : float
        The nominal sampling interval (s).
    family : GaussianFamily, UniformFamily, DualDiracFamily or GaussianScaleMixtureFamily
        The jitter family (its parameters come first in x).
    squared : bool
        The family's even parameter (:attr:`~jitterid.JitterFamily.even_index`: a dual
        Dirac's dj, a scale mixture's rho) is its square in x (``dj^2`` in s^2, ``rho^2``),
        and its score and information are in it: ln L is even in it, so flat at 0 in it but
        a regular quadratic in its square (the search's coordinate,
        :func:`jitterid.metrology.sinelik_fit.fit_sine_ml`). Other families: no effect.
    quantisation_step : float or None
        The record's quantisation step q (its values lie on a grid of step q): each sample's
        density is then the probability of its bin over q, with ``noise_std`` the noise
        before the quantiser (:mod:`jitterid.metrology.sinelik_kernel`). None: Gaussian
        noise of std ``noise_std``.

    Notes
    -----
    The parameter vector x is ``(*family.param_names, "amplitude", "phase_rad",
    "frequency_hz", "offset", "noise_std")``, the order of
    :class:`~jitterid.estimation.likelihood.ExactLikelihood` for a
    :class:`~jitterid.systems.tones.SineWave` with the noise std estimated.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> from jitterid.metrology.sinelik import SineLikelihood
    >>> rng = np.random.default_rng(0)
    >>> T, N, f = 1e-3, 2000, 123.0
    >>> tau = 50e-6 * rng.standard_normal(N)
    >>> y = np.sin(2 * np.pi * f * (np.arange(N) * T + tau)) + 1e-3 * rng.standard_normal(N)
    >>> lik = SineLikelihood(y, T, ji.GaussianFamily())
    >>> x = [50e-6, 1.0, 0.0, f, 0.0, 1e-3]
    >>> bool(lik.loglik(x) > lik.loglik([20e-6, 1.0, 0.0, f, 0.0, 1e-3]))
    True
    """

    def __init__(
        self,
        y: ArrayLike,
        T: float,
        family: JitterFamily,
        *,
        squared: bool = False,
        quantisation_step: float | None = None,
    ) -> None:
        self.y = real_array(y, "y", ndim=1)
        if not np.all(np.isfinite(self.y)):
            raise ValueError("y must be finite: remove or interpolate the NaN/inf samples first")
        self.T = positive(T, "T")
        if not isinstance(family, _FAMILIES):
            raise TypeError(
                "family must be a GaussianFamily, UniformFamily, DualDiracFamily or "
                "GaussianScaleMixtureFamily (the laws "
                f"SineLikelihood integrates in closed structure); got {type(family).__name__}: "
                "use jitterid.estimation.likelihood.ExactLikelihood for other laws"
            )
        self.family = family
        #: half the quantisation step (0: Gaussian noise)
        self.half = (
            0.0
            if quantisation_step is None
            else 0.5 * positive(quantisation_step, "quantisation_step")
        )
        self.nj = len(family.param_names)
        #: the index of the parameter whose square x holds (None: none)
        self.squared: int | None = family.even_index if squared else None
        self.names = (
            *family.param_names,
            "amplitude",
            "phase_rad",
            "frequency_hz",
            "offset",
            "noise_std",
        )

    @property
    def N(self) -> int:
        """The number of samples."""
        return int(self.y.size)

    # ------------------------------------------------------------------ evaluation
    def _split(self, x: ArrayLike) -> tuple[FloatArray, float, float, float, float, float]:
        xv = np.atleast_1d(real_array(x, "x"))
        if xv.shape != (len(self.names),):
            raise ValueError(f"x must hold {len(self.names)} values {self.names}; got {xv.shape}")
        jp = xv[: self.nj].copy()
        if self.squared is not None:
            i = self.squared
            if not jp[i] >= 0:
                raise ValueError(f"{self.family.param_names[i]}^2 must be >= 0; got {jp[i]!r}")
            jp[i] = math.sqrt(jp[i])
        A, phi, f, c, sigma = (float(v) for v in xv[self.nj :])
        # the jitter parameters validated (bounds), naming the bad one
        self.family.law(tuple(float(v) for v in jp))
        if not sigma > 0:
            raise ValueError(
                f"noise_std must be > 0; got {sigma!r} (a noise-free record is searched down "
                "to a floor: see the module doc of jitterid.metrology.sinelik)"
            )
        if not (f > 0 and A != 0 and math.isfinite(A) and math.isfinite(c)):
            raise ValueError(
                f"amplitude must be nonzero and frequency_hz > 0; got A = {A!r}, f = {f!r}"
            )
        return jp, A, phi, f, c, sigma

    def logpdf(self, x: ArrayLike) -> FloatArray:
        """ln p(y_k | x) for every sample, shape (N,).

        Parameters
        ----------
        x : array_like
            The parameters, in :attr:`names` order.
        """
        return np.concatenate([ch.logp for ch in self._chunks(x, score=False)])

    def loglik(self, x: ArrayLike) -> float:
        """sum_k ln p(y_k | x).

        Parameters
        ----------
        x : array_like
            The parameters, in :attr:`names` order.
        """
        return float(sum(float(np.sum(ch.logp)) for ch in self._chunks(x, score=False)))

    def scores(self, x: ArrayLike) -> tuple[float, FloatArray, FloatArray]:
        """(ln L, its gradient, the outer product of the per-sample scores) at x.

        Parameters
        ----------
        x : array_like
            The parameters, in :attr:`names` order.
        """
        P = len(self.names)
        ll, g, opg = 0.0, np.zeros(P), np.zeros((P, P))
        for ch in self._chunks(x, score=True):
            assert ch.score is not None
            ll += float(np.sum(ch.logp))
            g += ch.score.sum(axis=0)
            opg += _outer_sum(ch.score)
        return ll, g, opg

    def scores_information(
        self, x: ArrayLike, stride: int = 1
    ) -> tuple[float, FloatArray, FloatArray, FloatArray]:
        """(ln L, its gradient, the outer product of the per-sample scores, the observed
        information :meth:`observed_information`) at x, in one pass.

        Parameters
        ----------
        x : array_like
            The parameters, in :attr:`names` order.
        stride : int
            The information's node sums over every stride-th chunk of samples only, scaled
            to the record (an estimate for the search's Newton steps; 1: exact).
        """
        P = len(self.names)
        ll, g = 0.0, np.zeros(P)
        opg, second = np.zeros((P, P)), np.zeros((P, P))
        n_info = 0
        for ch in self._chunks(x, score=True, info=max(int(stride), 1)):
            assert ch.score is not None
            ll += float(np.sum(ch.logp))
            g += ch.score.sum(axis=0)
            opg += _outer_sum(ch.score)
            if ch.second is not None:
                second += ch.second
                n_info += ch.logp.size
        H = opg - second * (self.N / max(n_info, 1))
        return ll, g, opg, 0.5 * (H + H.T)

    def per_sample_scores(self, x: ArrayLike) -> FloatArray:
        """d ln p(y_k | x) / dx for every sample, shape (N, len(x)).

        Parameters
        ----------
        x : array_like
            The parameters, in :attr:`names` order.
        """
        out = [ch.score for ch in self._chunks(x, score=True)]
        return np.concatenate([s for s in out if s is not None])

    def _chunks(self, x: ArrayLike, *, score: bool, info: int = 0) -> Iterator[_Chunk]:
        """The chunks' terms; ``info``: the information's node sums in every info-th chunk
        (0: none)."""
        jp, A, phi, f, c, sigma = self._split(x)
        flip = A < 0
        if flip:  # A sin(psi) = |A| sin(psi + pi)
            A, phi = -A, phi + math.pi
        comps = _components(self.family, jp)
        mixture = isinstance(self.family, GaussianScaleMixtureFamily)
        mix = (float(jp[0]), float(jp[1]), self.squared is not None) if mixture else None
        dj2 = self.squared is not None and not mixture
        for i, k0 in enumerate(range(0, self.N, _CHUNK)):
            k = np.arange(k0, min(k0 + _CHUNK, self.N), dtype=float)
            with_info = info > 0 and i % info == 0
            ch = _chunk(
                self.y[k0 : k0 + k.size],
                k,
                self.T,
                comps,
                A,
                phi,
                f,
                c,
                sigma,
                score,
                with_info,
                dj2,
                mix,
                self.half,
            )
            if flip and ch.score is not None:
                ch.score[:, self.nj] *= -1.0
            if flip and ch.second is not None:
                ch.second[self.nj, :] *= -1.0
                ch.second[:, self.nj] *= -1.0
            yield ch

    # ------------------------------------------------------------------ information
    def observed_information(self, x: ArrayLike) -> FloatArray:
        """-d^2 ln L / dx^2, analytic (Louis' identity at the same nodes): with g_j and
        d2_j the gradient and Hessian in x of ln f_j, the node's log-integrand at a fixed
        standard jitter variable,

            -d^2 ln p_k = -E_k[d2] - (E_k[g g^T] - E_k[g] E_k[g]^T),

        so the record's is sum_k s_k s_k^T - sum_j pi_j (d2_j + g_j g_j^T) (s_k the
        per-sample score).

        Parameters
        ----------
        x : array_like
            The parameters, in :attr:`names` order.
        """
        return self.scores_information(x)[3]

    def bounds(
        self, noise_floor: float = 0.0, band_hz: tuple[float, float] | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """(lower, upper) bounds of x: the family's, the amplitude > 0, the band, the noise
        std above ``noise_floor`` (a tiny positive value when 0).

        Parameters
        ----------
        noise_floor : float
            The smallest noise std searched.
        band_hz : (float, float), optional
            The frequency's bounds, Hz.
        """
        fam = np.array(self.family.bounds, dtype=float)
        if self.squared is not None:
            fam[self.squared] = fam[self.squared] ** 2
        blo, bhi = band_hz if band_hz is not None else (1e-300, math.inf)
        lo = np.r_[fam[:, 0], 0.0, -math.inf, max(blo, 1e-300), -math.inf, noise_floor]
        hi = np.r_[fam[:, 1], math.inf, math.inf, bhi, math.inf, math.inf]
        amp_floor = 1e-300
        lo[self.nj] = amp_floor
        if not noise_floor > 0:
            lo[-1] = 1e-300
        return lo, hi
