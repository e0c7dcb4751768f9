"""Known continuous-time inputs u(t).

Every input is zero before its ``start`` and the system is at rest there, so a jittered
instant before t = 0 is well defined. Sampling at or past an input's ``end`` is an error,
because the output there depends on an input nobody specified.

Two kinds exist, because the exact response (``jitterid.systems.tf``) is computed differently:

- :class:`PiecewiseConstant` (switch times and levels): the paper's PRBS
  (:func:`telegraph_input`) and the zero-order hold of a sample sequence (:func:`zoh_input`).
- :class:`Multisine`: a sum of sinusoids, either switched on at ``start`` (transient
  included) or in periodic steady state (``steady_state=True``, defined for all t < end).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import finite, generator, positive, real_array, sampling_interval
from ._repr import brief

__all__ = [
    "Input",
    "Multisine",
    "PiecewiseConstant",
    "telegraph_input",
    "zoh_input",
]

FloatArray = NDArray[np.float64]


def _round_up(t_max: float, end: float) -> float:
    """A tidy time past ``t_max`` > ``end`` (the overshoot with half again, one digit)."""
    over = 1.5 * (t_max - end)
    step = 10.0 ** np.floor(np.log10(over))
    return float(end + np.ceil(over / step) * step)


def known_input(u: object, name: str = "u") -> Input:
    """``u`` if it is a jitterid input, else a TypeError naming ``name`` and the fix."""
    if isinstance(u, Input):
        return u
    hint = (
        " (an array of input values: wrap it, zoh_input(values, T) holds each for T)"
        if isinstance(u, (np.ndarray, list, tuple))
        else ""
    )
    raise TypeError(
        f"{name} must be a jitterid input (zoh_input, telegraph_input, Multisine or "
        f"PiecewiseConstant); got {type(u).__name__}{hint}"
    )


class Input:
    """Base of the known inputs: ``start``, ``end``, ``__call__(t)`` and ``fourier(psi)``.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> u = ji.zoh_input([1.0, -1.0], T=0.5)
    >>> isinstance(u, ji.Input), u.start, u.end
    (True, 0.0, 1.0)
    >>> u(np.array([0.25, 0.75])).tolist()
    [1.0, -1.0]
    """

    start: float
    end: float

    def __call__(self, t: ArrayLike) -> FloatArray:  # pragma: no cover - abstract
        raise NotImplementedError

    def fourier(self, psi: ArrayLike) -> NDArray[np.complex128]:  # pragma: no cover
        """Continuous-time Fourier transform U(psi) = int u(t) exp(-i 2 pi psi t) dt.

        Parameters
        ----------
        psi : array_like
            Frequencies in Hz.
        """
        raise NotImplementedError

    def check_covers(self, t_max: float, what: str = "the sampled interval") -> None:
        """Raise ValueError if the input ends before ``t_max``.

        Parameters
        ----------
        t_max : float
            The last instant (s) that must be covered.
        what : str, optional
            What ``t_max`` is, for the error message.
        """
        if t_max >= self.end:
            raise ValueError(self.coverage_message(t_max, what))

    def coverage_message(self, t_max: float, what: str = "the sampled interval") -> str:
        """What is wrong and how to fix it when the input ends before ``t_max`` (or, for a
        ``t_max`` just before the end, when it stops a search from going further): the one
        wording of every check of the input's end (the data checks, the moments, the
        likelihood, :func:`jitterid.simulate`, the checks after a fit).

        Parameters
        ----------
        t_max : float
            The last instant (s) that must be covered.
        what : str, optional
            What ``t_max`` is.
        """
        if t_max < self.end:
            return (
                f"{what} reaches t = {t_max:g}, at the end of the input (t = {self.end:g}): "
                "nothing further can be evaluated, the input being unknown past its end"
                + self._extension_hint(t_max)
            )
        return (
            f"the input ends at t = {self.end:g} but {what} reaches t = {t_max:g}; give an "
            "input that lasts longer (e.g. a larger duration) or use fewer samples"
            + self._extension_hint(t_max)
        )

    def _extension_hint(self, t_max: float) -> str:
        return ""


@dataclass(frozen=True, eq=False)
class PiecewiseConstant(Input):
    """Input holding ``levels[j]`` on ``[times[j], times[j+1])``, zero before ``times[0]``.

    Parameters
    ----------
    times : array_like, shape (J+1,)
        Strictly increasing boundaries; ``times[0]`` is the start, ``times[-1]`` the end.
    levels : array_like, shape (J,)
        The value held on each interval.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> u = ji.PiecewiseConstant(np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0]))
    >>> u(np.array([-0.5, 0.5, 1.5, 2.5])).tolist()
    [0.0, 1.0, -1.0, 0.0]
    """

    times: FloatArray
    levels: FloatArray
    start: float = field(init=False)
    end: float = field(init=False)

    def __post_init__(self) -> None:
        times = real_array(self.times, "times", ndim=1)
        levels = real_array(self.levels, "levels", ndim=1)
        if times.size < 2:
            raise ValueError("times must hold at least a start and an end time")
        if levels.size != times.size - 1:
            raise ValueError(
                f"levels must have one value per interval: len(times) - 1 = {times.size - 1}, "
                f"got len(levels) = {levels.size}"
            )
        if np.any(np.diff(times) <= 0):
            j = int(np.flatnonzero(np.diff(times) <= 0)[0])
            raise ValueError(
                f"times must be strictly increasing; times[{j}] = {times[j]:g} >= "
                f"times[{j + 1}] = {times[j + 1]:g}. Sort them and merge duplicates"
            )
        times.setflags(write=False)
        levels.setflags(write=False)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "levels", levels)
        object.__setattr__(self, "start", float(times[0]))
        object.__setattr__(self, "end", float(times[-1]))

    def __repr__(self) -> str:
        return f"PiecewiseConstant(times={brief(self.times)}, levels={brief(self.levels)})"

    @property
    def breaks(self) -> FloatArray:
        """Times where u jumps (the start and every switch), where the output is not smooth."""
        return self.times[:-1]

    def hold_last(self, until: float) -> PiecewiseConstant:
        """This input with its last level held until ``until`` (s): what a DAC or a
        zero-order hold does after its last sample, so that an input file with one value
        per sample covers the jitter's reach past the last sampling instant.

        Parameters
        ----------
        until : float
            The new end (s); an end before the current one is refused.

        Examples
        --------
        >>> import jitterid as ji
        >>> u = ji.zoh_input([1.0, -1.0], T=0.5).hold_last(1.25)
        >>> u.times.tolist(), u.levels.tolist()
        ([0.0, 0.5, 1.25], [1.0, -1.0])
        """
        end = finite(until, "until")
        if end < self.end:
            raise ValueError(
                f"until = {end:g} is before the input's end {self.end:g}; give a later time"
            )
        times = self.times.copy()
        times[-1] = end
        return PiecewiseConstant(times, self.levels)

    def _extension_hint(self, t_max: float) -> str:
        until = (
            f"u.hold_last({_round_up(t_max, self.end):g})"
            if t_max > self.end
            else "u.hold_last(t) with t a few jitter widths past the last sample"
        )
        return (
            ", or, for an input that stays at its last value (a DAC, a zero-order hold), hold "
            f"it over the jitter's reach: {until} (jitterid.load(..., hold_input=True), "
            "jitterid fit --hold-input)"
        )

    def __call__(self, t: ArrayLike) -> FloatArray:
        t = np.asarray(t, dtype=float)
        j = np.searchsorted(self.times, t, side="right") - 1
        inside = (j >= 0) & (j < self.levels.size)
        return np.where(inside, self.levels[np.clip(j, 0, self.levels.size - 1)], 0.0)

    def fourier(self, psi: ArrayLike) -> NDArray[np.complex128]:
        """U(psi) = sum_j u_j int_{t_j}^{t_{j+1}} exp(-i 2 pi psi t) dt, exact.

        Parameters
        ----------
        psi : array_like
            Frequencies in Hz.
        """
        psi = np.asarray(psi, dtype=float)
        flat = psi.ravel()
        out = np.empty(flat.size, complex)
        t0, t1 = self.times[:-1], self.times[1:]
        step = max(1, (1 << 20) // t0.size)  # bound the (psi, interval) temporaries
        for lo in range(0, flat.size, step):
            w = 2j * np.pi * flat[lo : lo + step, None]
            small = np.abs(w) * (t1 - t0) < 1e-6
            # (e^{-w t0} - e^{-w t1}) / w, with expm1 so that it stays accurate as w -> 0.
            safe_w = np.where(small, 1.0, w)
            seg = np.exp(-w * t0) * -np.expm1(-w * (t1 - t0)) / safe_w
            seg = np.where(small, (t1 - t0) * np.exp(-w * 0.5 * (t0 + t1)), seg)
            out[lo : lo + step] = seg @ self.levels
        return out.reshape(psi.shape)


@dataclass(frozen=True, eq=False)
class Multisine(Input):
    """u(t) = sum_m amplitudes[m] * sin(2 pi freqs[m] t + phases[m]) for start <= t < end.

    Parameters
    ----------
    freqs, amplitudes : array_like
        Frequencies in Hz (>= 0) and amplitudes, of equal length.
    end : float
        End of the input (s); sampling at or past it is an error.
    phases : array_like, optional
        Phases in radians (default 0).
    start : float
        Switch-on time in s (default 0). Ignored when ``steady_state`` is True.
    steady_state : bool
        If True the sinusoids have been on forever (no start transient): the input is
        defined for every t < end and a system's response is its periodic steady state.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> u = ji.Multisine(np.array([0.5, 1.5]), np.array([1.0, 0.5]), end=4.0)
    >>> round(float(u(np.array([0.5]))[0]), 6)
    0.5
    """

    freqs: FloatArray
    amplitudes: FloatArray
    end: float
    phases: FloatArray | None = None
    start: float = 0.0
    steady_state: bool = False

    def __post_init__(self) -> None:
        freqs = np.atleast_1d(real_array(self.freqs, "freqs"))
        amps = np.atleast_1d(real_array(self.amplitudes, "amplitudes"))
        phases = (
            np.zeros_like(freqs)
            if self.phases is None
            else np.atleast_1d(real_array(self.phases, "phases"))
        )
        if not (freqs.shape == amps.shape == phases.shape) or freqs.ndim != 1:
            raise ValueError(
                "freqs, amplitudes and phases must be 1-D and of equal length; got shapes "
                f"{freqs.shape}, {amps.shape}, {phases.shape}"
            )
        if np.any(freqs < 0):
            raise ValueError("freqs must be >= 0 Hz; fold a negative frequency into the phase")
        end = float(self.end)
        start = -np.inf if self.steady_state else float(self.start)
        if not np.isfinite(end) or end <= start:
            raise ValueError(f"end must be finite and after start; got start={start}, end={end}")
        for name, val in (("freqs", freqs), ("amplitudes", amps), ("phases", phases)):
            val.setflags(write=False)
            object.__setattr__(self, name, val)
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "start", start)

    def __repr__(self) -> str:
        return (
            f"Multisine(freqs={brief(self.freqs)}, amplitudes={brief(self.amplitudes)}, "
            f"end={self.end!r}, phases={brief(self.phases)}, start={self.start!r}, "
            f"steady_state={self.steady_state!r})"
        )

    @property
    def breaks(self) -> FloatArray:
        return np.array([]) if self.steady_state else np.array([self.start])

    def __call__(self, t: ArrayLike) -> FloatArray:
        t = np.asarray(t, dtype=float)
        assert self.phases is not None  # set in __post_init__
        arg = 2 * np.pi * t[..., None] * self.freqs + self.phases
        val = np.sin(arg) @ self.amplitudes
        return np.where(t >= self.start, val, 0.0)

    def fourier(self, psi: ArrayLike) -> NDArray[np.complex128]:
        raise NotImplementedError(
            "a multisine has a line spectrum, not a function U(psi); use "
            "jitterid.moments.reference.expected_dft_lines for the frequency-domain reference"
        )


def telegraph_input(
    duration: float,
    rng: np.random.Generator | int,
    levels: tuple[float, float] = (-0.5, 0.5),
    mean_hold: float = 1.0,
) -> PiecewiseConstant:
    """The paper's PRBS (Section 5): a random telegraph signal starting at t = 0.

    The level alternates between ``levels[0]`` and ``levels[1]`` after independent,
    exponentially distributed holding times with mean ``mean_hold``; the first level is
    drawn with equal probability.

    Parameters
    ----------
    duration : float
        The input is defined on [0, duration).
    rng : numpy.random.Generator or int
        Source of randomness (explicit; no global state).
    levels : pair of float
        The two levels (default +-0.5 as in the paper).
    mean_hold : float
        Mean holding time in seconds (default 1 s as in the paper).

    Returns
    -------
    PiecewiseConstant

    Examples
    --------
    >>> import jitterid as jid
    >>> u = jid.telegraph_input(10.0, rng=0)
    >>> sorted(set(u.levels.tolist()))
    [-0.5, 0.5]
    """
    duration = positive(duration, "duration")
    mean_hold = positive(mean_hold, "mean_hold")
    gen = generator(rng)
    lv = real_array(levels, "levels", ndim=1)
    if lv.size != 2:
        raise ValueError(f"levels must be a pair (low, high); got {levels!r}")
    # Refuse up front what cannot fit in memory (about 4 arrays of one value per switch).
    from ._checks import allocation

    allocation(
        4 * (duration / mean_hold + 10),
        f"a telegraph input of duration {duration:g} s with mean hold {mean_hold:g} s",
        fix="use a longer mean_hold or a shorter duration",
    )
    # Draw holding times in batches until the switches pass the end.
    expected = int(duration / mean_hold) + 1
    holds = gen.exponential(mean_hold, size=expected + 5 * int(np.sqrt(expected)) + 10)
    while holds.sum() <= duration:
        holds = np.concatenate([holds, gen.exponential(mean_hold, size=expected + 10)])
    switches = np.cumsum(holds)
    switches = switches[switches < duration]
    times = np.concatenate([[0.0], switches, [duration]])
    first = int(gen.integers(2))
    idx = (first + np.arange(times.size - 1)) % 2
    return PiecewiseConstant(times, lv[idx])


def zoh_input(samples: ArrayLike, T: float, start: float = 0.0) -> PiecewiseConstant:
    """Zero-order hold of ``samples`` on the grid ``start + k T`` (a DAC's output).

    The last sample is held for one interval, so the input ends at ``start + len(samples) T``.

    Parameters
    ----------
    samples : array_like, shape (n,)
        The held values, at least one.
    T : float
        Hold interval (s).
    start : float, optional
        Time of the first sample (s).

    Returns
    -------
    PiecewiseConstant

    Examples
    --------
    >>> import jitterid as jid
    >>> u = jid.zoh_input([0.0, 1.0, -1.0], T=0.5)
    >>> u.times.tolist(), u.levels.tolist()
    ([0.0, 0.5, 1.0, 1.5], [0.0, 1.0, -1.0])
    """
    T = sampling_interval(T, "T")
    u = real_array(samples, "samples", ndim=1)
    if u.size < 1:
        raise ValueError("samples must hold at least one value")
    times = float(start) + T * np.arange(u.size + 1, dtype=float)
    return PiecewiseConstant(times, u)
