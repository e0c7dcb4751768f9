"""The model protocol: what the moments, the likelihood and the fit need from a model of the
sampled signal s(t; theta) (the paper's (1a): y_k = s(kT + tau_k; theta) + v_k).

A :class:`Model` has named parameters with bounds, gives starting points, and at each
parameter vector a :class:`Signal`: s(t) at arbitrary instants, with where it is not smooth
(``breaks``), how fast it varies (``rate``), and, where it has them, its parameter gradient
ds/dtheta and its time slope ds/dt. Everything downstream (:mod:`jitterid.moments`, the
estimators, the search, the covariance) reads a model only through this protocol, so a new
kind of model is one class:

- LTI structures driven by a known input (:class:`jitterid.systems.structures.ModelStructure`:
  ``PolePairGain``, ``RationalModel``, ``KnownSystem``); their signal is the exact response
  :class:`jitterid.systems.tf.Response`, which the moments evaluate by the fast modal path
  over input segments (:mod:`jitterid.moments.modal`) where the input is piecewise constant;
- signal models with no input (:class:`jitterid.systems.signals.SignalModel`: a function
  s(t, theta) with named parameters), whose moments are quadratures over the jitter of the
  signal's values and gradient (:mod:`jitterid.moments.signal`).

A model without an analytic gradient declares it by returning ``None`` from
:meth:`Signal.gradient`: the moments then take central differences of the model through
:mod:`jitterid.finite_diff` (never silently: :attr:`Model.analytic` says which).
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import parameter_vector
from ..jitter.laws import shifted

if TYPE_CHECKING:
    from ..data import SampledData
    from ..inputs import Input, PiecewiseConstant
    from ..jitter.laws import JitterLaw

__all__ = ["Bounds", "DelayedSignal", "ModalSegments", "Model", "MomentPass", "Signal"]

FloatArray = NDArray[np.float64]
Bounds = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class MomentPass:
    """m_k, Var_k and their derivatives (what :func:`jitterid.moments.sample.moment_pass`
    and :meth:`Signal.jitter_moments` return; defined here, with the protocol, so that a
    signal with closed-form moments needs nothing from :mod:`jitterid.moments`).

    ``dmean``/``dvar`` have a row per parameter of the signal's gradient and ``scale_mean``/
    ``scale_var`` are the derivatives in the jitter scale; ``None`` where not asked for or
    not available (the signal declares no gradient or slope: the caller differences)."""

    mean: FloatArray
    var: FloatArray | None
    dmean: FloatArray | None = None
    dvar: FloatArray | None = None
    scale_mean: FloatArray | None = None
    scale_var: FloatArray | None = None
    mu3: FloatArray | None = None  # E[(s - m_k)^3] (with ``higher``)
    mu4: FloatArray | None = None  # E[(s - m_k)^4] (with ``higher``)


class ModalSegments(NamedTuple):
    """A signal that is the response of an LTI system in modal form to a piecewise-constant
    input (what :attr:`Signal.modal_segments` declares): its jittered moments, their
    derivatives and the likelihood's node values are sums per input segment from the modal
    form (:mod:`jitterid.moments.modal`), with no evaluation of s(t) node by node.

    Attributes
    ----------
    system : TransferFunction
        The system (stable, distinct poles: its :attr:`~jitterid.TransferFunction.modal`).
    u : PiecewiseConstant
        The input.
    """

    system: Any  # a jitterid.systems.tf.TransferFunction (that module imports this one)
    u: PiecewiseConstant


class Signal(abc.ABC):
    """s(t) of one model at one parameter vector.

    Attributes
    ----------
    breaks : ndarray
        Instants where s(t) is not analytic (input switch times): quadrature panels end there.
    rate : float
        The fastest rate (1/s) at which s varies between breaks; quadrature panels are kept
        shorter than about ``1 / rate``.
    start, end : float
        s(t) is zero before ``start``; evaluating at or after ``end`` is an error (an input
        that ends). ``-inf`` and ``inf`` for a signal defined everywhere.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> s = ji.SineWave().signal([2.0, 0.0, 0.25, 0.0])
    >>> isinstance(s, ji.Signal), s(np.array([0.0, 1.0])).round(6).tolist()
    (True, [0.0, 2.0])
    """

    breaks: FloatArray
    rate: float
    start: float
    end: float

    @abc.abstractmethod
    def __call__(self, t: ArrayLike) -> FloatArray:
        """s(t) at the instants ``t`` (any shape)."""

    @property
    def has_gradient(self) -> bool:
        """Whether :meth:`gradient` gives ds/dtheta in closed form."""
        return False

    @property
    def has_slope(self) -> bool:
        """Whether :meth:`slope` gives ds/dt in closed form."""
        return False

    @property
    def modal_segments(self) -> ModalSegments | None:
        """The signal as an LTI system's response to a piecewise-constant input
        (:class:`ModalSegments`), which the moments, their derivatives and the exact
        likelihood sum per input segment from the modal form; None (the default) for any
        other signal, evaluated at the quadrature nodes."""
        return None

    def gradient(self, t: FloatArray) -> FloatArray | None:
        """ds/dtheta at the instants ``t`` (1-D), shape (P, t.size), or None: no closed form
        (the declared finite-difference route of the moments and the likelihood).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.
        """
        return None

    def slope(self, t: FloatArray) -> FloatArray | None:
        """ds/dt at the instants ``t`` (1-D), or None: no closed form (a jitter family's
        scale is then differenced like its other parameters).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.
        """
        return None

    def second_derivatives(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """(d^2 s / dtheta^2 shape (P, P, n), d s' / dtheta shape (P, n), s'' shape (n,)) at
        the instants ``t``, or None: not in closed form (the likelihood's Newton matrix then
        drops the second-derivative term, (L5) of :mod:`jitterid.estimation.likelihood`).

        Parameters
        ----------
        t : ndarray, shape (n,)
            Instants in s.
        """
        return None

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
        """The moments of s(kT + tau) in closed form, as
        :func:`jitterid.moments.sample.moment_pass` defines them, or None: no closed form
        (the default; the moments are then quadratures over the jitter at nodes). A signal
        that has one (a sum of tones, through the jitter's characteristic function:
        :class:`jitterid.systems.tones.ToneSignal`) overrides this.

        Parameters
        ----------
        jitter : JitterLaw
            The sampling jitter's law.
        T : float
            Nominal sampling interval (s).
        N : int
            Number of samples.
        variance : bool, optional
            Also the variances.
        gradient : bool, optional
            Also the derivatives.
        scale : float, optional
            The jitter scale, for the derivative with respect to it.
        higher : bool, optional
            Also the third and fourth central moments.
        """
        return None

    def check_covers(self, t_max: float, what: str) -> None:
        """Refuse instants at or past :attr:`end` with a ValueError naming ``what``.

        Parameters
        ----------
        t_max : float
            The last instant (s) that must be covered.
        what : str
            What ``t_max`` is, for the error message.
        """
        if t_max >= self.end:
            raise ValueError(f"{what} (t = {t_max:g}) is at or past the signal's end {self.end:g}")

    def jitter_equivalent(self, jitter: JitterLaw) -> tuple[JitterLaw, Signal]:
        """A (law, signal) pair whose jittered samples s(kT + tau) have the same law as this
        signal's under ``jitter``: the pair itself, except for a pure time shift
        (:class:`DelayedSignal`: the delay moves into the jitter's mean, so the moments and
        the likelihood keep the fast modal path of the undelayed response).

        Parameters
        ----------
        jitter : JitterLaw
            The sampling jitter's law.
        """
        return jitter, self


@dataclass(frozen=True, eq=False)
class DelayedSignal(Signal):
    """s(t) = inner(t - delay_s): a signal delayed by ``delay_s`` seconds (an input-output
    delay, :class:`jitterid.Delayed`).

    Its jittered samples inner(kT + tau - delay_s) are those of ``inner`` under the jitter
    moved by -delay_s (:meth:`jitter_equivalent`), which is how the moments and the
    likelihood evaluate it.
    """

    inner: Signal
    delay_s: float

    def __post_init__(self) -> None:
        d = float(self.delay_s)
        object.__setattr__(self, "breaks", np.asarray(self.inner.breaks, dtype=float) + d)
        object.__setattr__(self, "rate", self.inner.rate)
        object.__setattr__(self, "start", self.inner.start + d)
        object.__setattr__(self, "end", self.inner.end + d)

    def __call__(self, t: ArrayLike) -> FloatArray:
        return self.inner(np.asarray(t, dtype=float) - self.delay_s)

    @property
    def has_gradient(self) -> bool:
        return self.inner.has_gradient

    @property
    def has_slope(self) -> bool:
        return self.inner.has_slope

    def gradient(self, t: FloatArray) -> FloatArray | None:
        # the inner signal's rows include the delay's, -inner'(t - delay_s): the derivative
        # in its jitter-equivalent frame is the delayed signal's (jitterid.systems.tf.Response)
        return self.inner.gradient(np.asarray(t, dtype=float) - self.delay_s)

    def slope(self, t: FloatArray) -> FloatArray | None:
        return self.inner.slope(np.asarray(t, dtype=float) - self.delay_s)

    def second_derivatives(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        return self.inner.second_derivatives(np.asarray(t, dtype=float) - self.delay_s)

    def jitter_equivalent(self, jitter: JitterLaw) -> tuple[JitterLaw, Signal]:
        law, sig = self.inner.jitter_equivalent(jitter)
        return shifted(law, -self.delay_s), sig


class Model(abc.ABC):
    """A parameterised model of the sampled signal, s(t; theta).

    Subclasses define ``param_names``, ``bounds`` (closed, used by the optimiser),
    :meth:`signal` and :meth:`initial_points`, and may declare ``gain_params`` (parameters in
    which s is linear: the scaling of the data maps them exactly, and each start gets its
    least-squares gain) and :attr:`uses_input`.

    Examples
    --------
    >>> import jitterid as ji
    >>> model = ji.RationalModel(0, 1)
    >>> isinstance(model, ji.Model), model.param_names, model.uses_input
    (True, ('b0', 'a0'), True)
    """

    param_names: tuple[str, ...]
    bounds: Bounds
    #: whether s depends on a known input ``data.u`` (LTI structures) or not (signal models)
    uses_input: bool = True

    @property
    def gain_params(self) -> tuple[int, ...]:
        """Indices of parameters that scale the output linearly."""
        return ()

    @property
    def analytic(self) -> bool:
        """Whether the signal's parameter gradient is in closed form (else: differences)."""
        return True

    @abc.abstractmethod
    def signal(self, params: ArrayLike, u: Input | None = None) -> Signal:
        """s(t; params), driven by the known input ``u`` where the model has one.

        Parameters
        ----------
        params : array_like
            The model's parameters, in :attr:`param_names` order.
        u : Input, optional
            The known input, for a model that has one.
        """

    @abc.abstractmethod
    def initial_points(self, data: SampledData) -> Sequence[FloatArray]:
        """A few starting points for the ordinary fit that ignores the jitter (Section 4.5).

        Parameters
        ----------
        data : SampledData
            The data to be fitted.
        """

    def _check(self, params: ArrayLike) -> FloatArray:
        return parameter_vector(params, self.param_names, self.bounds)
