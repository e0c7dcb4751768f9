"""Sinusoidal signal models with no input: :class:`SineWave` (a sinusoid of unknown
amplitude, phase, frequency and offset, optionally with harmonics) and :class:`MultiTone`
(given frequencies, unknown amplitudes and phases): the paper's Section 3.4 signal, and the
sine-wave test of data converters and sampling oscilloscopes (IEEE 1057 / 1241).

Both are sums of tones s(t) = c + sum_h Im(a_h exp(i w_h t)), a_h = A_h exp(i phi_h), i.e.
A_h sin(w_h t + phi_h). Under jitter their moments are closed forms in the characteristic
function chi(w) = E[exp(i w tau)] (Lemma 1 in the time domain, notes section 1):

    m_k   = c + sum_h Im(a_h e^{i w_h kT} chi(w_h))                                     (S1)
    Var_k = sum_{h,g} Re(a_h conj(a_g) P-_hg - a_h a_g P+_hg) / 2 - (m_k - c)^2,        (S2)
            P-+_hg = e^{i (w_h -+ w_g) kT} chi(w_h -+ w_g),

with their derivatives through chi'(w) = E[i tau exp(i w tau)], and in a jitter family's
scale a (the law of a xi) through d chi(w) / da = (w / a) chi'(w). chi and chi' are
quadratures of the law at a handful of frequencies, once per evaluation, so the moments
cost O(N H^2) with no quadrature per sample (:meth:`ToneSignal.jitter_moments`); the
third and fourth moments (the exact covariance) take the generic quadrature path.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import positive
from ._sinefit import periodogram_peak, sine_fit_4
from .model import Bounds, Model, MomentPass, Signal

if TYPE_CHECKING:
    from ..data import SampledData
    from ..inputs import Input
    from ..jitter.laws import JitterLaw

__all__ = ["MultiTone", "SineWave", "ToneSignal"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
_FORMS = ("polar", "iq")
# Bytes of [cos; sin] bases kept by one ToneBases (the likelihood's frozen rule over a long
# record holds about as much in its nodes; past this the bases are computed, not kept).
_BASES_BUDGET = 256 * 2**20


@dataclass(frozen=True)
class _ToneMap:
    """theta -> (c, a_h, w_h) and their derivatives, one row per parameter."""

    c: float
    a: ComplexArray  # complex amplitudes a_h, shape (H,)
    w: FloatArray  # angular frequencies w_h (rad/s), shape (H,)
    dc: FloatArray  # (P,)
    da: ComplexArray  # (P, H)
    dw: FloatArray  # (P, H)
    # d^2 a_h: its nonzero entries {(i, j, h): value}, or dense, shape (P, P, H)
    d2a: dict[tuple[int, int, int], complex] | ComplexArray | None = None


class ToneBases:
    """The bases [cos(w_h t); sin(w_h t)] of fixed angular frequencies ``w`` at arrays of
    instants, kept while each array lives (a weak reference drops its basis with it), up to
    ``_BASES_BUDGET`` bytes: the signals of one input at many parameter values (the
    steady-state response to a multisine during a search over the likelihood's frozen
    quadrature rule) are evaluated at the same node arrays, and cos and sin are most of
    their cost. A kept basis is used only for the very array it was made for, unchanged
    (its size, end points and sum are checked); pickling keeps none.

    Parameters
    ----------
    w : ndarray, shape (H,)
        Angular frequencies in rad/s.
    last_only : bool, optional
        Keep the last basis only (one signal's own: the likelihood asks for s, its gradient,
        slope and second derivatives at the same nodes in turn).
    """

    def __init__(self, w: FloatArray, last_only: bool = False) -> None:
        self.w = np.array(w, dtype=float)
        self.last_only = bool(last_only)
        self._held: dict[int, tuple[Any, tuple[float, ...], FloatArray]] = {}
        self._bytes = 0

    def __reduce__(self) -> tuple[type, tuple[FloatArray, bool]]:
        return (ToneBases, (self.w, self.last_only))

    def basis(self, t: FloatArray) -> FloatArray:
        """[cos(w_h t); sin(w_h t)] at the instants ``t`` (1-D), shape (2H, n).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.

        Examples
        --------
        >>> import numpy as np
        >>> from jitterid.systems.tones import ToneBases
        >>> ToneBases(np.array([np.pi])).basis(np.array([0.0, 0.5])).round(12).tolist()
        [[1.0, 0.0], [0.0, 1.0]]
        """
        key = id(t)
        held = self._held.get(key)
        stamp = _stamp(t)
        if held is not None and held[0]() is t and held[1] == stamp:
            return held[2]
        H = self.w.size  # real arithmetic: numpy's complex exp is several times slower
        arg = self.w[:, None] * t[None, :]
        cs = np.empty((2 * H, t.size))
        np.cos(arg, out=cs[:H])
        np.sin(arg, out=cs[H:])
        if held is not None:
            self._drop(key)
        if self.last_only:
            for k in list(self._held):
                self._drop(k)
        if t.size >= 64 and self._bytes + cs.nbytes <= _BASES_BUDGET:
            ref = weakref.ref(t, partial(self._drop, key))
            self._held[key] = (ref, stamp, cs)
            self._bytes += cs.nbytes
        return cs

    def _drop(self, key: int, ref: Any = None) -> None:
        held = self._held.get(key)
        if held is not None and (ref is None or held[0] is ref):
            del self._held[key]
            self._bytes -= held[2].nbytes


def _stamp(t: FloatArray) -> tuple[float, ...]:
    """A check that an array of instants is unchanged: its size, end points and sum."""
    if not t.size:
        return (0.0,)
    return (float(t.size), float(t[0]), float(t[-1]), float(np.sum(t)))


class ToneSignal(Signal):
    """s(t) = c + sum_h Im(a_h exp(i w_h t)) at one parameter vector, with closed-form
    gradient, slope and jittered moments. ``bases``: a :class:`ToneBases` of the same
    frequencies shared with other signals (the responses to one input); by default the
    signal has its own, which keeps the last basis only."""

    def __init__(self, tones: _ToneMap, bases: ToneBases | None = None) -> None:
        self.tones = tones
        self.rate = float(max(np.max(np.abs(tones.w)), 1e-300))
        self.breaks = np.zeros(0)
        self.start, self.end = -np.inf, np.inf
        if bases is not None and not np.array_equal(bases.w, tones.w):
            raise ValueError("bases must be of the tones' own frequencies w")
        self._bases = bases if bases is not None else ToneBases(tones.w, last_only=True)

    def _phasors(self, t: FloatArray) -> ComplexArray:
        return np.exp(1j * self.tones.w[:, None] * t[None, :])  # (H, n)

    def _basis(self, t: FloatArray) -> FloatArray:
        """[cos(w_h t); sin(w_h t)], shape (2H, n), one array so that any Im(q z) or
        Re(q z), z = e^{i w t}, is one matrix product (:meth:`_im`): from the shared
        :class:`ToneBases` where there is one, else from the signal's own, which keeps the
        last."""
        return self._bases.basis(t)

    def _cos_sin(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """cos(w_h t), sin(w_h t), shape (H, n) each (views of :meth:`_basis`)."""
        cs = self._basis(t)
        H = self.tones.w.size
        return cs[:H], cs[H:]

    def _im(self, q: ComplexArray, t: FloatArray) -> FloatArray:
        """Im(sum_h q_h e^{i w_h t}) for coefficients ``q`` of shape (..., H): shape (..., n).
        Im(q z) = Im q cos + Re q sin."""
        coef = np.concatenate([q.imag, q.real], axis=-1)
        out = coef.reshape(-1, coef.shape[-1]) @ self._basis(t)
        return np.asarray(out.reshape(*q.shape[:-1], t.size), dtype=float)

    def _re(self, q: ComplexArray, t: FloatArray) -> FloatArray:
        """Re(sum_h q_h e^{i w_h t}), as :meth:`_im`: Re(q z) = Re q cos - Im q sin."""
        return self._im(1j * np.asarray(q), t)

    def __call__(self, t: ArrayLike) -> FloatArray:
        tt = np.asarray(t, dtype=float)
        flat = tt if tt.ndim == 1 else tt.ravel()  # the same t: the memo holds
        return (self.tones.c + self._im(self.tones.a, flat)).reshape(tt.shape)

    @property
    def has_gradient(self) -> bool:
        return True

    @property
    def has_slope(self) -> bool:
        return True

    def gradient(self, t: FloatArray) -> FloatArray:
        tn = self.tones
        # d Im(a_h e^{i w_h t}) = Im((da_h + i t a_h dw_h) e^{i w_h t})
        out = tn.dc[:, None] + self._im(tn.da, t)
        if np.any(tn.dw):  # no frequency parameter (an LTI response): no t-weighted term
            out += t[None, :] * self._re(tn.dw * tn.a[None, :], t)
        return out

    def slope(self, t: FloatArray) -> FloatArray:
        return self._re(self.tones.w * self.tones.a, t)  # Im(i w a z) = Re(w a z)

    def second_derivatives(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """d^2 s / dtheta^2, d s'/dtheta and s'' in closed form, in real arithmetic over the
        few nonzero entries. With z = e^{i w t} and s = c + Im(a z): d^2 s = Im(d2a z + i t
        (da dw^T + dw da^T) z - t^2 a dw dw^T z) (d2a nonzero only in the polar form: a = A
        e^{i phi}), ds' = Im(i (dw a + w da) z - t w a dw z), s'' = Im(-w^2 a z)."""
        tn = self.tones
        curv = self._im(-(tn.w**2) * tn.a, t)
        if not np.any(tn.dw) and not isinstance(tn.d2a, dict):
            # amplitudes only (an LTI response): d^2 s = Im(d2a z), ds' = Re(w da z)
            P, H = tn.da.shape
            hss = np.zeros((P, P, t.size)) if tn.d2a is None else self._im(tn.d2a, t)
            return hss, self._re(tn.w * tn.da, t), curv
        cos_, sin_ = self._cos_sin(t)
        P, H = tn.da.shape
        n = t.size
        hess = np.zeros((P, P, n))
        dsl = np.zeros((P, n))
        # Im(q z) = Re q sin + Im q cos; Re(q z) = Re q cos - Im q sin
        for h in range(H):
            c, s = cos_[h], sin_[h]
            a, w = tn.a[h], tn.w[h]
            im_az = a.real * s + a.imag * c
            re_az = a.real * c - a.imag * s
            ps = np.flatnonzero(tn.da[:, h])
            fs = np.flatnonzero(tn.dw[:, h])
            for p_ in ps:
                q = tn.da[p_, h]
                re_qz = q.real * c - q.imag * s
                # ds'/dtheta_p = Im(i w da z) = w Re(da z)
                dsl[p_] += w * re_qz
                for f_ in fs:  # d^2 s / dp df = Im(i t da dw z) = t dw Re(da z)
                    v = t * tn.dw[f_, h] * re_qz
                    hess[p_, f_] += v
                    hess[f_, p_] += v
            for f_ in fs:
                dw = tn.dw[f_, h]
                # ds'/df = Im(i dw a z) - t w dw Im(a z)... = dw Re(a z) - t w dw Im(a z)
                dsl[f_] += dw * re_az - t * w * dw * im_az
                for g_ in fs:
                    hess[f_, g_] -= t**2 * dw * tn.dw[g_, h] * im_az
        if isinstance(tn.d2a, dict):
            for (i, j, h), v in tn.d2a.items():
                hess[i, j] += v.real * sin_[h] + v.imag * cos_[h]
        elif tn.d2a is not None:
            hess += self._im(tn.d2a, t)
        return hess, dsl, curv

    def jitter_moments(
        self,
        jitter: JitterLaw,
        T: float,
        N: int,
        *,
        variance: bool = True,
        gradient: bool = False,
        scale: float | None = None,
        higher: bool = False,
    ) -> MomentPass | None:
        """m_k, Var_k and their derivatives by (S1)-(S2) (module doc); None with ``higher``
        (the third and fourth moments take the generic quadrature path)."""

        if higher:
            return None
        # a signed measure (a density's derivative, mass 0: jitterid.estimation.jacobians)
        # has the moments of moment_pass's sums, sum w s and sum w (s - m)^2, with its mass
        # where a law's is 1; its derivatives are not asked for (the node route if they are)
        mass = float(jitter.mass)
        if mass != 1.0 and (gradient or scale is not None):
            return None
        tn = self.tones
        H = tn.w.size
        t = np.arange(N, dtype=float) * T
        wm = tn.w[:, None] - tn.w[None, :]
        wp = tn.w[:, None] + tn.w[None, :]
        nus = np.concatenate([tn.w, wm.ravel(), wp.ravel()])
        chi, dchi = _chi(jitter, nus)  # E[e^{i nu tau}], E[i tau e^{i nu tau}]
        c1, c1d = chi[:H], dchi[:H]
        cm, cmd = chi[H : H + H * H].reshape(H, H), dchi[H : H + H * H].reshape(H, H)
        cp, cpd = chi[H + H * H :].reshape(H, H), dchi[H + H * H :].reshape(H, H)
        z = self._phasors(t)  # (H, N)
        E = z * c1[:, None]  # e^{i w t} chi(w)
        dev = np.imag(tn.a @ E)  # m - c (sum w (s - c))
        mean = tn.c * mass + dev
        var = dmean = dvar = scale_mean = scale_var = None
        aa_m = tn.a[:, None] * np.conj(tn.a)[None, :]
        aa_p = tn.a[:, None] * tn.a[None, :]
        zm = z[:, None, :] * np.conj(z)[None, :, :]  # e^{i (w_h - w_g) t}
        zp = z[:, None, :] * z[None, :, :]
        Pm, Pp = zm * cm[:, :, None], zp * cp[:, :, None]
        if variance:
            second = 0.5 * np.real(
                np.einsum("hg,hgn->n", aa_m, Pm) - np.einsum("hg,hgn->n", aa_p, Pp)
            )
            if mass == 1.0:
                var = np.maximum(second - dev**2, 0.0)
            else:  # sum w s^2 - 2 m sum w s + m^2 mass, sum w s^2 = c^2 mass + 2 c dev + second
                var = second + 2 * tn.c * dev + tn.c**2 * mass - mean**2 * (2 - mass)
        if gradient:
            # dE_h = dw_h (i t E_h + z_h chi'(w_h)); dP = (dw_h -+ dw_g)(i t P + z.. chi'(.))
            dEw = 1j * t[None, :] * E + z * c1d[:, None]  # per unit dw_h, (H, N)
            dmean = tn.dc[:, None] + np.imag(tn.da @ E + (tn.dw * tn.a[None, :]) @ dEw)
            if variance:
                dPm = 1j * t * Pm + zm * cmd[:, :, None]
                dPp = 1j * t * Pp + zp * cpd[:, :, None]
                rows = []
                for i in range(tn.dc.size):
                    da, dw = tn.da[i], tn.dw[i]
                    d_aam = (
                        da[:, None] * np.conj(tn.a)[None, :] + tn.a[:, None] * np.conj(da)[None, :]
                    )
                    d_aap = da[:, None] * tn.a[None, :] + tn.a[:, None] * da[None, :]
                    dwm = dw[:, None] - dw[None, :]
                    dwp = dw[:, None] + dw[None, :]
                    d2 = 0.5 * np.real(
                        np.einsum("hg,hgn->n", d_aam, Pm)
                        + np.einsum("hg,hgn->n", aa_m * dwm, dPm)
                        - np.einsum("hg,hgn->n", d_aap, Pp)
                        - np.einsum("hg,hgn->n", aa_p * dwp, dPp)
                    )
                    rows.append(d2 - 2 * dev * (dmean[i] - tn.dc[i]))
                dvar = np.array(rows).reshape(-1, N)
        if scale is not None:
            # d chi(nu) / da = (nu / a) chi'(nu): the law of a xi
            dE = z * (tn.w / scale * c1d)[:, None]
            scale_mean = np.imag(tn.a @ dE)
            if variance:
                dPm = zm * (wm / scale * cmd)[:, :, None]
                dPp = zp * (wp / scale * cpd)[:, :, None]
                d2 = 0.5 * np.real(
                    np.einsum("hg,hgn->n", aa_m, dPm) - np.einsum("hg,hgn->n", aa_p, dPp)
                )
                scale_var = d2 - 2 * dev * scale_mean
        return MomentPass(mean, var, dmean, dvar, scale_mean, scale_var)


def _chi(law: JitterLaw, nus: FloatArray) -> tuple[ComplexArray, ComplexArray]:
    """chi(nu) = E[e^{i nu tau}] and chi'(nu) = E[i tau e^{i nu tau}] by the law's own
    quadrature, with enough nodes per panel for the fastest oscillation."""
    lo, hi = law.support
    if not hi > lo:
        tau0 = float(lo)
        e = np.exp(1j * nus * tau0)
        return e, 1j * tau0 * e
    bp = np.asarray(law.breakpoints(), dtype=float)
    widest = float(np.max(np.diff(bp))) if bp.size > 1 else hi - lo
    order = int(min(max(64, 0.75 * float(np.max(np.abs(nus))) * widest + 32), 4096))
    vals = law.expect(
        lambda tau: np.concatenate(
            [np.exp(1j * np.outer(nus, tau)), 1j * tau * np.exp(1j * np.outer(nus, tau))]
        ),
        nodes_per_panel=order,
    )
    vals = np.asarray(vals)
    return vals[: nus.size], vals[nus.size :]


# ------------------------------------------------------------------------------ the models
def _polar_second(a: ComplexArray, unit: ComplexArray) -> dict[tuple[int, int, int], complex]:
    """The nonzero d^2 a_h of the polar form, parameters (A_h, phi_h) at (2h, 2h + 1):
    d^2 a / dA dphi = i e^{i phi}, d^2 a / dphi^2 = -a."""
    out: dict[tuple[int, int, int], complex] = {}
    for h in range(a.size):
        out[(2 * h, 2 * h + 1, h)] = out[(2 * h + 1, 2 * h, h)] = 1j * complex(unit[h])
        out[(2 * h + 1, 2 * h + 1, h)] = -complex(a[h])
    return out


def _frequency_bounds(band_hz: tuple[float, float] | None) -> tuple[float, float]:
    if band_hz is None:
        return (0.0, np.inf)
    try:
        lo, hi = (float(v) for v in band_hz)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"band_hz must be a pair (low, high) in Hz; got {band_hz!r}") from exc
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
        raise ValueError(f"band_hz must satisfy 0 <= low < high < inf (Hz); got {band_hz!r}")
    return (lo, hi)


def _linear_tones(y: FloatArray, t: FloatArray, w: FloatArray) -> tuple[float, ComplexArray]:
    """Least-squares offset and complex amplitudes of tones at known w (IEEE 1057's
    three-parameter fit, one cos/sin pair per tone)."""
    cols = [np.ones_like(t)]
    for wh in w:
        cols += [np.cos(wh * t), np.sin(wh * t)]
    coef = np.linalg.lstsq(np.column_stack(cols), y, rcond=None)[0]
    cos_, sin_ = coef[1::2], coef[2::2]
    return float(coef[0]), sin_ + 1j * cos_  # a cos + b sin = Im((b + i a) e^{i w t})


@dataclass(frozen=True, eq=False)
class SineWave(Model):
    """A sinusoid with no input, s(t) = offset + sum_h A_h sin(2 pi h f t + phi_h).

    Parameters
    ----------
    frequency_hz : float, optional
        A known frequency in Hz (coherent sampling from a known source): it is then not a
        parameter. Default None: the frequency is estimated (parameter ``frequency_hz``).
    harmonics : int
        Number of harmonics h = 1..harmonics (1: a pure sinusoid).
    form : {"polar", "iq"}
        ``"polar"``: parameters ``amplitude``, ``phase_rad`` (and ``amplitude_h``,
        ``phase_rad_h`` for h >= 2), A_h sin(w_h t + phi_h); ``"iq"``: ``in_phase``,
        ``quadrature`` (``in_phase_h``, ``quadrature_h``), I_h cos(w_h t) + Q_h sin(w_h t).
        The in-phase/quadrature form is linear in its amplitudes (better conditioned when an
        amplitude may be near zero).
    band_hz : (float, float), optional
        Bounds on the estimated frequency in Hz; may lie above the Nyquist frequency
        1/(2T) (equivalent-time sampling). Default (0, inf). The starting frequency is the
        periodogram's peak refined by the four-parameter sine fit
        (:func:`jitterid.metrology.sinefit.sine_fit_4`), folded into the band: every alias
        f0 + m/T or m/T - f0 in the band is a start (without jitter the aliases fit the
        samples equally well; see :func:`jitterid.measure_jitter` to tell them apart).

    Notes
    -----
    Time is measured from the first sample, t = kT. The jittered moments are closed forms
    in the jitter's characteristic function (module doc, (S1)-(S2)).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> model = ji.SineWave()
    >>> model.param_names
    ('amplitude', 'phase_rad', 'frequency_hz', 'offset')
    >>> s = model.signal([2.0, 0.0, 0.25, 0.5])
    >>> s(np.array([0.0, 1.0]))
    array([0.5, 2.5])
    """

    frequency_hz: float | None = None
    harmonics: int = 1
    form: str = "polar"
    band_hz: tuple[float, float] | None = None

    uses_input = False

    def __post_init__(self) -> None:
        if self.frequency_hz is not None:
            object.__setattr__(self, "frequency_hz", positive(self.frequency_hz, "frequency_hz"))
        if isinstance(self.harmonics, bool) or not isinstance(self.harmonics, (int, np.integer)):
            raise TypeError(f"harmonics must be a whole number >= 1; got {self.harmonics!r}")
        if not 1 <= self.harmonics <= 64:
            raise ValueError(f"harmonics must lie in 1..64; got {self.harmonics}")
        if self.form not in _FORMS:
            raise ValueError(f"form must be one of {_FORMS}; got {self.form!r}")
        band = _frequency_bounds(self.band_hz)
        if self.band_hz is not None:
            object.__setattr__(self, "band_hz", band)
        if self.frequency_hz is not None and self.band_hz is not None:
            raise ValueError("give either frequency_hz (known) or band_hz (estimated), not both")

    # ---------------------------------------------------------------- layout
    def _suffix(self, h: int) -> str:
        return "" if h == 1 else f"_{h}"

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        pair = ("amplitude", "phase_rad") if self.form == "polar" else ("in_phase", "quadrature")
        names: list[str] = []
        for h in range(1, self.harmonics + 1):
            names += [p + self._suffix(h) for p in pair]
        if self.frequency_hz is None:
            names.append("frequency_hz")
        return (*names, "offset")

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        free = (-np.inf, np.inf)
        out = [free] * (2 * self.harmonics)
        if self.frequency_hz is None:
            lo, hi = _frequency_bounds(self.band_hz)
            out.append((max(lo, 1e-300), hi))
        return (*out, free)

    @property
    def gain_params(self) -> tuple[int, ...]:
        H = self.harmonics
        amps = tuple(range(0, 2 * H, 2)) if self.form == "polar" else tuple(range(2 * H))
        return (*amps, len(self.param_names) - 1)

    def tones(self, params: ArrayLike) -> _ToneMap:
        """theta -> (offset c, complex amplitudes a_h, angular frequencies w_h in rad/s),
        with their derivatives with respect to the parameters.

        Parameters
        ----------
        params : array_like
            The model's parameters, in :attr:`param_names` order.
        """
        x = self._check(params)
        H, P = self.harmonics, x.size
        f = self.frequency_hz if self.frequency_hz is not None else float(x[2 * H])
        h = np.arange(1, H + 1)
        w = np.asarray(2 * np.pi * f * h, dtype=float)
        da = np.zeros((P, H), complex)
        dw = np.zeros((P, H))
        dc = np.zeros(P)
        dc[-1] = 1.0
        d2a: dict[tuple[int, int, int], complex] | None = None
        if self.form == "polar":
            A, ph = x[0 : 2 * H : 2], x[1 : 2 * H : 2]
            a = A * np.exp(1j * ph)
            da[2 * h - 2, h - 1] = np.exp(1j * ph)
            da[2 * h - 1, h - 1] = 1j * a
            d2a = _polar_second(a, np.exp(1j * ph))
        else:
            inph, quad = x[0 : 2 * H : 2], x[1 : 2 * H : 2]
            a = quad + 1j * inph
            da[2 * h - 2, h - 1] = 1j
            da[2 * h - 1, h - 1] = 1.0
        if self.frequency_hz is None:
            dw[2 * H] = 2 * np.pi * h
        return _ToneMap(float(x[-1]), a.astype(complex), w, dc, da, dw, d2a)

    def signal(self, params: ArrayLike, u: Input | None = None) -> ToneSignal:
        """s(t; params); ``u`` is ignored (the model has no input).

        Parameters
        ----------
        params : array_like
            The model's parameters, in :attr:`param_names` order.
        u : Input, optional
            Unused: a signal model has no input.
        """
        return ToneSignal(self.tones(params))

    # ---------------------------------------------------------------- starts
    def start_frequencies(self, data: SampledData) -> list[float]:
        """The starting frequencies in Hz: the known one, or the four-parameter fit's at the
        periodogram's peak, with every alias inside ``band_hz``.

        Parameters
        ----------
        data : SampledData
            The data to be fitted.
        """
        if self.frequency_hz is not None:
            return [float(self.frequency_hz)]
        y, T = np.asarray(data.y, dtype=float), float(data.T)
        t = np.arange(y.size, dtype=float) * T
        fit4 = sine_fit_4(y, t, periodogram_peak(y, T))
        f0 = abs(float(fit4.frequency)) if fit4.converged else periodogram_peak(y, T)
        base = f0 % (1 / T)
        lo, hi = _frequency_bounds(self.band_hz)
        if self.band_hz is None:
            return [f0]
        cands: list[float] = []
        for m in range(int(np.floor(lo * T)) - 1, int(np.ceil(hi * T)) + 2):
            for f in (m / T + base, m / T - base):
                if lo <= f <= hi and f > 0 and all(abs(f - g) > 1e-9 / T for g in cands):
                    cands.append(f)
        if not cands:
            raise ValueError(
                f"no alias of the record's frequency {base:g} Hz (+ m/T, T = {T:g} s) lies in "
                f"band_hz = {self.band_hz}; widen the band or check T"
            )
        return sorted(cands)

    def initial_points(self, data: SampledData) -> list[FloatArray]:
        y, T = np.asarray(data.y, dtype=float), float(data.T)
        t = np.arange(y.size, dtype=float) * T
        out = []
        for f in self.start_frequencies(data):
            h = np.arange(1, self.harmonics + 1)
            c, a = _linear_tones(y, t, np.asarray(2 * np.pi * f * h, dtype=float))
            pairs = np.column_stack(
                [np.abs(a), np.angle(a)] if self.form == "polar" else [a.imag, a.real]
            ).ravel()
            freq = [f] if self.frequency_hz is None else []
            out.append(np.array([*pairs, *freq, c]))
        return out


@dataclass(frozen=True, eq=False)
class MultiTone(Model):
    """Tones at given frequencies with unknown amplitudes and phases and an offset:
    s(t) = offset + sum_j A_j sin(2 pi f_j t + phi_j).

    Parameters
    ----------
    frequencies_hz : sequence of float
        The tones' frequencies in Hz (distinct, > 0; may lie above the Nyquist frequency).
    form : {"polar", "iq"}
        As for :class:`SineWave`: ``amplitude_j``, ``phase_rad_j`` or ``in_phase_j``,
        ``quadrature_j``, j = 1..J.

    Examples
    --------
    >>> import jitterid as ji
    >>> ji.MultiTone([0.1, 0.3]).param_names
    ('amplitude_1', 'phase_rad_1', 'amplitude_2', 'phase_rad_2', 'offset')
    """

    frequencies_hz: Sequence[float]
    form: str = "polar"

    uses_input = False

    def __post_init__(self) -> None:
        try:
            f = np.atleast_1d(np.asarray(self.frequencies_hz, dtype=float))
        except (TypeError, ValueError) as exc:
            raise ValueError(
                "frequencies_hz must be a sequence of frequencies in Hz; got "
                f"{self.frequencies_hz!r}"
            ) from exc
        if f.ndim != 1 or f.size < 1 or not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise ValueError(
                f"frequencies_hz must hold one or more finite frequencies > 0 Hz; got {f}"
            )
        if np.unique(f).size != f.size:
            raise ValueError(f"frequencies_hz must be distinct; got {f}")
        if self.form not in _FORMS:
            raise ValueError(f"form must be one of {_FORMS}; got {self.form!r}")
        object.__setattr__(self, "frequencies_hz", tuple(float(v) for v in f))

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        pair = ("amplitude", "phase_rad") if self.form == "polar" else ("in_phase", "quadrature")
        names = [f"{p}_{j}" for j in range(1, len(self.frequencies_hz) + 1) for p in pair]
        return (*names, "offset")

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        return tuple((-np.inf, np.inf) for _ in self.param_names)

    @property
    def gain_params(self) -> tuple[int, ...]:
        J = len(self.frequencies_hz)
        amps = tuple(range(0, 2 * J, 2)) if self.form == "polar" else tuple(range(2 * J))
        return (*amps, 2 * J)

    def tones(self, params: ArrayLike) -> _ToneMap:
        """theta -> (offset c, complex amplitudes a_h, angular frequencies w_h in rad/s),
        with their derivatives with respect to the parameters.

        Parameters
        ----------
        params : array_like
            The model's parameters, in :attr:`param_names` order.
        """
        x = self._check(params)
        J, P = len(self.frequencies_hz), x.size
        j = np.arange(J)
        w = 2 * np.pi * np.asarray(self.frequencies_hz)
        da = np.zeros((P, J), complex)
        dc = np.zeros(P)
        dc[-1] = 1.0
        d2a: dict[tuple[int, int, int], complex] | None = None
        if self.form == "polar":
            a = x[0 : 2 * J : 2] * np.exp(1j * x[1 : 2 * J : 2])
            da[2 * j, j] = np.exp(1j * x[1 : 2 * J : 2])
            da[2 * j + 1, j] = 1j * a
            d2a = _polar_second(a, np.exp(1j * x[1 : 2 * J : 2]))
        else:
            a = x[1 : 2 * J : 2] + 1j * x[0 : 2 * J : 2]
            da[2 * j, j] = 1j
            da[2 * j + 1, j] = 1.0
        return _ToneMap(float(x[-1]), a.astype(complex), w, dc, da, np.zeros((P, J)), d2a)

    def signal(self, params: ArrayLike, u: Input | None = None) -> ToneSignal:
        """s(t; params); ``u`` is ignored (the model has no input).

        Parameters
        ----------
        params : array_like
            The model's parameters, in :attr:`param_names` order.
        u : Input, optional
            Unused: a signal model has no input.
        """
        return ToneSignal(self.tones(params))

    def initial_points(self, data: SampledData) -> list[FloatArray]:
        y, T = np.asarray(data.y, dtype=float), float(data.T)
        t = np.arange(y.size, dtype=float) * T
        c, a = _linear_tones(y, t, 2 * np.pi * np.asarray(self.frequencies_hz, dtype=float))
        pairs = np.column_stack(
            [np.abs(a), np.angle(a)] if self.form == "polar" else [a.imag, a.real]
        ).ravel()
        return [np.array([*pairs, c])]
