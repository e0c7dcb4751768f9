"""Parameterised LTI model structures G_theta driven by a known input: the models of
:mod:`jitterid.systems.model` whose signal is the exact response s = G_theta u."""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import finite_diff
from .._checks import count
from ..inputs import Multisine
from .model import Bounds, Model, Signal
from .tf import CoefficientDerivatives, TransferFunction

if TYPE_CHECKING:
    from ..data import SampledData
    from ..inputs import Input

__all__ = ["Delayed", "KnownSystem", "ModelStructure", "PolePairGain", "RationalModel"]

FloatArray = NDArray[np.float64]


class ModelStructure(Model):
    """A family of transfer functions G_theta with named parameters, driven by a known input.

    Subclasses define ``param_names``, ``bounds`` (closed, used by the optimiser), a map
    ``system(params) -> TransferFunction``, and ``starts(T)``: a few starting points for the
    ordinary output-error fit that initialises every estimator (paper, Section 4.5). Its
    signal (:meth:`signal`) is the exact response of G_theta to the input, whose moments the
    fast modal path computes (:mod:`jitterid.moments.modal`).

    Examples
    --------
    >>> import jitterid as ji
    >>> model = ji.RationalModel(0, 1)
    >>> isinstance(model, ji.ModelStructure), model.param_names
    (True, ('b0', 'a0'))
    >>> model.system([2.0, 2.0]).den.tolist()
    [1.0, 2.0]
    """

    uses_input = True

    @property
    def gain_params(self) -> tuple[int, ...]:
        """Indices of parameters that scale the output linearly (the numerator)."""
        return ()

    @property
    def delay_index(self) -> int | None:
        """Index of the input-output delay among the parameters (:class:`Delayed`), or None.
        Its derivative is not in :meth:`coefficient_jacobian` (the delay moves no
        coefficient): the moments difference it, the likelihood takes it from the slope."""
        return None

    @abc.abstractmethod
    def system(self, params: ArrayLike) -> TransferFunction:
        """G_theta at ``params``.

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        """
        ...

    @abc.abstractmethod
    def starts(self, T: float) -> list[FloatArray]:
        """A few starting parameter vectors for data sampled every ``T``.

        Parameters
        ----------
        T : float
            Nominal sampling interval (s).
        """
        ...

    def signal(self, params: ArrayLike, u: Input | None = None) -> Signal:
        """s(t) = (G_theta u)(t), the exact response to the known input ``u``.

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        u : Input
            The known input (required).
        """
        if u is None:
            raise ValueError(
                f"{type(self).__name__} is driven by a known input: data.u must be given "
                "(a PiecewiseConstant, telegraph_input, zoh_input or Multisine)"
            )
        tf = self.system(params)
        if isinstance(u, Multisine) and u.steady_state:  # closed-form parameter derivatives
            return tf.response(u, self.derivatives(params, tf.den.size))
        return tf.response(u)

    def derivatives(self, params: ArrayLike, n: int) -> CoefficientDerivatives:
        """d(num, den)/dtheta (:meth:`coefficient_derivatives`), their second derivatives
        where :meth:`coefficient_hessian` gives them, and the delay's index: what the
        response to a steady-state multisine needs for its closed-form parameter derivatives
        (:class:`jitterid.systems.tf.Response`).

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        n : int
            Length of the denominator's coefficient vector (order + 1).

        Examples
        --------
        >>> import jitterid as ji
        >>> d = ji.PolePairGain().derivatives([5.0, -1.0, 2.0], 3)
        >>> d.dden.tolist(), d.d2den[1, 1].tolist()
        ([[0.0, 0.0, 0.0], [0.0, -2.0, -2.0], [0.0, 0.0, 4.0]], [0.0, 0.0, 2.0])
        """
        dnum, dden = self.coefficient_derivatives(params, n)
        second = (
            self.coefficient_hessian(params, n)
            if closed_form_applies(self, "coefficient_hessian")
            else None
        )
        d2num, d2den = (None, None) if second is None else second
        return CoefficientDerivatives(dnum, dden, d2num, d2den, self.delay_index)

    def initial_points(self, data: SampledData) -> list[FloatArray]:
        return self.starts(data.T)

    def coefficient_jacobian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        """d(num, den)/dtheta in closed form, shape (P, n) each (num padded to the length n
        of the denominator), or None: this structure declares no analytic derivative, and
        :meth:`coefficient_derivatives` then takes central differences of :meth:`system`.
        A subclass that maps its parameters otherwise must override it.

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        n : int
            Length of the denominator's coefficient vector (order + 1).
        """
        return None

    def coefficient_hessian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        """d^2(num, den)/dtheta^2 in closed form, shape (P, P, n) each (num padded to the
        length n of the denominator), or None: this structure declares none (the response
        to a steady-state multisine then gives no second derivatives, and the likelihood's
        Newton matrix is Gauss-Newton). A subclass that maps its parameters otherwise must
        override it.

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        n : int
            Length of the denominator's coefficient vector (order + 1).

        Examples
        --------
        >>> import jitterid as ji
        >>> d2num, d2den = ji.RationalModel(0, 1).coefficient_hessian([2.0, 1.0], 2)
        >>> d2den.shape, float(abs(d2den).max())
        ((2, 2, 2), 0.0)
        """
        return None

    def coefficient_derivatives(self, params: ArrayLike, n: int) -> tuple[FloatArray, FloatArray]:
        """d(num, den)/dtheta, shape (P, n) each (num padded to the length n of den): the
        closed form of :meth:`coefficient_jacobian` where it belongs to this structure's
        map (:func:`closed_form_applies`), else central differences of :meth:`system`
        through :mod:`jitterid.finite_diff` (the one home of this rule: the moments' modal
        sensitivities and the order selection's root gradients use it).

        Parameters
        ----------
        params : array_like
            The structure's parameters, in :attr:`param_names` order.
        n : int
            Length of the denominator's coefficient vector (order + 1).
        """
        theta = self._check(params)
        closed = self.coefficient_jacobian(theta, n) if closed_form_applies(self) else None
        if closed is not None:
            return closed
        P = theta.size
        dnum, dden = np.zeros((P, n)), np.zeros((P, n))
        for i in range(P):
            up, down, h2 = finite_diff.central_pair(theta, i, self.bounds[i], finite_diff.REL_STEP)
            a, b = self.system(up), self.system(down)
            dnum[i] = (padded(a.num, n) - padded(b.num, n)) / h2
            dden[i] = (padded(a.den, n) - padded(b.den, n)) / h2
        return dnum, dden


def padded(c: ArrayLike, n: int) -> FloatArray:
    """Polynomial coefficients ``c`` (highest power first) with leading zeros to length n."""
    c = np.asarray(c, dtype=float)
    return np.r_[np.zeros(n - c.size), c]


def closed_form_applies(structure: ModelStructure, method: str = "coefficient_jacobian") -> bool:
    """Whether ``structure``'s closed form ``method`` (``coefficient_jacobian`` or
    ``coefficient_hessian``) belongs to its own ``system``: False when a subclass redefines
    the parameter map below the class that wrote the closed form."""
    mro = type(structure).__mro__
    system = next(k for k in mro if "system" in k.__dict__)
    closed = next(k for k in mro if method in k.__dict__)
    return system is closed or not issubclass(system, closed)


@dataclass(frozen=True)
class PolePairGain(ModelStructure):
    """The paper's (27): G(s) = k0 / ((s - pr - i pi)(s - pr + i pi)), theta = (k0, pr, pi).

    Bounds keep the system stable (pr <= -pr_min) with a true complex pair (pi >= pi_min).

    Parameters
    ----------
    pr_min : float, optional
        Smallest decay rate -pr allowed, in rad/s.
    pi_min : float, optional
        Smallest imaginary part pi allowed, in rad/s.

    Examples
    --------
    >>> import jitterid as jid
    >>> model = jid.PolePairGain()
    >>> model.param_names
    ('k0', 'pr', 'pi')
    >>> model.system([5.0, -1.0, 2.0]).den.tolist()
    [1.0, 2.0, 5.0]
    """

    pr_min: float = 1e-6
    pi_min: float = 1e-3

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return ("k0", "pr", "pi")

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        return ((-np.inf, np.inf), (-np.inf, -self.pr_min), (self.pi_min, np.inf))

    @property
    def gain_params(self) -> tuple[int, ...]:
        return (0,)

    def system(self, params: ArrayLike) -> TransferFunction:
        k0, pr, pi = self._check(params)
        return TransferFunction(np.array([k0]), np.array([1.0, -2.0 * pr, pr * pr + pi * pi]))

    def coefficient_jacobian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        _, pr, pi = self._check(params)  # k0 / (s^2 - 2 pr s + pr^2 + pi^2)
        dnum, dden = np.zeros((3, n)), np.zeros((3, n))
        dnum[0, -1] = 1.0
        dden[1, n - 2 :] = (-2.0, 2.0 * pr)
        dden[2, n - 1] = 2.0 * pi
        return dnum, dden

    def coefficient_hessian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        self._check(params)  # d^2 (pr^2 + pi^2) = 2 in pr and pi; the rest is linear
        d2num, d2den = np.zeros((3, 3, n)), np.zeros((3, 3, n))
        d2den[1, 1, n - 1] = d2den[2, 2, n - 1] = 2.0
        return d2num, d2den

    def starts(self, T: float) -> list[FloatArray]:
        # Pole pairs spread over the band below Nyquist (1/(2T) Hz); k0 = |p|^2 (unit DC gain).
        out = []
        for w in (0.1, 0.3, 0.9):
            for zeta in (0.3, 0.7):
                omega = w * np.pi / T
                pr, pi = -zeta * omega, omega * np.sqrt(1 - zeta**2)
                out.append(np.array([omega**2, pr, pi]))
        return out


@dataclass(frozen=True)
class RationalModel(ModelStructure):
    """G(s) = (b_m s^m + ... + b_0) / (s^n + a_{n-1} s^{n-1} + ... + a_0), monic denominator.

    Parameters are named ``b{m}..b0`` then ``a{n-1}..a0`` (as MATLAB's tfest). Requires
    ``num_order <= den_order`` (a proper model) and ``den_order >= 1``.

    Parameters
    ----------
    num_order : int
        Numerator order m (>= 0).
    den_order : int
        Denominator order n (>= 1).

    Examples
    --------
    >>> import jitterid as jid
    >>> model = jid.RationalModel(0, 2)
    >>> model.param_names
    ('b0', 'a1', 'a0')
    >>> model.system([2.0, 3.0, 2.0]).den.tolist()
    [1.0, 3.0, 2.0]
    """

    num_order: int
    den_order: int

    def __post_init__(self) -> None:
        count(self.den_order, "den_order", minimum=1)
        count(self.num_order, "num_order", minimum=0)
        if self.num_order > self.den_order:
            raise ValueError(
                f"num_order ({self.num_order}) must not exceed den_order ({self.den_order}): "
                "the model would be improper"
            )

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        b = tuple(f"b{i}" for i in range(self.num_order, -1, -1))
        a = tuple(f"a{i}" for i in range(self.den_order - 1, -1, -1))
        return b + a

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        return tuple((-np.inf, np.inf) for _ in self.param_names)

    @property
    def gain_params(self) -> tuple[int, ...]:
        return tuple(range(self.num_order + 1))

    def system(self, params: ArrayLike) -> TransferFunction:
        x = self._check(params)
        nb = self.num_order + 1
        return TransferFunction(x[:nb], np.r_[1.0, x[nb:]])

    def coefficient_jacobian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        x = self._check(params)  # (b_m .. b_0) / (1, a_{n-1} .. a_0): the identity
        if n != self.den_order + 1:
            return None
        nb = self.num_order + 1
        dnum, dden = np.zeros((x.size, n)), np.zeros((x.size, n))
        dnum[np.arange(nb), n - nb + np.arange(nb)] = 1.0
        dden[nb + np.arange(n - 1), 1 + np.arange(n - 1)] = 1.0
        return dnum, dden

    def coefficient_hessian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        x = self._check(params)  # the identity map: no second derivative
        if n != self.den_order + 1:
            return None
        return np.zeros((x.size, x.size, n)), np.zeros((x.size, x.size, n))

    def starts(self, T: float) -> list[FloatArray]:
        # Real poles spread below Nyquist, numerator giving unit DC gain.
        out = []
        for w in (0.1, 0.3, 0.9):
            poles = -w * np.pi / T * np.geomspace(1.0, 2.0, self.den_order)
            den = np.real(np.poly(poles))
            num = np.zeros(self.num_order + 1)
            num[-1] = den[-1]
            out.append(np.r_[num, den[1:]])
        return out


@dataclass(frozen=True, eq=False)
class KnownSystem(ModelStructure):
    """A fixed, known system (no free parameters), e.g. Table 1's G = 1/(s+2).

    Parameters
    ----------
    tf : TransferFunction
        The known system.

    Examples
    --------
    >>> import jitterid as ji
    >>> model = ji.KnownSystem(ji.TransferFunction([1.0], [1.0, 2.0]))
    >>> model.param_names
    ()
    >>> model.system([]).den.tolist()
    [1.0, 2.0]
    """

    tf: TransferFunction

    def __post_init__(self) -> None:
        if not isinstance(self.tf, TransferFunction):
            raise TypeError(f"tf must be a TransferFunction; got {type(self.tf).__name__}")

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return ()

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        return ()

    def system(self, params: ArrayLike = ()) -> TransferFunction:
        self._check(params) if np.size(params) else None
        return self.tf

    def starts(self, T: float) -> list[FloatArray]:
        return [np.zeros(0)]


@dataclass(frozen=True, eq=False)
class Delayed(ModelStructure):
    """``structure`` with an input-output delay: G(s) = e^{-s delay_s} G_theta(s).

    The parameters are the structure's, then ``delay_s`` (seconds; MATLAB's ``IODelay``).
    The delayed input of a piecewise-constant or sinusoidal input is still one, so the
    response stays exact; the moments and the likelihood evaluate it as the undelayed
    response under the jitter moved by -delay_s
    (:meth:`jitterid.systems.model.DelayedSignal.jitter_equivalent`), on the same fast path.

    **Delay and mean jitter.** Samples y_k = (G u)(kT + tau_k - delay_s) see only
    ``delay_s - E tau``: a converter that samples late on average by m seconds looks
    exactly like a delay of -m. The fit estimates ``delay_s`` with the jitter law's mean held
    at its given value (zero for the symmetric laws and families; a known offset is a
    :class:`jitterid.Shifted` law); to estimate a mean jitter offset instead, allow a negative
    delay (``min_delay_s < 0``) with a zero-mean law and read m = -delay_s.

    Parameters
    ----------
    structure : ModelStructure
        The rational part (``PolePairGain()``, ``RationalModel(m, n)``, ...), not itself delayed.
    min_delay_s, max_delay_s : float
        Bounds of ``delay_s`` in seconds; default [0, inf) (a causal delay).

    Examples
    --------
    >>> import jitterid as ji
    >>> model = ji.Delayed(ji.RationalModel(0, 1), max_delay_s=5.0)
    >>> model.param_names
    ('b0', 'a0', 'delay_s')
    >>> model.system([2.0, 1.0, 0.3])
    TransferFunction(num=[2.0], den=[1.0, 1.0], delay_s=0.3)
    """

    structure: ModelStructure
    min_delay_s: float = 0.0
    max_delay_s: float = np.inf

    def __post_init__(self) -> None:
        if not isinstance(self.structure, ModelStructure):
            raise TypeError(
                "structure must be an LTI model structure (PolePairGain(), RationalModel(m, n), "
                f"...); got {type(self.structure).__name__}"
            )
        if isinstance(self.structure, Delayed) or "delay_s" in self.structure.param_names:
            raise ValueError("structure already has a delay_s parameter: delay it once")
        lo, hi = float(self.min_delay_s), float(self.max_delay_s)
        if not (np.isfinite(lo) and lo < hi) or np.isnan(hi):
            raise ValueError(
                f"min_delay_s must be finite and below max_delay_s; got [{lo!r}, {hi!r}] "
                "(e.g. min_delay_s=0, max_delay_s=10 * T)"
            )
        object.__setattr__(self, "min_delay_s", lo)
        object.__setattr__(self, "max_delay_s", hi)

    @property
    def param_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return (*self.structure.param_names, "delay_s")

    @property
    def bounds(self) -> Bounds:  # type: ignore[override]
        return (*self.structure.bounds, (self.min_delay_s, self.max_delay_s))

    @property
    def gain_params(self) -> tuple[int, ...]:
        return self.structure.gain_params

    @property
    def delay_index(self) -> int | None:
        return len(self.structure.param_names)

    def system(self, params: ArrayLike) -> TransferFunction:
        x = self._check(params)
        tf = self.structure.system(x[:-1])
        return TransferFunction(tf.num, tf.den, delay_s=float(x[-1]))

    def coefficient_jacobian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        x = self._check(params)
        inner = self.structure.coefficient_jacobian(x[:-1], n)
        if inner is None:
            return None
        zero = np.zeros((1, n))  # the delay moves no coefficient
        return np.vstack([inner[0], zero]), np.vstack([inner[1], zero])

    def coefficient_hessian(
        self, params: ArrayLike, n: int
    ) -> tuple[FloatArray, FloatArray] | None:
        x = self._check(params)
        inner = self.structure
        out = (
            inner.coefficient_hessian(x[:-1], n)
            if closed_form_applies(inner, "coefficient_hessian")
            else None
        )
        if out is None:
            return None
        P = x.size  # the delay's row and column are zero: it moves no coefficient
        d2num, d2den = np.zeros((P, P, n)), np.zeros((P, P, n))
        d2num[:-1, :-1], d2den[:-1, :-1] = out
        return d2num, d2den

    def starts(self, T: float) -> list[FloatArray]:
        # The structure's starts times a few delays in [min, max]: the criterion in the delay
        # has a local optimum per input switch, so one delay start is not enough.
        grid = np.array([0.0, 0.5, 1.0, 2.0, 4.0, -0.5, -1.0]) * T
        delays = np.unique(np.clip(grid, self.min_delay_s, min(self.max_delay_s, 1e300)))
        return [np.r_[x, d] for d in delays for x in self.structure.starts(T)]


def as_structure(system: Model | TransferFunction) -> Model:
    """Accept a model (a structure, a signal model) or a known TransferFunction (wrapped in
    :class:`KnownSystem`)."""
    if isinstance(system, Model):
        return system
    if isinstance(system, TransferFunction):
        return KnownSystem(system)
    raise TypeError(
        "system must be a model structure (PolePairGain(), RationalModel(m, n)), a signal "
        f"model (SignalModel) or a known TransferFunction; got {type(system).__name__}"
    )
