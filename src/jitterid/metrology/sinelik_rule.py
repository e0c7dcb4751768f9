"""The per-sample rule of the structured sine likelihood (:mod:`jitterid.metrology.sinelik`):
ln p(y_k) of (S1) for a chunk of samples, its score and its information terms.

The integrand's structure is used (the generic route,
:class:`jitterid.estimation.likelihood.ExactLikelihood`, integrates over tau with panels
sized for any signal):

* **Branches.** sin is monotone on each branch [b pi - pi/2, b pi + pi/2]; on a branch the
  Gaussian factor has a single peak, at the root psi_b = b pi + (-1)^b asin(z),
  z = (y - c)/A (clipped to the turning point where |z| > 1). The prior's support (a
  Gaussian's +-8.5 std, the law's own cut; a uniform's +-a; each Gaussian of a dual Dirac
  or of a scale mixture separately) is cut into the branches it meets: one or two for a
  phase spread below pi/2.
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
1e-6 in each ln p(y_k), at noise std from 1e-9 to 1 of the amplitude and phase spreads
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

(s = +-1 the dual Dirac's component; a dual Dirac's dj^2 and a scale mixture's rho^2 at a
fixed jitter instead, by their laws' own derivatives: :func:`_dual_dirac_terms`,
:func:`_mixture_terms`). These are Gaussian noise's; a quantised record's bin kernel
(:mod:`jitterid.metrology.sinelik_kernel`) has -k1 = -d ln K / de in place of e / sigma^2
and E[ks] = E[d ln K / d sigma] for the noise std's. The observed information follows from
the same nodes by Louis' identity, -d^2 ln p_k = -E_k[d2 ln f] - Var_k[d ln f] (f the node's
integrand at a fixed standard jitter variable; test: against central differences of the
score). The record's sums are :class:`jitterid.metrology.sinelik_loglik.SineLikelihood`'s,
its maximum :func:`jitterid.metrology.sinelik_fit.fit_sine_ml`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import special

from ..jitter.laws import GaussianFamily, JitterFamily, UniformFamily
from ..jitter.regular import GaussianScaleMixtureFamily
from .sinelik_kernel import Kernel

__all__ = ["TOLERANCE"]

FloatArray = NDArray[np.float64]

#: The stated accuracy of each ln p(y_k) (absolute), see the module doc.
TOLERANCE = 1e-6
_ORDER = 10  # Gauss-Legendre nodes per panel
_WINDOW = 10.0  # window half-width in Laplace widths
_CUTS = np.array([-1.0, -1.0 / 3.0, 0.0, 1.0 / 3.0, 1.0])  # panel edges, in window units
_DROP = 40.0  # pieces this far (in ln) below the sample's largest are dropped
_GAUSS_CUT = 8.5  # a Gaussian's support, in std (the law's pdf is 0 beyond)
_NEWTON = 6  # Newton steps for the mode
_AGREE = 1e-9  # two rules of a piece agreeing within this (in ln) are accepted
_FINE = 16  # equal panels of the third rule
_CHUNK = 1 << 12  # samples per chunk (its node arrays stay in cache)
_LN_SQRT_2PI = 0.5 * math.log(2 * math.pi)
# a dual Dirac's score in dj^2 is its score in dj / (2 dj) from dj = this x rj (rounding:
# ~1e-16 rj / dj relative); below, the law's own derivative at a fixed jitter
_DJ_RATIO = 1e-3
_GL_X, _GL_W = np.polynomial.legendre.leggauss(_ORDER)
_GL_LOGW = np.log(_GL_W)


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
    if isinstance(family, GaussianScaleMixtureFamily):
        sg, rho = float(jp[0]), float(jp[1])
        return [
            _Component(0.5, 0.0, sg * math.sqrt(1.0 - rho), False, 0.0),
            _Component(0.5, 0.0, sg * math.sqrt(1.0 + rho), False, 0.0),
        ]
    rj, dj = float(jp[0]), float(jp[1])
    return [
        _Component(0.5, -0.5 * dj, rj, False, -1.0),
        _Component(0.5, 0.5 * dj, rj, False, 1.0),
    ]


@dataclass(frozen=True)
class _Group:
    """One group of pieces at its nodes: what the score and the information read.

    ``post`` the posterior weights at the nodes ``psi`` (pieces, nodes); per piece its
    sample in the chunk ``gidx``, the sample ``yy``, nominal phase ``th``, nominal instant
    ``kT`` and its component's centre ``cen`` (s), scale (s) and dual-Dirac sign ``sgn``;
    the tone's ``w`` (rad/s), ``A``, ``c``, the noise kernel ``kern``
    (:class:`~jitterid.metrology.sinelik_kernel.Kernel`) and its ln K at the nodes ``kr``
    (relative to its constant; None: recomputed); ``nj`` jitter parameters."""

    post: FloatArray
    psi: FloatArray
    gidx: NDArray[np.intp]
    yy: FloatArray
    th: FloatArray
    kT: FloatArray
    cen: FloatArray
    scale: FloatArray
    sgn: FloatArray
    w: float
    A: float
    c: float
    kern: Kernel
    kr: FloatArray | None
    nj: int
    dj2: bool = False
    mix: tuple[float, float, bool] | None = None


@dataclass(frozen=True)
class _NodeTerms:
    """What the score of a group (:func:`_score_group`) hands the information
    (:func:`_second_group`) at the nodes (pieces, nodes): the noise kernel's derivatives
    (:meth:`~jitterid.metrology.sinelik_kernel.Kernel.second`), sin psi and cos psi."""

    kernel: tuple[FloatArray, ...]
    sin: FloatArray
    cos: FloatArray


@dataclass(frozen=True)
class _Chunk:
    """One chunk's pieces: per-sample ln p, (with the score) the per-sample score, and
    (with the information) sum_nodes pi_j (d2 ln f_j + g_j g_j^T) over the chunk."""

    logp: FloatArray
    score: FloatArray | None
    second: FloatArray | None = None


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
    dj2: bool = False,
    mix: tuple[float, float, bool] | None = None,
    half: float = 0.0,
) -> _Chunk:
    """ln p and the per-sample score of one chunk of samples (module doc); ``dj2``: a
    dual Dirac's law columns are d / d rj and d / d (dj^2) at a fixed jitter
    (:func:`_dual_dirac_terms`); ``mix``: a scale mixture's (sigma, rho, whether its second
    column is in rho^2), whose law columns are at a fixed jitter (:func:`_mixture_terms`);
    ``half``: half the quantisation step of a quantised record, whose noise kernel is then
    the bin's (:mod:`jitterid.metrology.sinelik_kernel`; 0: Gaussian noise of std sigma)."""
    kern = Kernel(sigma, half)
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
    sig0 = kern.std  # (the first guesses: the kernel's own std)
    # the window's centre and width from the Gaussian of the kernel's own std: a bin kernel
    # is flat inside its bin, where its own mode and curvature say nothing of the posterior
    # (the bin's q / sqrt(12) is its std); the posterior's moments then confirm the window
    # (else the piece is integrated again, below)
    shape = Kernel(sig0) if kern.half > 0.0 else kern
    e_r = np.abs(yy - c - A * np.sin(root)) / sig0
    wn2 = sig0**2 / (A**2 * np.cos(root) ** 2 + 2 * A * sig0 * (1 + e_r))
    prec_p = np.where(uni, 0.0, 1.0 / cs**2)
    prec = 1.0 / wn2 + prec_p
    m = np.clip((root / wn2 + cc * prec_p) / prec, lo, hi)
    p_lin = 1.0 / np.sqrt(prec)
    for _ in range(_NEWTON):
        sn, co = np.sin(m), np.cos(m)
        d1, d2 = _mode_derivatives(shape, yy - c - A * sn, A, sn, co, prec_p, m - cc)
        step = np.where(d2 < 0, -d1 / np.where(d2 < 0, d2, -1.0), np.sign(d1) * p_lin)
        step = np.clip(step, -(hi - lo), hi - lo)
        m = np.clip(m + step, lo, hi)
    sn, co = np.sin(m), np.cos(m)
    e = yy - c - A * sn
    d1, d2 = _mode_derivatives(shape, e, A, sn, co, prec_p, m - cc)
    curv = np.where(d2 < 0, -d2, 1.0 / p_lin**2)
    width = 1.0 / np.sqrt(curv + d1 * d1)
    # the window's reach: where l falls by K^2 / 2 below the mode on its quadratic model
    # (K widths at an interior mode; at an edge where l falls linearly, K^2 / (2 |l'|))
    reach = _WINDOW**2 / (np.abs(d1) + np.sqrt(d1 * d1 + _WINDOW**2 * curv))
    reach = np.maximum(reach, 1e-14 * (1.0 + np.abs(m)))  # a window the phase resolves
    # the log prior (phase density) and log integrand at the mode: the piece's Laplace mass
    lp_m = _log_prior(m - cc, cs, uni, cw)
    mass = kern.log_rel(e) + lp_m + np.log(width)
    best = np.full(n, -np.inf)
    np.maximum.at(best, idx, mass)
    keep = mass >= best[idx] - _DROP
    cuts = _bin_cuts(kern, yy, c, A, b)
    if not np.all(keep):
        idx, ci, lo, hi, m = idx[keep], ci[keep], lo[keep], hi[keep], m[keep]
        width, reach = width[keep], reach[keep]
        yy, th, cw, cc, cs, uni = yy[keep], th[keep], cw[keep], cc[keep], cs[keep], uni[keep]
        cuts = cuts[keep] if cuts is not None else None
    # ---- the nodes: four panels of the Laplace window cut to the piece. Where the nodes'
    # own posterior mean and std disagree with the Laplace centre and width (a piece that
    # is not log-concave: near a turning point the Gaussian factor is not), the piece is
    # integrated again with the panels at those moments; where the two values differ by
    # more than _AGREE, a third time on _FINE equal panels over both windows. A bin kernel's
    # panels are cut at the bin's edges too (where it falls off over sigma: a step as sigma
    # goes to 0).
    # (a bin kernel's ln K at the nodes kept for the score, which reads its derivatives:
    # its two normal CDFs a node are most of a pass)
    keep_k = score and kern.half > 0.0
    krs: list[FloatArray | None] = []
    psi, lw = _nodes(m, reach, lo, hi, cuts)
    ln, kr1 = _log_integrand(psi, lw, yy, c, A, kern, cc, cs, uni, cw, keep_k)
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
        cj = cuts[j] if cuts is not None else None
        psi2, lw2 = _nodes(mean[j], _WINDOW * std[j], lo[j], hi[j], cj)
        ln2, kr2 = _log_integrand(psi2, lw2, yy[j], c, A, kern, cc[j], cs[j], uni[j], cw[j], keep_k)
        r2, p2, s2sum = _piece_terms(ln2)
        with np.errstate(divide="ignore", invalid="ignore"):
            i1 = rmax[j] + np.log(psum[j])
            i2 = r2 + np.log(s2sum)
            agree = np.abs(i1 - i2) <= _AGREE
        ja, jd = j[agree], j[~agree]
        groups.append((ja, psi2[agree], r2[agree], p2[agree], s2sum[agree]))
        krs.append(kr2[agree] if kr2 is not None else None)
        if jd.size:
            reach_lo = np.maximum(
                lo[jd], np.minimum(m[jd] - reach[jd], mean[jd] - _WINDOW * std[jd])
            )
            reach_hi = np.minimum(
                hi[jd], np.maximum(m[jd] + reach[jd], mean[jd] + _WINDOW * std[jd])
            )
            psi3, lw3 = _even_nodes(reach_lo, reach_hi, cuts[jd] if cuts is not None else None)
            ln3, kr3 = _log_integrand(
                psi3, lw3, yy[jd], c, A, kern, cc[jd], cs[jd], uni[jd], cw[jd], keep_k
            )
            groups.append((jd, psi3, *_piece_terms(ln3)))
            krs.append(kr3)
    keep1 = np.flatnonzero(~off)
    if keep1.size == idx.size:
        groups.insert(0, (keep1, psi, rmax, pn, psum))
        krs.insert(0, kr1)
    else:
        groups.insert(0, (keep1, psi[keep1], rmax[keep1], pn[keep1], psum[keep1]))
        krs.insert(0, kr1[keep1] if kr1 is not None else None)
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
        logp = top + np.log(tot) + kern.const
    logp = np.where(np.isfinite(logp), logp, -np.inf)
    if not score:
        return _Chunk(logp, None)
    nj = 1 if len(comps) == 1 else 2
    S = np.zeros((n, nj + 5))
    cen_all = np.array([cp.centre_s for cp in comps])[ci]
    scale_all = np.array([cp.scale_s for cp in comps])[ci]
    sgn_all = np.array([cp.sign for cp in comps])[ci]
    second = np.zeros((nj + 5, nj + 5)) if info else None
    for (g_j, g_psi, _, g_p, _), sc, g_kr in zip(groups, scales, krs, strict=True):
        if g_j.size:
            gi = idx[g_j]
            grp = _Group(
                post=g_p * (sc / tot[gi])[:, None],
                psi=g_psi,
                gidx=gi,
                yy=yy[g_j],
                th=th[g_j],
                kT=k[gi] * T,
                cen=cen_all[g_j],
                scale=scale_all[g_j],
                sgn=sgn_all[g_j],
                w=w,
                A=A,
                c=c,
                kern=kern,
                kr=g_kr,
                nj=nj,
                dj2=dj2 and nj == 2 and mix is None,
                mix=mix,
            )
            terms = _score_group(S, grp, full=second is not None)
            if second is not None:
                assert terms is not None
                second += _second_group(grp, terms)
    return _Chunk(logp, S, second)


def _mode_derivatives(
    kern: Kernel,
    e: FloatArray,
    A: float,
    sn: FloatArray,
    co: FloatArray,
    prec_p: FloatArray,
    u: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """(l', l'') of a piece's log-integrand in psi at its mode's iterate: the kernel's
    k1 de/dpsi and k2 (de/dpsi)^2 + k1 d2e/dpsi2 (de/dpsi = -A cos psi, d2e/dpsi2 = A sin
    psi), with a Gaussian prior's -prec_p u and -prec_p (u the offset from its centre)."""
    k1, k2 = kern.mode_terms(e)
    return -k1 * A * co - prec_p * u, k2 * (A * co) ** 2 + k1 * A * sn - prec_p


def _score_group(S: FloatArray, grp: _Group, full: bool = False) -> _NodeTerms | None:
    """Add the module doc's score terms of one group of pieces to S (per sample), with the
    posterior weights ``grp.post`` at their nodes ``grp.psi``; with ``full``, return what
    the information reads at the nodes (:class:`_NodeTerms`: the noise kernel's first and
    second derivatives, :meth:`~jitterid.metrology.sinelik_kernel.Kernel.second`, and the
    nodes' sin and cos, so that they are not computed twice)."""
    post, psi, gidx, yy, th = grp.post, grp.psi, grp.gidx, grp.yy, grp.th
    w, A, c, kern, nj = grp.w, grp.A, grp.c, grp.kern, grp.nj
    n = S.shape[0]
    sn = np.sin(psi)
    e = A * sn
    np.subtract(yy[:, None] - c, e, out=e)
    sum_p = post.sum(axis=1)
    # pk = post x (-d ln K / de) (e / sigma^2 for Gaussian noise); the noise std's column
    # E[d ln K / d sigma]
    terms = kern.second(e, grp.kr) if full else None
    if terms is not None:
        k1, ks = terms[3], terms[4]
        pk = -post * k1
        sig_col = np.einsum("ij,ij->i", post, ks)
    elif kern.half == 0.0:
        sigma = kern.sigma
        pk = post * e
        pk /= sigma * sigma
        sig_col = np.einsum("ij,ij->i", pk, e) / sigma - sum_p / sigma
    else:
        k1, ks = kern.first(e, grp.kr)
        pk = -post * k1
        sig_col = np.einsum("ij,ij->i", post, ks)
    co = np.cos(psi)
    pd = co * pk
    pd *= A  # post x D
    sum_pd = pd.sum(axis=1)
    pd_tau = (np.einsum("ij,ij->i", pd, psi) - th * sum_pd) / w  # E[D tau]
    cols = [w * (pd_tau - grp.cen * sum_pd) / grp.scale]
    if grp.mix is not None:  # sigma at a fixed standard variable (tau / sigma), rho^2 at a
        # fixed jitter (its law's score, :func:`_mixture_terms`)
        sig_m = grp.mix[0]
        g_u = _mixture_terms((psi - th[:, None]) / w, *grp.mix, False)[0][1]
        cols = [w * pd_tau / sig_m, np.einsum("ij,ij->i", post, g_u)]
    elif nj == 2:
        cols.append(w * 0.5 * grp.sgn * sum_pd)
    if grp.dj2:  # d / d(dj^2) = (d / d dj) / (2 dj), where dj resolves it
        dj = 2.0 * float(np.abs(grp.cen[0]))
        if dj >= _DJ_RATIO * float(grp.scale[0]):
            cols[1] = cols[1] / (2.0 * dj)
        else:  # at a fixed jitter, the law's own derivative (smooth at dj = 0)
            gl, _ = _dual_dirac_terms((psi - th[:, None]) / w, grp.scale[0], grp.cen, False)
            cols[1] = np.einsum("ij,ij->i", post, gl[1])
    cols += [
        np.einsum("ij,ij->i", pk, sn),
        sum_pd,
        2 * math.pi * (pd_tau + grp.kT * sum_pd),
        pk.sum(axis=1),
        sig_col,
    ]
    for col, v in enumerate(cols):
        S[:, col] += np.bincount(gidx, weights=v, minlength=n)
    return None if terms is None else _NodeTerms(terms, sn, co)


def _outer_sum(S: FloatArray) -> FloatArray:
    """S^T S (BLAS's matmul can raise spurious floating-point flags on tall, thin arrays:
    the flags are ignored and the sum checked instead)."""
    with np.errstate(over="ignore", invalid="ignore"):
        out = S.T @ S
    if not np.all(np.isfinite(out)):  # pragma: no cover - a real overflow
        out = np.einsum("ki,kj->ij", S, S)
    return np.asarray(out)


def _second_group(grp: _Group, nodes: _NodeTerms) -> FloatArray:
    """sum_j pi_j (d2 ln f_j + g_j g_j^T) over one group's nodes, with ln f = ln K(e) (the
    noise kernel: -e^2 / (2 sigma^2) - ln sigma + const for Gaussian noise) + (the law's,
    free of x at a fixed standard variable),
    e = y - c - A sin psi, psi = theta_k + w (mu + r xi): d psi / d(scale) = w xi, d psi /
    d dj = w s / 2, d psi / d phi = 1, d psi / d f = 2 pi (kT + tau), d2 psi / d f d(scale)
    = 2 pi xi, d2 psi / d f d dj = pi s.

    On the rows whose node gradient is g = k1 de (the sine's, and the law's where they
    move psi; k1 = d ln K / de of the noise kernel, -e / sigma^2 for Gaussian noise:
    :mod:`jitterid.metrology.sinelik_kernel`) g g^T and the first term of d2 ln f = k2 de
    de^T + k1 d2e are one product, de diag(pi (k1^2 + k2)) de^T; k1 d2e's A sin psi dpsi
    dpsi^T only on the rows where psi moves (the phase, frequency and, unless at a fixed
    jitter, the law's); the other rows (the noise std's, the law's at a fixed jitter) by
    their own thin products."""
    post, psi, th, w = grp.post, grp.psi, grp.th, grp.w
    A, nj = grp.A, grp.nj
    P = nj + 5
    iA, iphi, ifr, ic, isg = nj, nj + 1, nj + 2, nj + 3, nj + 4
    terms = nodes.kernel
    sn, co = nodes.sin.ravel(), nodes.cos.ravel()
    pw = post.ravel()
    tau2 = (psi - th[:, None]) / w
    tau = tau2.ravel()
    xi = ((tau2 - grp.cen[:, None]) / grp.scale[:, None]).ravel()
    kT = np.repeat(grp.kT, psi.shape[1])
    sg = np.repeat(grp.sgn, psi.shape[1])
    fixed = grp.dj2 or grp.mix is not None  # the law's columns at a fixed jitter
    # the rows where psi moves: the law's (unless at a fixed jitter), the phase, the frequency
    ph = ([] if fixed else list(range(nj))) + [iphi, ifr]
    dpsi = np.empty((len(ph), psi.size))
    if not fixed:
        dpsi[0] = w * xi
        if nj == 2:
            dpsi[1] = 0.5 * w * sg
    dpsi[-2] = 1.0
    dpsi[-1] = 2 * math.pi * (kT + tau)
    live = pw > 0  # nodes of empty panels carry no weight (and may be far off)
    pw = np.where(live, pw, 0.0)
    # the rows with g = k1 de (de: d e / dx; 0 on the others)
    data = [*ph, iA, ic]
    de = np.empty((len(data), psi.size))
    de[: len(ph)] = dpsi * (-A * co)
    de[-2] = -sn
    de[-1] = -1.0
    # the kernel's derivatives at the nodes (``terms``: Kernel.second's, by the score; 0 at
    # the empty panels' nodes); pk = pi (-k1)
    k2, kss, k1s, k1, ks = (np.where(live, t.ravel(), 0.0) for t in terms)
    pk = -pw * k1
    out = np.zeros((P, P))
    # (BLAS's matmul may raise spurious floating-point flags on these shapes: the sums
    # are checked for finiteness by the caller instead)
    with np.errstate(over="ignore", invalid="ignore"):
        out[np.ix_(data, data)] = (de * (pw * (k1 * k1 + k2))) @ de.T
        # e d2e: A sin psi dpsi dpsi^T ...
        out[np.ix_(ph, ph)] -= (dpsi * (pk * A * sn)) @ dpsi.T
        # ... d2e / dA dpsi = -cos psi dpsi (matrix-vector products: no k x M temporaries)
        pco = pk * co
        cross = -(dpsi @ pco)
        out[iA, ph] -= cross
        out[ph, iA] -= cross
        if not fixed:  # ... and -A cos psi d2psi: d2psi/df d(scale) = 2 pi xi, /df ddj = pi s
            fs = -A * 2 * math.pi * float(pco @ xi)
            out[ifr, 0] -= fs
            out[0, ifr] -= fs
            if nj == 2:
                fd = -A * math.pi * float(pco @ sg)
                out[ifr, 1] -= fd
                out[1, ifr] -= fd
        # the other rows' g: the noise std's (and the law's at a fixed jitter)
        others = [isg]
        g_o = [ks]
        law2 = None
        if fixed:
            if grp.mix is not None:
                gl, hl = _mixture_terms(tau, *grp.mix, True)
            else:
                gl, hl = _dual_dirac_terms(tau, grp.scale[0], grp.cen, True)
            others += [0, 1]
            g_o += [np.where(live, gl[0].ravel(), 0.0), np.where(live, gl[1].ravel(), 0.0)]
            assert hl is not None
            law2 = _weighted_sums(hl, pw, live)
        G_o = np.array(g_o) * pw
        cross_o = (G_o * k1) @ de.T  # (others, data) of g g^T
        out[np.ix_(others, data)] += cross_o
        out[np.ix_(data, others)] += cross_o.T
        out[np.ix_(others, others)] += G_o @ np.array(g_o).T
    # the noise std's row of d2 ln f: d2/dsigma^2 = kss, d2/dsigma dx = k1s de (Gaussian:
    # -3 e^2 / sigma^4 + 1 / sigma^2 and 2 e de / sigma^3)
    row = de @ (pw * k1s)
    out[isg, data] += row
    out[data, isg] += row
    out[isg, isg] += float(np.sum(pw * kss))
    if law2 is not None:  # the law's own second derivatives (at a fixed jitter)
        out[:2, :2] += law2
    return out


def _weighted_sums(
    hl: list[list[FloatArray]], pw: FloatArray, live: NDArray[np.bool_]
) -> FloatArray:
    """sum_j pw_j h_j for each array h of the symmetric 2 x 2 ``hl`` (the law's second
    derivatives at the nodes; the off-diagonal summed once): one dot product each, the
    nodes that carry no weight (``live`` False, ``pw`` 0 there) masked only where a value
    there is not finite."""
    out = np.empty((2, 2))
    for i, j in ((0, 0), (0, 1), (1, 1)):
        h = hl[i][j].ravel()
        v = float(pw @ h)
        if not math.isfinite(v):
            v = float(pw @ np.where(live, h, 0.0))
        out[i, j] = out[j, i] = v
    return out


def _mixture_polys(kmax: int) -> list[np.polynomial.Polynomial]:
    """Q_0 .. Q_kmax: d^k N(tau; v) / dv^k = N v^-k Q_k(z), z = tau^2 / v (N the Gaussian
    density of variance v): Q_0 = 1, Q_{k+1} = -k Q_k - z Q_k' + Q_k (z - 1) / 2."""
    z = np.polynomial.Polynomial([0.0, 1.0])
    out = [np.polynomial.Polynomial([1.0])]
    for k in range(kmax):
        q = out[-1]
        out.append(-k * q - z * q.deriv() + q * (z - 1.0) / 2.0)
    return out


#: Below this rho a scale mixture's u-derivatives (u = rho^2) come from the series
#: S(u, z) = sum_m u^m Q_2m(z) / (2m)! (terms to u^_MIX_TERMS; the closed form's divided
#: differences lose ~eps / rho^2 there).
_MIX_SERIES = 2e-3
_MIX_TERMS = 4
# the series' coefficients: row m holds Q_2m(z) / (2m)! in powers of z
_MIX_C = np.array(
    [
        np.pad(
            np.asarray(q.coef, dtype=float) / float(math.factorial(k)),
            (0, 2 * _MIX_TERMS + 1 - q.coef.size),
        )
        for k, q in enumerate(_mixture_polys(2 * _MIX_TERMS))
        if k % 2 == 0
    ]
)


def _mixture_terms(
    tau: FloatArray, sigma: float, rho: float, squared: bool, second: bool
) -> tuple[list[FloatArray], list[list[FloatArray]] | None]:
    """A Gaussian scale mixture's ln p(tau) = ln N(tau; sigma^2) + ln S(u, z), u = rho^2,
    z = tau^2 / sigma^2, S = (phi(rho) + phi(-rho)) / 2, phi(r) = (1 + r)^(-1/2) exp(z r /
    (2 (1 + r))), differentiated at a fixed tau in sigma and u (``squared``) or rho::

        d / d sigma   = (z - 1 - 2 z S_z / S) / sigma
        d / d u       = S_u / S
        d2 / d sigma2 = (1 - 3 z + 6 z S_z / S + 4 z^2 (S_zz / S - (S_z / S)^2)) / sigma^2
        d2 / d sigma du = -2 z (S_uz / S - S_u S_z / S^2) / sigma
        d2 / d u2     = S_uu / S - (S_u / S)^2

    (in rho: d / d rho = 2 rho d / du, d2 / d rho2 = 4 rho^2 d2 / du2 + 2 d / du). S is even
    in rho, so analytic in u; below ``_MIX_SERIES`` its u-derivatives come from its series
    in u, above from the closed form (S_u = S_rho / (2 rho), S_uu = (S_rho,rho - S_rho /
    rho) / (4 rho^2)). Returns the two first derivatives and, with ``second``, the 2 x 2
    second derivatives, at the nodes; without ``second`` the sigma derivative is left out
    (an empty array: the score takes it at a fixed standard variable, E[D w tau / sigma])."""
    z = (tau / sigma) ** 2
    S: FloatArray | float
    if rho < _MIX_SERIES:
        u = rho * rho
        m = np.arange(_MIX_C.shape[0], dtype=float)
        um = np.array([u**k for k in range(m.size)])
        dm = np.r_[0.0, um[:-1]] * m  # d u^m / du
        ddm = np.r_[0.0, 0.0, um[:-2]] * m * (m - 1.0)
        c_s, c_u, c_uu = um @ _MIX_C, dm @ _MIX_C, ddm @ _MIX_C
        deg = np.arange(c_s.size, dtype=float)

        def dz(c: FloatArray) -> FloatArray:  # the z-derivative's coefficients
            return np.r_[(c * deg)[1:], 0.0]

        def poly(c: FloatArray) -> FloatArray:  # sum_k c_k z^k, by Horner's rule
            acc = np.full(z.shape, c[-1])
            for ck in c[-2::-1]:
                acc *= z
                acc += ck
            return acc

        # (the score alone needs S and S_u: 2 of the 6 polynomials)
        S, Su = poly(c_s), poly(c_u)
        if second:
            Suu, Sz, Szz, Suz = poly(c_uu), poly(dz(c_s)), poly(dz(dz(c_s))), poly(dz(c_u))
    else:
        # per component r = +-rho (b = 1 + r): ln phi = al + c1 z, d ln phi / dz = c1 =
        # r / (2 b), d ln phi / dr = a1 = z / (2 b^2) - 1 / (2 b), d2 ln phi / dr2 = a2 =
        # 1 / (2 b^2) - z / b^3 (al, c1 scalars): the ratios to S are sums over the
        # components' weights W_r = phi_r / (2 S), W_+ = expit(ln phi_+ - ln phi_-)
        co = []
        for r in (rho, -rho):
            bb = 1.0 + r
            co.append((-0.5 * math.log(bb), r / (2.0 * bb), 0.5 / bb**2, -0.5 / bb, bb))
        (al_p, c_p, p_p, q_p, b_p), (al_m, c_m, p_m, q_m, b_m) = co
        w_p = special.expit((al_p - al_m) + (c_p - c_m) * z)  # W_+
        w_m = 1.0 - w_p
        a1_p, a1_m = p_p * z + q_p, p_m * z + q_m
        S = 1.0  # (the sums below are already ratios to S)
        Su = (w_p * a1_p - w_m * a1_m) / (2.0 * rho)
        if second:
            Sz = w_p * c_p + w_m * c_m
            a2_p = 0.5 / b_p**2 - z / b_p**3
            a2_m = 0.5 / b_m**2 - z / b_m**3
            Sr = 2.0 * rho * Su
            Srr = w_p * (a1_p * a1_p + a2_p) + w_m * (a1_m * a1_m + a2_m)
            Suu = (Srr - Sr / rho) / (4.0 * rho * rho)
            Szz = w_p * c_p * c_p + w_m * c_m * c_m
            Szr = w_p * (a1_p * c_p + 0.5 / b_p**2) - w_m * (a1_m * c_m + 0.5 / b_m**2)
            Suz = Szr / (2.0 * rho)
    Ru = Su / S
    g_u = Ru
    if not second:  # (the score's sigma column is taken at a fixed standard variable)
        return [np.empty(0), g_u if squared else 2.0 * rho * g_u], None
    Rz = Sz / S
    g_s = (z - 1.0 - 2.0 * z * Rz) / sigma
    h_ss = (1.0 - 3.0 * z + 6.0 * z * Rz + 4.0 * z * z * (Szz / S - Rz * Rz)) / sigma**2
    h_su = -2.0 * z * (Suz / S - Ru * Rz) / sigma
    h_uu = Suu / S - Ru * Ru
    if squared:
        return [g_s, g_u], [[h_ss, h_su], [h_su, h_uu]]
    h_sr = 2.0 * rho * h_su
    h_rr = 4.0 * rho * rho * h_uu + 2.0 * g_u
    return [g_s, 2.0 * rho * g_u], [[h_ss, h_sr], [h_sr, h_rr]]


def _tanhc_terms(x: FloatArray, second: bool) -> tuple[FloatArray, FloatArray, FloatArray]:
    """tanh(x) / x, (with ``second``) h(x) = (x sech^2 x - tanh x) / x^3 (d tanhc / dx =
    x h) and sech^2 x, smooth at 0 (series below |x| = 0.05: error < 1e-10); one tanh."""
    small = np.abs(x) < 0.05
    xs = np.where(small, 1.0, x)
    t = np.tanh(xs) if not np.all(small) else xs
    x2 = x * x
    tc = np.where(small, 1.0 - x2 * (1.0 / 3.0 - x2 * (2.0 / 15.0)), t / xs)
    if not second:
        return tc, tc, tc
    sech2 = np.where(small, 1.0 - x2 * tc * tc, 1.0 - t * t)
    h = np.where(
        small,
        -2.0 / 3.0 + x2 * (8.0 / 15.0 - x2 * (34.0 / 105.0)),
        (xs * sech2 - t) / (xs * xs * xs),
    )
    return tc, h, sech2


def _dual_dirac_terms(
    tau: FloatArray, rj: float, cen: FloatArray, second: bool
) -> tuple[list[FloatArray], list[list[FloatArray]] | None]:
    """The dual Dirac's ln p(tau) = -ln rj - (tau^2 + d^2) / (2 rj^2) + ln cosh(tau d /
    rj^2) + const (d = dj / 2), differentiated in rj and u = dj^2 at a fixed tau: smooth
    and even in dj, so a search in u sees the flat dj = 0 as a regular quadratic (x = tau
    d / rj^2)::

        d / d rj   = -1 / rj + (tau^2 + d^2) / rj^3 - 2 x tanh(x) / rj
        d / d u    = (-1 / (2 rj^2) + tau^2 tanhc(x) / (2 rj^4)) / 4
        d2 / d rj2 = 1 / rj^2 - 3 (tau^2 + d^2) / rj^4 + (6 x tanh x + 4 x^2 sech^2 x) / rj^2
        d2 / d rj du = (1 / rj^3 - (tau^2 / rj^5) (x^2 h(x) + 2 tanhc(x))) / 4
        d2 / d u2  = tau^4 h(x) / (4 rj^8) / 16

    ``tau`` the nodes' jitter (pieces, nodes), ``cen`` the pieces' component centres (+-d):
    d = |cen|. Returns the two first derivatives and, with ``second``, the 2 x 2 second
    derivatives, at the nodes."""
    dd = np.abs(cen)
    d: FloatArray | float
    if dd.size and np.all(dd == dd[0]):  # (the two components' |centre| is dj / 2)
        d = float(dd[0])
    elif np.ndim(tau) == 2:
        d = dd[:, None]
    else:  # flattened nodes (the information's): d per node
        d = np.repeat(dd, tau.size // max(dd.size, 1))
    r2 = rj * rj
    x = tau * (d / r2)
    tc, h, sech2 = _tanhc_terms(x, second)
    xt = x * x * tc  # x tanh x
    t2 = tau * tau
    g_r = (t2 + d * d) / (r2 * rj) - 2.0 * xt / rj - 1.0 / rj
    g_u = t2 * tc * (0.125 / (r2 * r2)) - 0.125 / r2
    if not second:
        return [g_r, g_u], None
    h_rr = 1.0 / r2 - 3.0 * (t2 + d * d) / (r2 * r2) + (6.0 * xt + 4.0 * x * x * sech2) / r2
    h_ru = 0.25 * (1.0 / (r2 * rj) - (t2 / (r2 * r2 * rj)) * (x * x * h + 2.0 * tc))
    h_uu = (t2 * t2 * h / (4.0 * r2**4)) / 16.0
    return [g_r, g_u], [[h_rr, h_ru], [h_ru, h_uu]]


def _even_nodes(
    lo: FloatArray, hi: FloatArray, cuts: FloatArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and ln weights of _FINE equal panels over [lo, hi] (cut at
    ``cuts`` too, (pieces, k), where inside)."""
    edges = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, _FINE + 1)[None, :]
    return _panel_nodes(_with_cuts(edges, cuts))


def _nodes(
    m: FloatArray,
    reach: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    cuts: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and ln weights of the four panels m + reach [-1, -1/3, 0,
    1/3, 1] cut to [lo, hi] (and at ``cuts``, (pieces, k), where inside), shape (pieces,
    panels x _ORDER) (-inf on empty panels)."""
    edges = m[:, None] + reach[:, None] * _CUTS[None, :]
    edges = np.clip(edges, lo[:, None], hi[:, None])
    return _panel_nodes(_with_cuts(edges, cuts))


def _with_cuts(edges: FloatArray, cuts: FloatArray | None) -> FloatArray:
    """``edges`` (pieces, e) with ``cuts`` (pieces, k) clipped to their span added, sorted
    (a cut outside the span adds an empty panel)."""
    if cuts is None:
        return edges
    extra = np.clip(cuts, edges[:, :1], edges[:, -1:])
    return np.sort(np.concatenate([edges, extra], axis=1), axis=1)


#: a bin kernel's panels are cut at each edge and this many of its falloff widths either side
_BIN_REACH = 4.0
#: ... where sigma is below these fractions of the step: the edges (below _BIN_EDGES; above
#: it the kernel is smooth on the panels' scale), and their falloff's ends (below
#: _BIN_FALLS; measured ln p within 3e-9 with the edges alone at sigma = 0.2 q, 1.4e-6 at
#: 0.04 q, 2e-8 with the falloffs' ends at 0.002 q)
_BIN_EDGES = 1.0
_BIN_FALLS = 0.1


def _bin_cuts(kern: Kernel, yy: FloatArray, c: float, A: float, b: FloatArray) -> FloatArray | None:
    """A bin kernel's edges on each piece's branch b (psi_e where y - c - A sin psi =
    -+ q/2: b pi + (-1)^b asin z) and psi_e -+ _BIN_REACH sigma / (A |cos psi_e|), where its
    falloff over sigma ends, shape (pieces, 6) (the edges alone, (pieces, 2), for sigma
    from _BIN_FALLS q; None from _BIN_EDGES q, and for the Gaussian kernel). (Panels that
    end there see the kernel smooth: as sigma goes to 0 it is a step.)"""
    q = 2.0 * kern.half
    if kern.half == 0.0 or kern.sigma >= _BIN_EDGES * q:
        return None
    sign = np.where(np.mod(b, 2.0) != 0, -1.0, 1.0)
    z = np.clip(np.stack(kern.edges(yy, c, A), axis=1), -1.0, 1.0)
    root = (b * math.pi)[:, None] + sign[:, None] * np.arcsin(z)
    if kern.sigma >= _BIN_FALLS * q:
        return root
    with np.errstate(divide="ignore"):
        fall = _BIN_REACH * kern.sigma / (A * np.sqrt(np.maximum(1.0 - z * z, 0.0)))
    fall = np.minimum(fall, math.pi)  # (at a turning point: no finite width)
    return np.concatenate([root, root - fall, root + fall], axis=1)


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
    kern: Kernel,
    cc: FloatArray,
    cs: FloatArray,
    uni: FloatArray,
    cw: FloatArray,
    keep: bool = False,
) -> tuple[FloatArray, FloatArray | None]:
    """ln(weight x integrand of (S1) without the kernel's constant ``kern.const``) at the
    nodes (-inf at the nodes of empty panels), and with ``keep`` a bin kernel's ln K there
    (:meth:`~jitterid.metrology.sinelik_kernel.Kernel.log_rel`; else None)."""
    e = A * np.sin(psi)
    np.subtract(yy[:, None] - c, e, out=e)
    kr = None
    if kern.half == 0.0:
        ln = e * e
        ln *= -0.5 / kern.sigma**2
    else:
        ln = kern.log_rel(e)
        kr = ln.copy() if keep else None
    q = np.where(uni, 0.0, 0.5 / cs**2)
    const = np.log(cw) + np.where(uni, -np.log(2 * cs), -np.log(cs) - _LN_SQRT_2PI)
    u = psi - cc[:, None]
    u *= u
    u *= q[:, None]
    ln -= u
    ln += lw
    ln += const[:, None]
    return ln, kr


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
