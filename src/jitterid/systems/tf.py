"""Continuous-time transfer functions and their exact response at arbitrary instants.

scipy.signal.lsim and python-control refuse unequal time steps; jittered sampling needs
the output at arbitrary instants. For a rational G(s) with distinct poles the output is
exact from the modal (partial-fraction) form: per pole p with residue r,
x' = p x + u, s(t) = D u(t) + sum_p r x_p(t) (notes, section 5). Between switch times of a
piecewise-constant input, x(t) = exp(p (t - t_j)) x(t_j) + u_j expm1(p (t - t_j)) / p.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import finite, real_array
from .._state import CachesAreNotState, cache_field
from ..inputs import Input, Multisine, PiecewiseConstant
from ..jitter.laws import JitterLaw
from .model import DelayedSignal, ModalSegments, MomentPass, Signal
from .tones import ToneBases, ToneSignal, _ToneMap

__all__ = ["CoefficientDerivatives", "ModalForm", "Response", "TransferFunction"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

IntArray = NDArray[np.intp]


class ModalForm(NamedTuple):
    """The partial-fraction (modal) form G(s) = direct + sum_p residues_p / (s - poles_p) of a
    stable transfer function with distinct poles (:attr:`TransferFunction.modal`).

    Attributes
    ----------
    direct : float
        The direct term D (the feedthrough; 0 for a strictly proper G).
    residues : ndarray of complex, shape (n,)
        The residue of each pole.
    poles : ndarray of complex, shape (n,)
        The poles, as :attr:`TransferFunction.poles`.
    """

    direct: float
    residues: ComplexArray
    poles: ComplexArray

    def kept(self) -> tuple[float, ComplexArray, ComplexArray, IntArray]:
        """(D, rho, p, columns) over the poles with Im p >= 0 (their columns in
        :attr:`poles`), rho the residue doubled for a complex pair, so that a real input's
        output is D u + Re sum rho x (the conjugate pole's term is the conjugate)."""
        cols = np.flatnonzero(self.poles.imag >= 0)
        pk = self.poles[cols]
        return self.direct, self.residues[cols] * np.where(pk.imag > 0, 2.0, 1.0), pk, cols


# Exponent range kept inside one block of the switch-time recursion: exp(+-_BLOCK) stays far
# from overflow while the partial sums lose no relative accuracy (see _switch_states).
_BLOCK = 500.0


@dataclass(frozen=True, eq=False)
class TransferFunction(CachesAreNotState):
    """A continuous-time transfer function G(s) = e^{-s delay_s} num(s) / den(s).

    Parameters
    ----------
    num, den : array_like
        Polynomial coefficients in s, highest power first (as in ``scipy.signal``).
        Leading zeros are stripped. The model must be proper (deg num <= deg den).
    delay_s : float, default 0
        Input-output delay in seconds (MATLAB's ``IODelay``), finite; a negative value is a
        lead (it stands for a mean jitter offset, see :class:`jitterid.Shifted`).

    Notes
    -----
    Frequencies are in Hz throughout: ``frequency_response(f_hz)`` returns G(i 2 pi f). Simulation
    (:meth:`response`) needs a stable model with distinct poles; poles closer than 1e-6
    (relative) are refused, and accuracy degrades like 1e-16 / (pole separation).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> G = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> abs(complex(G.frequency_response(0.0)))
    1.0
    >>> G.poles.tolist()
    [(-2+0j)]
    """

    num: FloatArray
    den: FloatArray
    delay_s: float = 0.0
    # (input, recursion, states, conjugate-filled states) of the last input (_recursion)
    _states_memo: tuple[PiecewiseConstant, _Recursion, ComplexArray, ComplexArray | None] | None = (
        cache_field()
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "delay_s", finite(self.delay_s, "delay_s"))
        num = _trim_leading(np.atleast_1d(real_array(self.num, "num")))
        den = _trim_leading(np.atleast_1d(real_array(self.den, "den")))
        if num.ndim != 1 or den.ndim != 1:
            raise ValueError("num and den must be 1-D coefficient sequences")
        if den.size == 0:
            raise ValueError("den must have a non-zero coefficient")
        if num.size == 0:
            num = np.zeros(1)
        if num.size > den.size:
            raise ValueError(
                f"G(s) is improper: deg num = {num.size - 1} > deg den = {den.size - 1}. "
                "A sampled output needs a proper model; add poles or remove zeros"
            )
        num.setflags(write=False)
        den.setflags(write=False)
        object.__setattr__(self, "num", num)
        object.__setattr__(self, "den", den)

    def __repr__(self) -> str:
        delay = f", delay_s={self.delay_s!r}" if self.delay_s else ""
        return f"TransferFunction(num={self.num.tolist()}, den={self.den.tolist()}{delay})"

    @cached_property
    def undelayed(self) -> TransferFunction:
        """The rational part num(s) / den(s) (``self`` when there is no delay)."""
        return TransferFunction(self.num, self.den) if self.delay_s else self

    @property
    def order(self) -> int:
        """Number of poles."""
        return int(self.den.size - 1)

    @cached_property
    def poles(self) -> ComplexArray:
        return np.roots(self.den).astype(complex) if self.order else np.zeros(0, complex)

    @cached_property
    def zeros(self) -> ComplexArray:
        return np.roots(self.num).astype(complex) if self.num.size > 1 else np.zeros(0, complex)

    @property
    def is_stable(self) -> bool:
        """True if every pole has a negative real part."""
        return bool(np.all(self.poles.real < 0))

    @property
    def dcgain(self) -> float:
        return float(self.num[-1] / self.den[-1])

    def frequency_response(self, f_hz: ArrayLike) -> ComplexArray:
        """G(i 2 pi f) at frequencies ``f_hz`` in Hz.

        Parameters
        ----------
        f_hz : array_like
            Frequencies in Hz.

        Examples
        --------
        >>> complex(TransferFunction([2.0], [1.0, 2.0]).frequency_response(0.0))
        (1+0j)
        """
        s = 2j * np.pi * real_array(f_hz, "f_hz")
        g = np.polyval(self.num, s) / np.polyval(self.den, s)
        return g * np.exp(-s * self.delay_s) if self.delay_s else g

    def freqresp(self, f: ArrayLike) -> ComplexArray:
        """Deprecated: :meth:`frequency_response` (which names its unit, Hz; scipy's
        ``freqresp`` takes rad/s).

        Parameters
        ----------
        f : array_like
            Frequencies in Hz.
        """
        warnings.warn(
            "TransferFunction.freqresp is deprecated; use frequency_response(f_hz) (Hz)",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.frequency_response(f)

    @cached_property
    def modal(self) -> ModalForm:
        """The partial-fraction form G = D + sum r / (s - p) (:class:`ModalForm`): the one
        home of the modal form, on which the exact response, the moments' segment route and
        the likelihood build.

        Raises
        ------
        ValueError
            If the system is not stable or has (nearly) repeated poles.

        Examples
        --------
        >>> import jitterid as ji
        >>> m = ji.TransferFunction([2.0], [1.0, 3.0, 2.0]).modal
        >>> m.direct, m.poles.real.round(6).tolist(), m.residues.real.round(6).tolist()
        (0.0, [-2.0, -1.0], [-2.0, 2.0])
        """
        if not self.is_stable:
            bad = self.poles[self.poles.real >= 0]
            kind = "an integrator (a pole at 0)" if np.any(np.abs(bad) == 0) else "unstable modes"
            raise ValueError(
                f"the system {self!r} is not stable: poles {np.round(bad, 6).tolist()} have "
                f"Re >= 0 ({kind}). jitterid's exact response and moments are built on decaying "
                "modes, so it models stable systems only: model a slow mode as a stable pole "
                "(e.g. a0 > 0 small in RationalModel), or identify the system from the "
                "differenced output when it holds an integrator"
            )
        lead = self.den[0]
        d = float(self.num[0] / lead) if self.num.size == self.den.size else 0.0
        rem = np.polysub(self.num, d * self.den) if d else self.num
        p = self.poles
        if p.size > 1:
            gap = np.abs(p[:, None] - p[None, :])
            np.fill_diagonal(gap, np.inf)
            scale = max(1.0, float(np.max(np.abs(p))))
            # np.roots splits an exact double root by ~sqrt(eps); refuse such near-repeats.
            if np.min(gap) < 1e-6 * scale:
                raise ValueError(
                    "the system has repeated poles, which the modal simulation cannot represent; "
                    "perturb them slightly (accuracy ~1e-16 / separation) or re-parameterise"
                )
        r = np.polyval(rem, p) / np.polyval(np.polyder(self.den), p) if p.size else p
        return ModalForm(d, np.asarray(r, complex), p)

    def response(self, u: Input, derivatives: CoefficientDerivatives | None = None) -> Signal:
        """The exact output s(t) = (g * u)(t) to input ``u`` from rest: a :class:`Response`,
        or with a delay the undelayed system's :class:`Response` delayed
        (:class:`jitterid.systems.model.DelayedSignal`).

        Parameters
        ----------
        u : Input
            The input, zero before it starts.
        derivatives : CoefficientDerivatives, optional
            d(num, den)/dtheta of the structure this system is a value of: the response to a
            steady-state multisine then has its parameter derivatives in closed form
            (:attr:`Response.derivatives`).

        Examples
        --------
        >>> import numpy as np
        >>> import jitterid as ji
        >>> u = ji.Multisine([0.1], [1.0], end=100.0, steady_state=True)
        >>> s = ji.TransferFunction([1.0], [1.0, 1.0], delay_s=0.5).response(u)
        >>> type(s).__name__, s.has_slope
        ('DelayedSignal', True)
        """
        if self.delay_s:
            return DelayedSignal(Response(self.undelayed, u, derivatives), self.delay_s)
        return Response(self, u, derivatives)

    def _recursion(self, u: PiecewiseConstant) -> tuple[_Recursion, ComplexArray]:
        """The switch-time recursion over ``u`` for the poles with Im p >= 0, and its states.

        Memoised for the last input: evaluating one system on many chunks of instants (the
        jitter quadrature, the likelihood's nodes) must not redo this O(J) work per chunk,
        which made the total cost grow like N^2 / chunk; the state derivative reuses its
        exponentials. The memo lives on the system (not on a :class:`Response`), so no
        reference cycle keeps the arrays alive.
        """
        memo = self._states_memo
        if memo is not None and memo[0] is u:
            return memo[1], memo[2]
        p = self.modal.poles
        rec = _Recursion.build(p[p.imag >= 0], u.times)
        states = rec.solve(u.levels[:, None] * rec.expm1 / rec.p)
        object.__setattr__(self, "_states_memo", (u, rec, states, None))
        return rec, states

    def kept_switch_states(self, u: PiecewiseConstant) -> ComplexArray:
        """:meth:`switch_states` over the poles with Im p >= 0 only, shape (J+1, n_kept).

        Parameters
        ----------
        u : PiecewiseConstant
            The input, with boundaries t_j.
        """
        return self._recursion(u)[1]

    def switch_states(self, u: PiecewiseConstant) -> ComplexArray:
        """Modal states x_p(t_j) at every boundary t_j of ``u`` (notes 5), shape (J+1, n).

        x_{j+1} = e^{p dt_j} x_j + u_j expm1(p dt_j) / p from rest. A real input's state for
        a pole's conjugate is the conjugate, so only the poles with Im p >= 0 are solved for.

        Parameters
        ----------
        u : PiecewiseConstant
            The input, with boundaries t_j.
        """
        memo = self._states_memo
        if memo is None or memo[0] is not u:
            self._recursion(u)
            memo = self._states_memo
            assert memo is not None
        full = memo[3]
        if full is None:  # the conjugate columns, made only when asked for
            full = _conjugate_fill(self.modal.poles, memo[2])
            object.__setattr__(self, "_states_memo", (*memo[:3], full))
        return full

    def switch_state_sensitivity(self, u: PiecewiseConstant) -> ComplexArray:
        """dx_p(t_j)/dp at every boundary of ``u``, shape (J+1, n), exact.

        x_{j+1} = a_j x_j + u_j expm1(p dt_j)/p with a_j = e^{p dt_j}; differentiating,

            dx_{j+1}/dp = a_j dx_j/dp + dt_j a_j x_j + u_j (dt_j a_j / p - expm1(p dt_j) / p^2),

        the same linear recursion with another forcing, solved with the same exponentials
        (a fraction of one recursion, against three for a difference in p).

        Parameters
        ----------
        u : PiecewiseConstant
            The input, with boundaries t_j.
        """
        return _conjugate_fill(self.modal.poles, self.kept_switch_state_sensitivity(u))

    def kept_switch_state_sensitivity(self, u: PiecewiseConstant) -> ComplexArray:
        """:meth:`switch_state_sensitivity` over the poles with Im p >= 0, (J+1, n_kept).

        Parameters
        ----------
        u : PiecewiseConstant
            The input, with boundaries t_j.
        """
        rec, X = self._recursion(u)
        q, dt, a = rec.p, rec.dt, rec.step
        forcing = dt * a * X[:-1] + u.levels[:, None] * (dt * a / q - rec.expm1 / q**2)
        return rec.solve(forcing)


@dataclass(frozen=True, eq=False)
class CoefficientDerivatives:
    """d(num, den)/dtheta of a model structure at one parameter vector (what
    :meth:`jitterid.systems.structures.ModelStructure.coefficient_derivatives` and
    ``coefficient_hessian`` give), for the closed-form parameter derivatives of a
    :class:`Response` to a steady-state multisine.

    Parameters
    ----------
    dnum, dden : ndarray, shape (P, n)
        First derivatives of the numerator (padded to the length n of the denominator) and
        the denominator's coefficients, highest power first, one row per parameter.
    d2num, d2den : ndarray, shape (P, P, n), optional
        Second derivatives; None where the structure gives none in closed form (the
        response then has no second derivatives, :meth:`Response.second_derivatives`).
    delay : int, optional
        Index of the input-output delay among the parameters (:class:`jitterid.Delayed`;
        its rows above are zero: a delay moves no coefficient), or None.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> from jitterid.systems.tf import CoefficientDerivatives
    >>> d = CoefficientDerivatives(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0, 0.0],
    ...     [0.0, 1.0]]))
    >>> d.n_params
    2
    """

    dnum: FloatArray
    dden: FloatArray
    d2num: FloatArray | None = None
    d2den: FloatArray | None = None
    delay: int | None = None

    def __post_init__(self) -> None:
        dnum, dden = (np.asarray(v, dtype=float) for v in (self.dnum, self.dden))
        if dnum.ndim != 2 or dnum.shape != dden.shape:
            raise ValueError(
                f"dnum and dden must be (P, n) arrays of one shape; got {dnum.shape}, {dden.shape}"
            )
        P, n = dnum.shape
        object.__setattr__(self, "dnum", dnum)
        object.__setattr__(self, "dden", dden)
        if (self.d2num is None) != (self.d2den is None):
            raise ValueError("d2num and d2den must both be given or both be None")
        if self.d2num is not None:
            d2num, d2den = (np.asarray(v, dtype=float) for v in (self.d2num, self.d2den))
            if d2num.shape != (P, P, n) or d2den.shape != (P, P, n):
                raise ValueError(
                    f"d2num and d2den must have shape {(P, P, n)}; got {d2num.shape}, {d2den.shape}"
                )
            object.__setattr__(self, "d2num", d2num)
            object.__setattr__(self, "d2den", d2den)
        if self.delay is not None and not 0 <= int(self.delay) < P:
            raise ValueError(f"delay must index one of the {P} parameters; got {self.delay!r}")

    @property
    def n_params(self) -> int:
        """Number of parameters P."""
        return int(self.dnum.shape[0])


@dataclass(frozen=True, eq=False)
class Response(Signal, CachesAreNotState):
    """The exact output s(t) of ``system`` to input ``u`` (at rest before ``u.start``): the
    :class:`~jitterid.systems.model.Signal` of an LTI structure.

    Call it with any array of instants (< ``end``) to get s(t), vectorised.

    The steady-state response to a :class:`~jitterid.inputs.Multisine` is a sum of tones,

        s(t) = sum_m Im(a_m e^{i w_m t}),   a_m = A_m e^{i phi_m} G(i w_m),

    evaluated as one (:class:`jitterid.systems.tones.ToneSignal`): its slope s' and s'' are
    closed forms, and so, given the structure's ``derivatives``, are its parameter
    derivatives, da_m = A_m e^{i phi_m} dG(i w_m) with

        dG = (dN - G dD) / D,   d^2 G_ij = (d^2 N_ij - dG_i dD_j - dG_j dD_i - G d^2 D_ij) / D

    (N, D the numerator and denominator at s = i w_m); a delay d of the structure (the
    undelayed response under the jitter moved by -d, ``DelayedSignal.jitter_equivalent``)
    has da = -i w a, d^2 a / dd^2 = -w^2 a and d^2 a / dd dtheta = -i w da / dtheta. The
    response to any other input gives no parameter gradient here (the moments and the
    likelihood take it from the modal form, or difference it).

    Attributes
    ----------
    system : TransferFunction
    u : Input
    derivatives : CoefficientDerivatives or None
        d(num, den)/dtheta of the structure ``system`` is a value of (None: no parameters
        known to this signal, :attr:`has_gradient` is False).
    end : float
        The input's end; evaluating at or past it raises ValueError.
    breaks : ndarray
        Times where s(t) is not analytic (input switch times): quadrature splits there.
    rate : float
        The fastest rate (1/s) at which s varies between breaks: max |pole| and 2 pi f of
        the input's sinusoids. Quadrature panels are kept shorter than about 1 / rate.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> s = ji.Response(ji.TransferFunction([2.0], [1.0, 2.0]), ji.zoh_input([1.0] * 40, T=0.1))
    >>> s(np.array([0.0, 3.0])).round(4).tolist()
    [0.0, 0.9975]
    """

    system: TransferFunction
    u: Input
    derivatives: CoefficientDerivatives | None = None
    start: float = field(init=False)
    end: float = field(init=False)
    breaks: FloatArray = field(init=False)
    rate: float = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.system, TransferFunction):
            raise TypeError(f"system must be a TransferFunction; got {type(self.system).__name__}")
        if not isinstance(self.u, (PiecewiseConstant, Multisine)):
            raise TypeError(
                "u must be a jitterid input (PiecewiseConstant, telegraph_input, zoh_input, "
                f"Multisine); got {type(self.u).__name__}"
            )
        if self.derivatives is not None and not isinstance(
            self.derivatives, CoefficientDerivatives
        ):
            raise TypeError(
                "derivatives must be a CoefficientDerivatives or None; got "
                f"{type(self.derivatives).__name__}"
            )
        _, _, p = self.system.modal  # validates stability early
        rate = float(np.max(np.abs(p))) if p.size else 0.0
        if isinstance(self.u, Multisine) and self.u.freqs.size:
            rate = max(rate, float(2 * np.pi * np.max(self.u.freqs)))
        object.__setattr__(self, "start", self.u.start)
        object.__setattr__(self, "end", self.u.end)
        object.__setattr__(self, "breaks", self.u.breaks)
        object.__setattr__(self, "rate", rate)

    @property
    def modal_segments(self) -> ModalSegments | None:
        """This response's system and input (a
        :class:`~jitterid.systems.model.ModalSegments`) when the input is piecewise constant,
        the one test of the segment route; None for a multisine."""
        return ModalSegments(self.system, self.u) if isinstance(self.u, PiecewiseConstant) else None

    def check_covers(self, t_max: float, what: str) -> None:
        """Refuse instants past the input's end (:meth:`jitterid.inputs.Input.check_covers`).

        Parameters
        ----------
        t_max : float
            The last instant (s) that must be covered.
        what : str
            What ``t_max`` is, for the error message.
        """
        self.u.check_covers(t_max, what)

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
        """Closed-form jittered moments of the steady-state response to a multisine.

        The steady-state response to a :class:`~jitterid.inputs.Multisine` is a sum of
        tones, Im(A e^{i phi} G(i w) e^{i w t}) per input tone, so its moments are the
        closed forms (S1)-(S2) of :class:`jitterid.systems.tones.ToneSignal`: O(N H^2) with
        no quadrature over the jitter, where the node route costs O(N) panels of the
        fastest of the poles and tones.

        Parameters
        ----------
        jitter : JitterLaw
            The jitter law.
        T : float
            Nominal sampling interval (s).
        N : int
            Number of samples.
        variance : bool
            Whether to compute Var_k.
        gradient : bool
            Also the parameter derivatives dm_k, dVar_k, in closed form where the response
            has its structure's :attr:`derivatives` (:attr:`has_gradient`); otherwise left
            None (the caller differences the moments).
        scale : float, optional
            The jitter family's scale a (tau = a xi), for dm_k/da and dVar_k/da.
        higher : bool
            Third and fourth moments asked for: not in closed form (returns None).

        Returns
        -------
        MomentPass or None
            None for any other input (a switched-on multisine, a piecewise-constant
            input: the modal or node routes apply) or with ``higher``.

        Examples
        --------
        >>> import numpy as np
        >>> import jitterid as ji
        >>> u = ji.Multisine([0.1], [1.0], end=100.0, steady_state=True)
        >>> sig = ji.TransferFunction([1.0], [1.0, 1.0]).response(u)
        >>> mp = sig.jitter_moments(ji.Uniform(0.2), 1.0, 5)
        >>> mp.mean.shape, bool(np.all(mp.var >= 0))
        ((5,), True)
        """
        tones = self._tones
        if tones is None or higher:
            return None
        return tones.jitter_moments(
            jitter, T, N, variance=variance, gradient=gradient and self.has_gradient, scale=scale
        )

    @cached_property
    def _tones(self) -> ToneSignal | None:
        """The steady-state response to a multisine as a sum of tones (class doc), with its
        parameter derivatives where :attr:`derivatives` is given; None for any other input."""
        u = self.u
        if not (isinstance(u, Multisine) and u.steady_state):
            return None
        assert u.phases is not None  # filled in by Multisine.__post_init__
        w = 2 * np.pi * np.asarray(u.freqs, dtype=float)
        s = 1j * w
        num, den = self.system.num, self.system.den
        den_s = np.polyval(den, s)
        g = np.polyval(num, s) / den_s
        phasor = u.amplitudes * np.exp(1j * u.phases)
        a = np.asarray(phasor * g, dtype=complex)
        bases = u.__dict__.get("_tone_bases")  # shared by the responses to this input
        if bases is None:
            bases = ToneBases(w)
            object.__setattr__(u, "_tone_bases", bases)
        dv = self.derivatives
        H = w.size
        if dv is None:
            return ToneSignal(
                _ToneMap(0.0, a, w, np.zeros(0), np.zeros((0, H), complex), np.zeros((0, H))),
                bases,
            )
        n, P = den.size, dv.n_params
        if dv.dnum.shape[1] != n:
            raise ValueError(
                f"derivatives has {dv.dnum.shape[1]} coefficients per row; the system's "
                f"denominator has {n}"
            )
        powers = s[None, :] ** np.arange(n - 1, -1, -1)[:, None]  # (n, H)
        dN, dD = dv.dnum @ powers, dv.dden @ powers  # (P, H)
        dG = (dN - g * dD) / den_s
        da = phasor * dG
        d2a = None
        if dv.d2num is not None and dv.d2den is not None:
            d2G = (
                dv.d2num @ powers
                - dG[:, None, :] * dD[None, :, :]
                - dD[:, None, :] * dG[None, :, :]
                - g * (dv.d2den @ powers)
            ) / den_s
            d2a = phasor * d2G
        k = dv.delay
        if k is not None:  # d/dd of a e^{-i w d}: the jitter-equivalent frame (class doc)
            da[k] = -s * a
            if d2a is not None:
                d2a[k, :] = d2a[:, k] = -s * da
                d2a[k, k] = s * s * a
        return ToneSignal(_ToneMap(0.0, a, w, np.zeros(P), da, np.zeros((P, H)), d2a), bases)

    @property
    def has_gradient(self) -> bool:
        """Whether :meth:`gradient` gives ds/dtheta in closed form: the steady-state response
        to a multisine, given the structure's :attr:`derivatives`."""
        return self.derivatives is not None and self._tones is not None

    @property
    def has_slope(self) -> bool:
        """Whether :meth:`slope` gives ds/dt in closed form: the steady-state response to a
        multisine."""
        return self._tones is not None

    def gradient(self, t: FloatArray) -> FloatArray | None:
        """ds/dtheta at the instants ``t`` in closed form (class doc), shape (P, t.size), or
        None (:attr:`has_gradient` is False).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.

        Examples
        --------
        >>> import numpy as np
        >>> import jitterid as ji
        >>> u = ji.Multisine([0.1], [1.0], end=100.0, steady_state=True)
        >>> s = ji.RationalModel(0, 1).signal([2.0, 1.0], u)
        >>> s.gradient(np.array([0.0, 1.0])).shape
        (2, 2)
        """
        tones = self._tones
        if tones is None or self.derivatives is None:
            return None
        self._check_instants(t)
        return tones.gradient(np.asarray(t, dtype=float))

    def slope(self, t: FloatArray) -> FloatArray | None:
        """ds/dt at the instants ``t`` in closed form, or None (:attr:`has_slope` is False).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.

        Examples
        --------
        >>> import numpy as np
        >>> import jitterid as ji
        >>> u = ji.Multisine([0.25], [1.0], end=100.0, steady_state=True)
        >>> s = ji.TransferFunction([1.0], [1.0, 1e6]).response(u)  # ~1e-6 sin(pi t / 2)
        >>> (s.slope(np.array([0.0])) * 1e6 / (np.pi / 2)).round(4).tolist()
        [1.0]
        """
        tones = self._tones
        if tones is None:
            return None
        self._check_instants(t)
        return tones.slope(np.asarray(t, dtype=float))

    def second_derivatives(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """(d^2 s / dtheta^2 shape (P, P, n), d s' / dtheta shape (P, n), s'' shape (n,)) in
        closed form (class doc), or None: no gradient, or the structure gives no second
        derivatives of its coefficients (``derivatives.d2num`` is None).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.

        Examples
        --------
        >>> import numpy as np
        >>> import jitterid as ji
        >>> u = ji.Multisine([0.1], [1.0], end=100.0, steady_state=True)
        >>> s = ji.RationalModel(0, 1).signal([2.0, 1.0], u)
        >>> [a.shape for a in s.second_derivatives(np.array([0.0, 1.0, 2.0]))]
        [(2, 2, 3), (2, 3), (3,)]
        """
        tones = self._tones
        if tones is None or self.derivatives is None or self.derivatives.d2num is None:
            return None
        self._check_instants(t)
        return tones.second_derivatives(np.asarray(t, dtype=float))

    def _check_instants(self, t: ArrayLike) -> None:
        t = np.asarray(t, dtype=float)
        if t.size and float(np.max(t)) >= self.end:
            self.u.check_covers(float(np.max(t)), "an evaluation instant")

    @property
    def _switch_states(self) -> ComplexArray:
        """Modal states at every boundary of a piecewise-constant input, shape (J+1, n)."""
        assert isinstance(self.u, PiecewiseConstant)
        return self.system.switch_states(self.u)

    def __call__(self, t: ArrayLike) -> FloatArray:
        t = np.asarray(t, dtype=float)
        self._check_instants(t)
        tones = self._tones
        if tones is not None:  # the steady state: tones in real arithmetic (class doc)
            return tones(t)
        d, r, p = self.system.modal
        if isinstance(self.u, PiecewiseConstant):
            return self._piecewise(t, d, r, p)
        return self._multisine(t, d, r, p)

    def _piecewise(self, t: FloatArray, d: float, r: ComplexArray, p: ComplexArray) -> FloatArray:
        assert isinstance(self.u, PiecewiseConstant)
        times, levels = self.u.times, self.u.levels
        j = np.searchsorted(times, t, side="right") - 1
        before = j < 0
        jc = np.clip(j, 0, levels.size - 1)
        uj = np.where(before, 0.0, levels[jc])
        out = d * uj
        if p.size:
            # Conjugate pole pairs give conjugate terms: keep Im p >= 0 and double the pairs.
            keep = p.imag >= 0
            pk, rk = p[keep], r[keep] * np.where(p[keep].imag > 0, 2.0, 1.0)
            # before the input starts the output is 0; dt = 0 there keeps exp(p dt) finite
            dt = np.where(before, 0.0, t - times[jc])[..., None]
            e = np.exp(pk * dt)
            x = e * self._switch_states[jc][..., keep] + uj[..., None] * np.expm1(pk * dt) / pk
            out = out + np.where(before, 0.0, (x @ rk).real)
        return np.asarray(out, dtype=float)

    def _multisine(self, t: FloatArray, d: float, r: ComplexArray, p: ComplexArray) -> FloatArray:
        u = self.u
        assert isinstance(u, Multisine)
        out = d * u(t)
        if p.size == 0:
            return out
        # sin(w t + phi) = Im e^{i(w t + phi)}; response of 1/(s - p) to e^{i w t} switched on
        # at t0 from rest: (e^{i w t} - e^{p (t - t0)} e^{i w t0}) / (i w - p).
        w = 2 * np.pi * u.freqs
        tt = t[..., None, None]
        iw = 1j * w[:, None]
        steady = np.exp(iw * tt) / (iw - p)
        if not u.steady_state:
            steady = steady - np.exp(p * (tt - u.start) + iw * u.start) / (iw - p)
            steady = np.where(tt >= u.start, steady, 0.0)
        assert u.phases is not None  # filled in by Multisine.__post_init__
        phasor = (u.amplitudes * np.exp(1j * u.phases))[:, None]
        return np.asarray(out + np.einsum("...mn,mn->...", steady, phasor * r).imag, dtype=float)


def _trim_leading(c: FloatArray) -> FloatArray:
    """``c`` without its leading zeros (np.trim_zeros, at a tenth of its cost: a system is
    built at every parameter value an optimiser tries)."""
    if c.ndim != 1 or (c.size and c[0] != 0):
        return c
    nz = np.flatnonzero(c)
    return c[nz[0] :] if nz.size else c[:0]


def _conjugate_fill(p: ComplexArray, half: ComplexArray) -> ComplexArray:
    """Columns for every pole from ``half``, the columns of the poles with Im p >= 0: the
    state of a real input for a conjugate pole is the conjugate."""
    keep = p.imag >= 0
    out = np.empty((half.shape[0], p.size), complex)
    out[:, keep] = half
    kept = p[keep]
    for i in np.flatnonzero(~keep):
        out[:, i] = np.conj(half[:, int(np.argmin(np.abs(kept - np.conj(p[i]))))])
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class _Recursion(CachesAreNotState):
    """Solver of x_0 = 0, x_{j+1} = e^{p dt_j} x_j + f_j at the boundaries t_j of an input.

    The boundaries are cut into blocks whose span keeps |Re p| (t - t0) <= _BLOCK; inside a
    block x_i = e^{p r_i} (x_{j0} + sum_{m < i} f_m e^{-p r_{m+1}}), r = t - t_{j0}: a
    cumulative sum, taken for all blocks at once on a padded (block, position) layout, and
    the blocks are chained by one step of the recursion. The exponentials depend on the poles
    and times only, so they are computed once and shared by every forcing (the states and
    their pole derivative).
    """

    p: ComplexArray  # (n,)
    dt: FloatArray  # (J, 1)
    expm1: ComplexArray  # expm1(p dt_j), (J, n)
    E: ComplexArray  # e^{p r_i}, (J+1, n)
    Einv: ComplexArray  # e^{-p r_i}, (J+1, n)
    starts: NDArray[np.intp]
    ends: NDArray[np.intp]
    row: NDArray[np.intp]  # block of each boundary
    col: NDArray[np.intp]  # position in its block

    @classmethod
    def build(cls, p: ComplexArray, times: FloatArray) -> _Recursion:
        dt = np.diff(times)[:, None]
        alpha = max(float(np.max(-p.real)), 1e-300) if p.size else 1.0
        block = np.floor((times - times[0]) * alpha / _BLOCK).astype(np.int64)
        starts = np.flatnonzero(np.r_[True, block[1:] != block[:-1]])
        ends = np.r_[starts[1:], times.size]
        row = np.repeat(np.arange(starts.size), ends - starts)
        col = np.arange(times.size) - starts[row]
        rel = (times - times[starts[row]])[:, None]
        return cls(
            p, dt, np.expm1(p * dt), np.exp(p * rel), np.exp(-p * rel), starts, ends, row, col
        )

    @cached_property
    def step(self) -> ComplexArray:
        """e^{p dt_j}, (J, n): only the derivative's forcing needs it at every j."""
        return np.exp(self.p * self.dt)

    def solve(self, forcing: ComplexArray) -> ComplexArray:
        """x at every boundary (J+1, n) for the forcing f_j (J, n)."""
        n, size = self.p.size, self.row.size
        x = np.zeros((size, n), complex)
        if n == 0:
            return x
        terms = np.zeros((size, n), complex)
        terms[1:] = forcing * self.Einv[1:]  # term of boundary i: f_{i-1} e^{-p r_i}
        terms[self.starts] = 0.0
        width = int(np.max(self.ends - self.starts))
        if self.starts.size * width <= 4 * size + 1024:
            padded = np.zeros((self.starts.size, width, n), complex)
            padded[self.row, self.col] = terms
            csum = np.cumsum(padded, axis=1)[self.row, self.col]
        else:  # very uneven blocks: pad would be large, sum block by block
            csum = np.empty_like(terms)
            for j0, j1 in zip(self.starts, self.ends, strict=True):
                csum[j0:j1] = np.cumsum(terms[j0:j1], axis=0)
        # Chain the blocks: x0 of block k + 1 is one recursion step from the end of block k.
        x0 = np.zeros((self.starts.size, n), complex)
        lasts = self.ends[:-1] - 1
        steps = np.exp(self.p * self.dt[lasts])  # e^{p dt} at the block ends only
        for k, last in enumerate(lasts):
            x_last = self.E[last] * (x0[k] + csum[last])
            x0[k + 1] = steps[k] * x_last + forcing[last]
        return self.E * (x0[self.row] + csum)
