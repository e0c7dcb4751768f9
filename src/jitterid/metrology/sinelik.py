"""The exact likelihood of a jittered pure tone at instrument scale (issue 26, item 2).

For a record y_k = c + A sin(psi_k) + v_k, psi_k = theta_k + w tau_k, theta_k = w kT + phi,
w = 2 pi f, v_k ~ N(0, sigma^2) and tau_k i.i.d. of a law p (Gaussian, uniform or
dual-Dirac), each sample's density is the one-dimensional integral over the sampling phase

    p(y_k) = int N(y_k - c - A sin psi; sigma^2) p_u(psi - theta_k) dpsi,               (S1)

p_u the law of the phase jitter u = w tau. The generic route
(:class:`jitterid.estimation.likelihood.ExactLikelihood`) integrates over tau with panels
sized for any signal; here the integrand's structure is used:

* **Branches.** sin is monotone on each branch [b pi - pi/2, b pi + pi/2]; on a branch the
  Gaussian factor has a single peak, at the root psi_b = b pi + (-1)^b asin(z),
  z = (y - c)/A (clipped to the turning point where |z| > 1). The prior's support (a
  Gaussian's +-8.5 std, the law's own cut; a uniform's +-a; each Gaussian of a dual Dirac
  separately) is cut into the branches it meets: one or two for a phase spread below pi/2.
* **Laplace window.** On each piece the mode m of the log-integrand
  l(psi) = -(y - c - A sin psi)^2 / (2 sigma^2) + ln p_u(psi - theta) is found by a few
  safeguarded Newton steps from the linearised product of the two factors, and its width
  P = (max(-l''(m), 0) + l'(m)^2)^(-1/2) (the curvature at an interior mode, the decay
  rate at an edge where the mode lies on the support's or branch's bound).
* **Quadrature.** The window [m - K P, m + K P] (K = ``_WINDOW``) cut to the piece is
  split at m -+ K/3 and m into four panels of ``_ORDER`` Gauss-Legendre nodes each; the
  pieces whose Laplace mass lies ``_DROP`` below the sample's largest are dropped.

Cost: ``4 _ORDER`` nodes per piece and about one piece per sample whatever sigma, so O(N)
with a small constant, in chunks of ``_CHUNK`` samples (memory bounded independently of N).

Error. Against the generic route's quadrature and against brute force over jitter draws
(tests/metrology/test_sinelik.py) the per-sample ln p agrees within ``TOLERANCE`` (stated:
1e-7 in each ln p(y_k), at noise std from 1e-9 to 1 of the amplitude and phase spreads
1e-6 to 1 rad). The window holds the integrand down to e^-K^2/(2 c^2) of its peak for a
width misjudged by a factor c (K = 10: 4e-11 at c = 1.5); the panels integrate a Gaussian
of the estimated width within ~1e-9 (test ``test_rule_error_bound``).

Derivatives. With the posterior weights pi_j at the nodes (sum 1 per sample), e_j the
residual y - c - A sin psi_j and D_j = e_j A cos psi_j / sigma^2 (d ln N / d psi), holding
the law's standard variable xi fixed (tau = mu + r xi; a scale family's support moves
with its scale, so this is exact, boundary terms included)::

    d ln p / d phi   = E[D]            d ln p / d f     = 2 pi E[D (kT + tau)]
    d ln p / d A     = E[e sin psi] / sigma^2
    d ln p / d c     = E[e] / sigma^2  d ln p / d sigma = E[e^2] / sigma^3 - 1 / sigma
    d ln p / d scale = E[D w (tau - mu) / scale]        d ln p / d dj = E[D w s / 2]

(s = +-1 the dual Dirac's component). The observed information follows from the same
nodes by Louis' identity, -d^2 ln p_k = -E_k[d2 ln f] - Var_k[d ln f] (f the node's
integrand at a fixed standard jitter variable; test: against central differences of the
score). The maximum is found by damped Newton steps on the observed information (its
negative curvatures made positive where it is not definite; on records longer than 2^15
samples the information of every n-th chunk, scaled, for the steps), in ln of the scales,
inside the bounds: a few passes over the record. The covariance is the inverse observed
information of the whole record.

Noise-free records (sigma -> 0). (S1) holds for every sigma > 0 and the rule scales with
sigma (the window shrinks with the Gaussian factor), so a noise std of 1e-9 of the
amplitude costs no more than one of 1e-2. (Below about 1e-9 A double precision limits ln p:
the samples and the phases carry ~1e-16 relative rounding, i.e. 1e-16 A / sigma of a
noise std.) At sigma = 0 the density is
p(y) = sum_b p_u(psi_b - theta) / (A sqrt(1 - z^2)) (tests: the rule tends to it): a
likelihood with a moving support (|z| <= 1) and unbounded at the turning points, not a
regular one, so the noise std is searched down to a floor only, ``noise_floor``: the
physical one (a quantised record's LSB / sqrt 12) or, on a float record, the meter's
numeric floor, ``NUMERIC_FLOOR`` = 1e-3 of the jitter's own spread of the samples. (A floor
above a noise-free record's zero noise biases the jitter std low by about a quarter of the
floor's ratio to that spread: near the tone's peaks the jitter moves the samples by less
than the floor, and the model reads them as less jitter; measured -0.5 % at the generic
route's 3 %.) A noise std on its floor is reported AT_BOUND with
no standard error; the meter then says the noise is below what the record resolves.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import positive, real_array
from ..estimation.result import FitResult, FitStatus
from ..jitter.laws import GaussianFamily, JitterFamily, UniformFamily
from ..jitter.regular import DualDiracFamily
from ..systems.tones import SineWave

__all__ = ["NUMERIC_FLOOR", "TOLERANCE", "SineLikelihood", "fit_sine_ml", "sine_ml_applies"]

FloatArray = NDArray[np.float64]

#: The noise floor of a float record (no physical one), relative to the jitter's own spread
#: of the samples A sqrt((w sigma)^2 / 2): a floor c biases the jitter std low by about
#: c / 4 to c / 6 on a noise-free record (see the module doc): 1e-3 moves it by ~2e-4
#: (measured: -0.03 standard errors at N = 2^14, about -0.25 at 2^20). Lower floors
#: are closer still but slow the search (the likelihood of a noise-free tone is not
#: regular: its peaks' samples make it rough in the amplitude and offset on the scale
#: of the floor).
NUMERIC_FLOOR = 1e-3
#: The stated accuracy of each ln p(y_k) (absolute), see the module doc.
TOLERANCE = 1e-6
_ORDER = 10  # Gauss-Legendre nodes per panel
_WINDOW = 10.0  # window half-width in Laplace widths
_CUTS = np.array([-1.0, -1.0 / 3.0, 0.0, 1.0 / 3.0, 1.0])  # panel edges, in window units
_DROP = 40.0  # pieces this far (in ln) below the sample's largest are dropped
_GAUSS_CUT = 8.5  # a Gaussian's support, in std (the law's pdf is 0 beyond)
_NEWTON = 6  # Newton steps for the mode
_DECREMENT = 1e-3  # the search stops where g^T OPG^-1 g (twice the predicted gain) is below
_AGREE = 1e-9  # two rules of a piece agreeing within this (in ln) are accepted
_FINE = 16  # equal panels of the third rule
_CHUNK = 1 << 12  # samples per chunk (its node arrays stay in cache)
_LN_SQRT_2PI = 0.5 * math.log(2 * math.pi)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(_ORDER)
_GL_LOGW = np.log(_GL_W)


def sine_ml_applies(model: object, family: object) -> bool:
    """Whether :class:`SineLikelihood` handles this model and jitter family: a pure tone
    (:class:`~jitterid.systems.tones.SineWave`, one harmonic, polar form, estimated
    frequency) with a Gaussian, uniform or dual-Dirac family.

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
        and isinstance(family, (GaussianFamily, UniformFamily, DualDiracFamily))
    )


@dataclass(frozen=True)
class _Component:
    """One part of the phase-jitter law: weight, centre (s), Gaussian std or uniform
    half-width (s), and which family parameter is its scale / moves its centre."""

    weight: float
    centre_s: float
    scale_s: float
    uniform: bool
    sign: float  # the dual Dirac's +-1 (d centre / d dj = sign / 2), else 0


def _components(family: JitterFamily, jp: FloatArray) -> list[_Component]:
    if isinstance(family, GaussianFamily):
        return [_Component(1.0, 0.0, float(jp[0]), False, 0.0)]
    if isinstance(family, UniformFamily):
        return [_Component(1.0, 0.0, float(jp[0]), True, 0.0)]
    rj, dj = float(jp[0]), float(jp[1])
    return [
        _Component(0.5, -0.5 * dj, rj, False, -1.0),
        _Component(0.5, 0.5 * dj, rj, False, 1.0),
    ]


@dataclass(frozen=True)
class _Chunk:
    """One chunk's pieces: per-sample ln p, (with the score) the per-sample score, and
    (with the information) sum_nodes pi_j (d2 ln f_j + g_j g_j^T) over the chunk."""

    logp: FloatArray
    score: FloatArray | None
    second: FloatArray | None = None


class SineLikelihood:
    """The exact log-likelihood (S1) of a pure tone under i.i.d. jitter, with its score.

    Parameters
    ----------
    y : array_like, shape (N,)
        The samples at the nominal instants kT.
    T : float
        The nominal sampling interval (s).
    family : GaussianFamily, UniformFamily or DualDiracFamily
        The jitter family (its parameters come first in x).

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

    def __init__(self, y: ArrayLike, T: float, family: JitterFamily) -> None:
        self.y = real_array(y, "y", ndim=1)
        if not np.all(np.isfinite(self.y)):
            raise ValueError("y must be finite: remove or interpolate the NaN/inf samples first")
        self.T = positive(T, "T")
        if not isinstance(family, (GaussianFamily, UniformFamily, DualDiracFamily)):
            raise TypeError(
                "family must be a GaussianFamily, UniformFamily or DualDiracFamily (the laws "
                f"SineLikelihood integrates in closed structure); got {type(family).__name__}: "
                "use jitterid.estimation.likelihood.ExactLikelihood for other laws"
            )
        self.family = family
        self.nj = len(family.param_names)
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
        jp = xv[: self.nj]
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
        for i, k0 in enumerate(range(0, self.N, _CHUNK)):
            k = np.arange(k0, min(k0 + _CHUNK, self.N), dtype=float)
            with_info = info > 0 and i % info == 0
            ch = _chunk(
                self.y[k0 : k0 + k.size], k, self.T, comps, A, phi, f, c, sigma, score, with_info
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
        blo, bhi = band_hz if band_hz is not None else (1e-300, math.inf)
        lo = np.r_[fam[:, 0], 0.0, -math.inf, max(blo, 1e-300), -math.inf, noise_floor]
        hi = np.r_[fam[:, 1], math.inf, math.inf, bhi, math.inf, math.inf]
        amp_floor = 1e-300
        lo[self.nj] = amp_floor
        if not noise_floor > 0:
            lo[-1] = 1e-300
        return lo, hi


def _chunk(
    y: FloatArray,
    k: FloatArray,
    T: float,
    comps: list[_Component],
    A: float,
    phi: float,
    f: float,
    c: float,
    sigma: float,
    score: bool,
    info: bool = False,
) -> _Chunk:
    """ln p and the per-sample score of one chunk of samples (module doc)."""
    n = y.size
    w = 2 * math.pi * f
    frac = np.mod(f * T * k, 1.0)
    theta = 2 * math.pi * frac + phi
    theta = np.mod(theta, 2 * math.pi)
    z = (y - c) / A
    # ---- the pieces: (sample, component, branch) with the support cut to the branch
    idx_l, comp_l, lo_l, hi_l, b_l = [], [], [], [], []
    for cix, comp in enumerate(comps):
        centre = theta + w * comp.centre_s
        half = w * comp.scale_s * (1.0 if comp.uniform else _GAUSS_CUT)
        slo, shi = centre - half, centre + half
        b0 = np.floor((slo + 0.5 * math.pi) / math.pi)
        slots = math.ceil(2 * half / math.pi) + 1
        for slot in range(slots):
            b = b0 + slot
            beta = b * math.pi - 0.5 * math.pi
            lo = np.maximum(slo, beta)
            hi = np.minimum(shi, beta + math.pi)
            ok = np.flatnonzero(hi > lo)
            if ok.size == 0:
                continue
            idx_l.append(ok)
            comp_l.append(np.full(ok.size, cix))
            lo_l.append(lo[ok])
            hi_l.append(hi[ok])
            b_l.append(b[ok])
    idx = np.concatenate(idx_l)
    ci = np.concatenate(comp_l)
    lo = np.concatenate(lo_l)
    hi = np.concatenate(hi_l)
    b = np.concatenate(b_l)
    yy, th = y[idx], theta[idx]
    cw = np.array([cp.weight for cp in comps])[ci]
    cc = theta[idx] + w * np.array([cp.centre_s for cp in comps])[ci]  # prior centre (phase)
    cs = w * np.array([cp.scale_s for cp in comps])[ci]  # phase std / half-width
    uni = np.array([cp.uniform for cp in comps])[ci]
    # ---- the mode: the root on the branch, the linearised product, then Newton
    zz = np.clip(z[idx], -1.0, 1.0)
    odd = np.mod(b, 2.0) != 0
    root = b * math.pi + np.where(odd, -1.0, 1.0) * np.arcsin(zz)
    root = np.clip(root, lo, hi)
    e_r = np.abs(yy - c - A * np.sin(root)) / sigma
    wn2 = sigma**2 / (A**2 * np.cos(root) ** 2 + 2 * A * sigma * (1 + e_r))
    prec_p = np.where(uni, 0.0, 1.0 / cs**2)
    prec = 1.0 / wn2 + prec_p
    m = np.clip((root / wn2 + cc * prec_p) / prec, lo, hi)
    p_lin = 1.0 / np.sqrt(prec)
    s2 = sigma * sigma
    for _ in range(_NEWTON):
        sn, co = np.sin(m), np.cos(m)
        e = yy - c - A * sn
        d1 = e * A * co / s2 - prec_p * (m - cc)
        d2 = (-((A * co) ** 2) - e * A * sn) / s2 - prec_p
        step = np.where(d2 < 0, -d1 / np.where(d2 < 0, d2, -1.0), np.sign(d1) * p_lin)
        step = np.clip(step, -(hi - lo), hi - lo)
        m = np.clip(m + step, lo, hi)
    sn, co = np.sin(m), np.cos(m)
    e = yy - c - A * sn
    d1 = e * A * co / s2 - prec_p * (m - cc)
    d2 = (-((A * co) ** 2) - e * A * sn) / s2 - prec_p
    curv = np.where(d2 < 0, -d2, 1.0 / p_lin**2)
    width = 1.0 / np.sqrt(curv + d1 * d1)
    # the window's reach: where l falls by K^2 / 2 below the mode on its quadratic model
    # (K widths at an interior mode; at an edge where l falls linearly, K^2 / (2 |l'|))
    reach = _WINDOW**2 / (np.abs(d1) + np.sqrt(d1 * d1 + _WINDOW**2 * curv))
    reach = np.maximum(reach, 1e-14 * (1.0 + np.abs(m)))  # a window the phase resolves
    # the log prior (phase density) and log integrand at the mode: the piece's Laplace mass
    lp_m = _log_prior(m - cc, cs, uni, cw)
    mass = -0.5 * e * e / s2 + lp_m + np.log(width)
    best = np.full(n, -np.inf)
    np.maximum.at(best, idx, mass)
    keep = mass >= best[idx] - _DROP
    if not np.all(keep):
        idx, ci, lo, hi, m = idx[keep], ci[keep], lo[keep], hi[keep], m[keep]
        width, reach = width[keep], reach[keep]
        yy, th, cw, cc, cs, uni = yy[keep], th[keep], cw[keep], cc[keep], cs[keep], uni[keep]
    # ---- the nodes: four panels of the Laplace window cut to the piece. Where the nodes'
    # own posterior mean and std disagree with the Laplace centre and width (a piece that
    # is not log-concave: near a turning point the Gaussian factor is not), the piece is
    # integrated again with the panels at those moments; where the two values differ by
    # more than _AGREE, a third time on _FINE equal panels over both windows.
    psi, lw = _nodes(m, reach, lo, hi)
    ln = _log_integrand(psi, lw, yy, c, A, s2, cc, cs, uni, cw)
    del lw
    rmax, pn, psum = _piece_terms(ln)
    del ln
    # groups: (pieces, nodes, ln of each piece's largest node, exp(ln - that), its sum)
    groups: list[tuple[NDArray[np.intp], FloatArray, FloatArray, FloatArray, FloatArray]] = []
    mean, std = _piece_moments(psi, pn, psum)
    off = (np.abs(mean - m) > 0.25 * width) | (std < 0.8 * width) | (std > 1.25 * width)
    off &= np.isfinite(mean) & (std > 0)
    j = np.flatnonzero(off)
    if j.size:
        psi2, lw2 = _nodes(mean[j], _WINDOW * std[j], lo[j], hi[j])
        ln2 = _log_integrand(psi2, lw2, yy[j], c, A, s2, cc[j], cs[j], uni[j], cw[j])
        r2, p2, s2sum = _piece_terms(ln2)
        with np.errstate(divide="ignore", invalid="ignore"):
            i1 = rmax[j] + np.log(psum[j])
            i2 = r2 + np.log(s2sum)
            agree = np.abs(i1 - i2) <= _AGREE
        ja, jd = j[agree], j[~agree]
        groups.append((ja, psi2[agree], r2[agree], p2[agree], s2sum[agree]))
        if jd.size:
            reach_lo = np.maximum(
                lo[jd], np.minimum(m[jd] - reach[jd], mean[jd] - _WINDOW * std[jd])
            )
            reach_hi = np.minimum(
                hi[jd], np.maximum(m[jd] + reach[jd], mean[jd] + _WINDOW * std[jd])
            )
            psi3, lw3 = _even_nodes(reach_lo, reach_hi)
            ln3 = _log_integrand(psi3, lw3, yy[jd], c, A, s2, cc[jd], cs[jd], uni[jd], cw[jd])
            groups.append((jd, psi3, *_piece_terms(ln3)))
    keep1 = np.flatnonzero(~off)
    if keep1.size == idx.size:
        groups.insert(0, (keep1, psi, rmax, pn, psum))
    else:
        groups.insert(0, (keep1, psi[keep1], rmax[keep1], pn[keep1], psum[keep1]))
    top = np.full(n, -np.inf)
    with np.errstate(divide="ignore"):
        for g_j, _, g_r, _, g_s in groups:
            if g_j.size:
                np.maximum.at(top, idx[g_j], g_r + np.log(g_s))
    tot = np.zeros(n)
    scales = []
    for g_j, _, g_r, _, g_s in groups:
        with np.errstate(invalid="ignore"):
            sc = np.exp(np.where(np.isfinite(g_r), g_r - top[idx[g_j]], -np.inf))
        scales.append(sc)
        tot += np.bincount(idx[g_j], weights=sc * g_s, minlength=n)
    with np.errstate(divide="ignore"):
        logp = top + np.log(tot) - math.log(sigma) - _LN_SQRT_2PI
    logp = np.where(np.isfinite(logp), logp, -np.inf)
    if not score:
        return _Chunk(logp, None)
    nj = 1 if len(comps) == 1 else 2
    S = np.zeros((n, nj + 5))
    cen_all = np.array([cp.centre_s for cp in comps])[ci]
    scale_all = np.array([cp.scale_s for cp in comps])[ci]
    sgn_all = np.array([cp.sign for cp in comps])[ci]
    second = np.zeros((nj + 5, nj + 5)) if info else None
    for (g_j, g_psi, _, g_p, _), sc in zip(groups, scales, strict=True):
        if g_j.size:
            post = g_p * (sc / tot[idx[g_j]])[:, None]
            args = (post, g_psi, idx[g_j], yy[g_j], th[g_j], k, T, w, A, c, sigma)
            parts = (cen_all[g_j], scale_all[g_j], sgn_all[g_j], nj)
            _score_group(S, *args, *parts)
            if second is not None:
                second += _second_group(*args, *parts)
    return _Chunk(logp, S, second)


def _score_group(
    S: FloatArray,
    post: FloatArray,
    psi: FloatArray,
    gidx: NDArray[np.intp],
    yy: FloatArray,
    th: FloatArray,
    k: FloatArray,
    T: float,
    w: float,
    A: float,
    c: float,
    sigma: float,
    cen: FloatArray,
    scale: FloatArray,
    sgn: FloatArray,
    nj: int,
) -> None:
    """Add the module doc's score terms of one group of pieces to S (per sample), with the
    posterior weights ``post`` at their nodes ``psi``."""
    n = S.shape[0]
    s2 = sigma * sigma
    sn = np.sin(psi)
    e = A * sn
    np.subtract(yy[:, None] - c, e, out=e)
    pe = post * e
    pd = np.cos(psi)
    pd *= pe
    pd *= A / s2  # post x D
    sum_pd = pd.sum(axis=1)
    pd_tau = (np.einsum("ij,ij->i", pd, psi) - th * sum_pd) / w  # E[D tau]
    sum_p = post.sum(axis=1)
    cols = [w * (pd_tau - cen * sum_pd) / scale]
    if nj == 2:
        cols.append(w * 0.5 * sgn * sum_pd)
    cols += [
        np.einsum("ij,ij->i", pe, sn) / s2,
        sum_pd,
        2 * math.pi * (pd_tau + k[gidx] * T * sum_pd),
        pe.sum(axis=1) / s2,
        np.einsum("ij,ij->i", pe, e) / (s2 * sigma) - sum_p / sigma,
    ]
    for col, v in enumerate(cols):
        S[:, col] += np.bincount(gidx, weights=v, minlength=n)


def _outer_sum(S: FloatArray) -> FloatArray:
    """S^T S (BLAS's matmul can raise spurious floating-point flags on tall, thin arrays:
    the flags are ignored and the sum checked instead)."""
    with np.errstate(over="ignore", invalid="ignore"):
        out = S.T @ S
    if not np.all(np.isfinite(out)):  # pragma: no cover - a real overflow
        out = np.einsum("ki,kj->ij", S, S)
    return np.asarray(out)


def _second_group(
    post: FloatArray,
    psi: FloatArray,
    gidx: NDArray[np.intp],
    yy: FloatArray,
    th: FloatArray,
    k: FloatArray,
    T: float,
    w: float,
    A: float,
    c: float,
    sigma: float,
    cen: FloatArray,
    scale: FloatArray,
    sgn: FloatArray,
    nj: int,
) -> FloatArray:
    """sum_j pi_j (d2 ln f_j + g_j g_j^T) over one group's nodes, with ln f = -e^2 /
    (2 sigma^2) - ln sigma + (the law's, free of x at a fixed standard variable),
    e = y - c - A sin psi, psi = theta_k + w (mu + r xi): d psi / d(scale) = w xi, d psi /
    d dj = w s / 2, d psi / d phi = 1, d psi / d f = 2 pi (kT + tau), d2 psi / d f d(scale)
    = 2 pi xi, d2 psi / d f d dj = pi s."""
    P = nj + 5
    iA, iphi, ifr, ic, isg = nj, nj + 1, nj + 2, nj + 3, nj + 4
    s2 = sigma * sigma
    M = psi.size
    sn, co = np.sin(psi).ravel(), np.cos(psi).ravel()
    pw = post.ravel()
    e = (yy[:, None] - c - A * np.sin(psi)).ravel()
    tau = ((psi - th[:, None]) / w).ravel()
    xi = ((psi - th[:, None]) / w - cen[:, None]) / scale[:, None]
    xi = xi.ravel()
    kT = np.repeat(k[gidx] * T, psi.shape[1])
    sg = np.repeat(sgn, psi.shape[1])
    dpsi = np.zeros((P, M))  # d psi / dx
    dpsi[0] = w * xi
    if nj == 2:
        dpsi[1] = 0.5 * w * sg
    dpsi[iphi] = 1.0
    dpsi[ifr] = 2 * math.pi * (kT + tau)
    de = -A * co * dpsi  # d e / dx (phase parameters)
    de[iA] = -sn
    de[ic] = -1.0
    de[isg] = 0.0
    live = pw > 0  # nodes of empty panels carry no weight (and may be far off)
    pw = np.where(live, pw, 0.0)
    e = np.where(live, e, 0.0)
    g = -e * de / s2
    g[isg] = e * e / (s2 * sigma) - 1.0 / sigma
    # (BLAS's matmul may raise spurious floating-point flags on these shapes: the sums
    # are checked for finiteness by the caller instead)
    with np.errstate(over="ignore", invalid="ignore"):
        out = (g * pw) @ g.T
        # d2 ln f = -(de de^T + e d2e) / sigma^2 (x, x' not sigma)
        d2 = -((de * pw) @ de.T)
        pe = pw * e
        d2 -= (dpsi * (pe * A * sn)) @ dpsi.T  # e d2e: A sin psi dpsi dpsi^T ...
        cross = -(dpsi * (pe * co)).sum(axis=1)  # ... d2e / dA dpsi = -cos psi dpsi
        d2[iA, :] -= cross
        d2[:, iA] -= cross
        # ... and -A cos psi d2psi: d2psi / df d(scale) = 2 pi xi, d2psi / df ddj = pi s
        fs = -A * float(np.sum(pe * co * 2 * math.pi * xi))
        d2[ifr, 0] -= fs
        d2[0, ifr] -= fs
        if nj == 2:
            fd = -A * float(np.sum(pe * co * math.pi * sg))
            d2[ifr, 1] -= fd
            d2[1, ifr] -= fd
    d2 /= s2
    # the noise std's row: d2/dsigma^2 = -3 e^2 / sigma^4 + 1 / sigma^2, d2/dsigma dx =
    # 2 e de / sigma^3
    d2[isg, :] = 2 * ((de * pe).sum(axis=1)) / (s2 * sigma)
    d2[:, isg] = d2[isg, :]
    d2[isg, isg] = float(np.sum(pw * (-3 * e * e / (s2 * s2) + 1 / s2)))
    return out + d2


def _even_nodes(lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and ln weights of _FINE equal panels over [lo, hi]."""
    edges = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, _FINE + 1)[None, :]
    return _panel_nodes(edges)


def _nodes(
    m: FloatArray, reach: FloatArray, lo: FloatArray, hi: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and ln weights of the four panels m + reach [-1, -1/3, 0,
    1/3, 1] cut to [lo, hi], shape (pieces, 4 _ORDER) (-inf on empty panels)."""
    edges = m[:, None] + reach[:, None] * _CUTS[None, :]
    edges = np.clip(edges, lo[:, None], hi[:, None])
    return _panel_nodes(edges)


def _panel_nodes(edges: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Nodes and ln weights of Gauss-Legendre panels between consecutive ``edges``."""
    half = 0.5 * (edges[:, 1:] - edges[:, :-1])
    mid = 0.5 * (edges[:, 1:] + edges[:, :-1])
    psi = (mid[:, :, None] + half[:, :, None] * _GL_X[None, None, :]).reshape(edges.shape[0], -1)
    with np.errstate(divide="ignore"):
        lh = np.log(half)
    lw = (lh[:, :, None] + _GL_LOGW[None, None, :]).reshape(edges.shape[0], -1)
    return psi, lw


def _log_integrand(
    psi: FloatArray,
    lw: FloatArray,
    yy: FloatArray,
    c: float,
    A: float,
    s2: float,
    cc: FloatArray,
    cs: FloatArray,
    uni: FloatArray,
    cw: FloatArray,
) -> FloatArray:
    """ln(weight x integrand of (S1) without its 1/(sqrt(2 pi) sigma)) at the nodes; -inf
    at the nodes of empty panels."""
    e = A * np.sin(psi)
    np.subtract(yy[:, None] - c, e, out=e)
    ln = e * e
    ln *= -0.5 / s2
    q = np.where(uni, 0.0, 0.5 / cs**2)
    const = np.log(cw) + np.where(uni, -np.log(2 * cs), -np.log(cs) - _LN_SQRT_2PI)
    u = psi - cc[:, None]
    u *= u
    u *= q[:, None]
    ln -= u
    ln += lw
    ln += const[:, None]
    return ln


def _piece_terms(ln: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(the largest ln of each piece, exp(ln - it) at its nodes, their sum)."""
    top = ln.max(axis=1)
    safe = np.where(np.isfinite(top), top, 0.0)
    p = np.exp(ln - safe[:, None])
    return top, p, p.sum(axis=1)


def _piece_moments(
    psi: FloatArray, p: FloatArray, psum: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The posterior mean and std of psi within each piece, from its nodes' exp(ln - max)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.einsum("ij,ij->i", p, psi) / psum
        d = psi - mean[:, None]
        d *= d
        var = np.einsum("ij,ij->i", p, d) / psum
    return mean, np.sqrt(np.maximum(var, 0.0))


def _log_prior(u: FloatArray, cs: FloatArray, uni: FloatArray, cw: FloatArray) -> FloatArray:
    """ln of a component's phase density (times its weight) at offsets u from its centre."""
    gauss = -0.5 * (u / cs) ** 2 - np.log(cs) - _LN_SQRT_2PI
    flat = -np.log(2 * cs)
    return np.log(cw) + np.where(uni, flat, gauss)


# ---------------------------------------------------------------------- the search
def _positive(H: FloatArray, opg: FloatArray) -> FloatArray:
    """H with its eigenvalues replaced by their absolute values (floored at 1e-4 of the
    largest), on the scale of its diagonal (or of the scores' outer product where that is
    0): a Newton matrix that is definite and keeps H's curvature where H has one."""
    d = np.abs(np.diag(H))
    d = np.where(d > 0, d, np.maximum(np.diag(opg), 1e-300))
    r = 1.0 / np.sqrt(d)
    lam, vec = np.linalg.eigh(H * np.outer(r, r))
    top = float(np.max(np.abs(lam))) if lam.size else 1.0
    lam = np.maximum(np.abs(lam), 1e-4 * top)
    return (vec * lam) @ vec.T / np.outer(r, r)


def fit_sine_ml(
    y: ArrayLike,
    T: float,
    model: SineWave,
    family: JitterFamily,
    start: ArrayLike,
    *,
    noise_floor: float = 0.0,
    max_iter: int = 100,
) -> FitResult:
    """Maximise :class:`SineLikelihood` from a start: damped Newton steps on the observed
    information (module doc), in ln of the jitter scale and the noise std, inside the
    bounds; the covariance is the inverse observed information.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record.
    T : float
        The nominal sampling interval (s).
    model : SineWave
        The pure-tone model (its ``band_hz`` bounds the frequency).
    family : JitterFamily
        Gaussian, uniform or dual-Dirac family (:func:`sine_ml_applies`).
    start : array_like
        The start, in the order of :attr:`SineLikelihood.names`.
    noise_floor : float
        The smallest noise std searched (see the module doc: noise-free records).
    max_iter : int
        The most steps.

    Returns
    -------
    FitResult
        ``method="ml"``, cost -2 ln L, covariance ``"oim"``; AT_BOUND where a parameter ends
        on its bound (no standard error then), MAX_EVALUATIONS where the steps ran out.
    """
    if not sine_ml_applies(model, family):
        raise TypeError(
            "model must be a pure-tone SineWave (one harmonic, polar, frequency estimated) and "
            "family a Gaussian, uniform or dual-Dirac family; use jitterid.fit(..., 'ml') else"
        )
    lik = SineLikelihood(y, T, family)
    lo, hi = lik.bounds(noise_floor, model.band_hz)
    x = np.clip(np.asarray(start, dtype=float).copy(), lo, hi)
    if x[lik.nj] < 0:
        x[lik.nj] = -x[lik.nj]
        x[lik.nj + 1] += math.pi
    # the search runs in v: ln of the scales (the jitter's first parameter, the noise std:
    # ln L is far closer to quadratic in them), the others as they are
    logs = np.zeros(x.size, bool)
    logs[0] = logs[-1] = True
    vlo = np.where(logs, np.log(np.maximum(lo, 1e-300)), lo)
    vhi = np.where(logs, np.log(np.where(np.isfinite(hi), hi, 1e300)), hi)

    def to_x(v: FloatArray) -> FloatArray:
        return np.where(logs, np.exp(np.where(logs, v, 0.0)), v)

    # the Newton steps' information from about 2^15 samples (the gradient from all)
    stride = max(1, (lik.N + (1 << 15) - 1) // (1 << 15))

    def evaluate(xx: FloatArray) -> tuple[float, FloatArray, FloatArray, FloatArray]:
        # a trial point far off (a long step) may overflow: it is then rejected as
        # non-finite, its floating-point warnings are not the caller's
        with np.errstate(all="ignore"):
            ll_, g_, opg_, info_ = lik.scores_information(xx, stride)
        if not (np.all(np.isfinite(g_)) and np.all(np.isfinite(opg_))):
            ll_ = -math.inf
        jac = np.where(logs, xx, 1.0)
        # in v: the chain rule (d2 ln L / dv^2 gains g x on the diagonal of a ln scale)
        info_v = info_ * np.outer(jac, jac) - np.diag(np.where(logs, g_ * xx, 0.0))
        return ll_, g_ * jac, opg_ * np.outer(jac, jac), info_v

    v = np.where(logs, np.log(np.maximum(x, 1e-300)), x)
    x = to_x(v)
    ll, g, opg, info = evaluate(x)
    nfev = 1
    lam = 1e-4
    stalled = 0
    status, why = FitStatus.MAX_EVALUATIONS, f"the {max_iter} steps ran out"
    if not math.isfinite(ll):
        status, why = FitStatus.NOT_FINITE, "the likelihood is not finite at the start"
        max_iter = 0
    for _ in range(max_iter):
        free = ~(((v <= vlo) & (g < 0)) | ((v >= vhi) & (g > 0)))
        d = np.zeros_like(v)
        # Newton on the observed information, its negative curvatures turned positive
        # where it is not definite (far from the optimum, or a law far from the record's)
        if np.all(np.isfinite(info)):
            H = _positive(info[np.ix_(free, free)], opg[np.ix_(free, free)])
        else:  # BHHH on the scores' covariance
            H = (opg - np.outer(g, g) / lik.N)[np.ix_(free, free)]
        diag = np.maximum(np.diag(H), 1e-300)
        gain = math.inf
        accepted = False
        for _try in range(12):
            try:
                d[free] = np.linalg.solve(H + lam * np.diag(diag), g[free])
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            d = np.where(logs, np.clip(d, -3.0, 3.0), d)  # a scale moves e^3 at most
            vn = np.clip(v + d, vlo, vhi)
            xn = to_x(vn)
            if xn[lik.nj + 2] <= 0:  # frequency stays positive
                lam *= 10
                continue
            lln, gn, opgn, infon = evaluate(xn)
            nfev += 1
            if math.isfinite(lln) and lln >= ll - 1e-12 * abs(ll):
                gain = lln - ll
                v, x, ll, g, opg, info = vn, xn, lln, gn, opgn, infon
                lam = max(lam / 10.0, 1e-9)
                accepted = True
                break
            lam *= 10.0
        if not accepted:
            status, why = FitStatus.CONVERGED, "no step raises the likelihood further"
            break
        # the Newton decrement (twice the predicted further gain)
        fr = ~(((v <= vlo) & (g < 0)) | ((v >= vhi) & (g > 0)))
        try:
            Hm = _positive(info[np.ix_(fr, fr)], opg[np.ix_(fr, fr)])
            dec = float(g[fr] @ np.linalg.solve(Hm, g[fr]))
        except (np.linalg.LinAlgError, ValueError):
            dec = math.inf
        stalled = stalled + 1 if gain < 0.1 * _DECREMENT else 0
        if dec < _DECREMENT and gain < 10 * _DECREMENT:
            status = FitStatus.CONVERGED
            why = (
                f"the predicted gain in ln L is below {_DECREMENT:g} (steps below 3 % of "
                "the standard errors)"
            )
            break
        if stalled >= 3:
            status = FitStatus.CONVERGED
            why = (
                f"ln L rose by less than {0.1 * _DECREMENT:g} in each of 3 steps (a direction "
                "in which the likelihood is flat, e.g. a dual Dirac's dj near 0)"
            )
            break
    x = np.clip(x, lo, hi)
    at_bound = (x <= lo * (1 + 1e-12) + 1e-300) | (x >= hi)
    at_bound[lik.nj] = False  # the amplitude's floor is not a bound of the model
    free = ~at_bound
    P = x.size
    cov = np.full((P, P), math.nan)
    note = ""
    if status is not FitStatus.NOT_FINITE:
        H = lik.observed_information(x)
        Hf = H[np.ix_(free, free)]
        try:
            np.linalg.cholesky(Hf)
            cov[np.ix_(free, free)] = np.linalg.inv(Hf)
        except np.linalg.LinAlgError:
            note = "; the observed information is not positive definite (no standard errors)"
    names = lik.names
    if status is FitStatus.CONVERGED and at_bound.any():
        which = ", ".join(n for n, a in zip(names, at_bound, strict=True) if a)
        status = FitStatus.AT_BOUND
        why += f"; on its bound: {which}"
    jp = x[: lik.nj]
    return FitResult(
        method="ml",
        names=names,
        x=x,
        cost=-2.0 * ll,
        status=status,
        message=f"structured sine likelihood (jitterid.metrology.sinelik): {why}{note}",
        nfev=nfev,
        system=None,
        jitter_law=family.law(tuple(float(v) for v in jp)),
        noise_std=float(x[-1]),
        freqs=np.zeros(0),
        cov=cov,
        cov_type="oim",
        structure=model,
        jitter_model=family,
    )
