"""Jittered sampling of a known system's output: y_k = s(kT + tau_k) + v_k, eq. (1a)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._checks import count, generator, positive, sampling_interval
from .data import SampledData
from .inputs import Input, known_input
from .jitter.laws import JitterLaw, known_law
from .noise.models import NoiseModel
from .systems.model import Signal
from .systems.tf import TransferFunction

__all__ = ["SampledData", "simulate"]

FloatArray = NDArray[np.float64]


def simulate(
    system: TransferFunction | Signal,
    u: Input | None,
    jitter: JitterLaw,
    T: float,
    N: int,
    noise_std: float,
    rng: np.random.Generator | int,
    *,
    noise_model: NoiseModel | None = None,
) -> SampledData:
    """Sample the exact output of ``system`` to ``u`` (or a signal) at jittered instants,
    eq. (1a).

    y_k = s(kT + tau_k) + v_k with tau_k i.i.d. from ``jitter`` and v_k ~ N(0, noise_std^2);
    with ``noise_model``, v_k also holds the coloured noise v(kT + tau_k) of (1c).

    Parameters
    ----------
    system : TransferFunction or Signal
        Stable continuous-time system, at rest before the input starts; or a signal with
        no input, s(t), e.g. ``SineWave().signal([amplitude, phase_rad, frequency_hz,
        offset])`` (then ``u`` is None).
    u : Input or None
        Known input of ``system``; must last past the last possible instant
        (N-1) T + max tau. None for a signal.
    jitter : JitterLaw
        Law of the sampling-time jitter tau_k.
    T : float
        Nominal sampling interval (s) (> 0).
    N : int
        Number of samples (>= 4).
    noise_std : float
        Standard deviation of the white measurement noise (>= 0).
    rng : numpy.random.Generator or int
        Source of randomness; the jitter is drawn first, then the white noise, then the
        coloured noise (so adding ``noise_model`` leaves the other draws unchanged).
    noise_model : NoiseModel, optional
        Coloured noise v(t) = (h * e)(t), eq. (1c), sampled exactly at the jittered instants
        (the exact discretisation (N3) of :mod:`jitterid.noise.models`, not an Euler step). Default:
        white noise only (the OE structure (2a)).

    Returns
    -------
    SampledData
        With ``instants`` holding the true sampling instants (for diagnostics).

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as jid
    >>> sys = jid.TransferFunction([2.0], [1.0, 2.0])
    >>> u = jid.telegraph_input(20.0, rng=1)
    >>> data = jid.simulate(sys, u, jid.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> data.y.shape, data.T
    ((100,), 0.1)
    """
    T = sampling_interval(T, "T")
    N = count(N, "N", minimum=4)
    noise_std = positive(noise_std, "noise_std", allow_zero=True)
    jitter = known_law(jitter)
    if noise_model is not None and not isinstance(noise_model, NoiseModel):
        raise TypeError(
            "noise_model must be a NoiseModel (e.g. NoiseModel(TransferFunction([b], [1, c]))) "
            f"or None for white noise only; got {type(noise_model).__name__}"
        )
    if isinstance(system, Signal):
        if u is not None:
            raise ValueError("u must be None when system is a signal (it has no input)")
        signal = system
    elif isinstance(system, TransferFunction):
        if u is None:
            raise ValueError("u (the known input) is required with a TransferFunction")
        u = known_input(u)
        u.check_covers((N - 1) * T + jitter.support[1], "the last jittered sampling instant")
        signal = system.response(u)
    else:
        raise TypeError(
            "system must be a TransferFunction or a Signal (model.signal(params)); got "
            f"{type(system).__name__}"
        )
    gen = generator(rng)
    tau = np.asarray(jitter.sample(N, gen), dtype=float)
    instants = T * np.arange(N) + tau
    s = signal(instants)
    y = s + noise_std * gen.standard_normal(N)
    if noise_model is not None:
        y = y + noise_model.sample(instants, gen)
    return SampledData(y=y, T=T, u=u, noise_std=noise_std, instants=instants)
