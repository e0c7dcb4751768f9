"""Matplotlib figures for the diagnostics; computing lives in :mod:`jitterid.analysis`.

Every function takes ``ax=None`` (new axes are created) or the axes to draw on, and returns
a :class:`Plot`: the artists it made by name (a dict), with ``figure``, ``axes`` and
``legend``, in the style of python-control's ``ControlPlot``. Frequencies are in Hz.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .analysis.diagnostics import JitterDetection
from .analysis.responses import TimeResponseBand, lti_response
from .analysis.uncertainty import BodeBand, PdfBand
from .jitter.laws import JitterLaw
from .systems.tf import TransferFunction

if TYPE_CHECKING:
    from .metrology.meter import JitterMeasurement

__all__ = [
    "Plot",
    "plot_bode",
    "plot_gain_factor",
    "plot_jitter_pdf",
    "plot_jitter_phase",
    "plot_residuals",
    "plot_step_response",
]


class Plot(dict[str, Any]):
    """What a plot function drew: its artists by name (a dict, e.g. ``plot["magnitude"]``),
    and ``figure``, ``axes`` (a tuple) and ``legend`` (the first axes' legend, or None), as
    python-control's ``ControlPlot``; ``plot.savefig(path)`` saves the figure."""

    def __init__(self, artists: dict[str, Any], axes: Sequence[Any]) -> None:
        super().__init__(artists)
        self.axes: tuple[Any, ...] = tuple(axes)
        self.figure: Any = self.axes[0].figure
        self.legend: Any = self.axes[0].get_legend()

    def savefig(self, *args: Any, **kwargs: Any) -> Any:
        """``self.figure.savefig(...)``."""
        return self.figure.savefig(*args, **kwargs)


Artists = dict[str, Any]


def _db(mag: ArrayLike) -> Any:
    """20 log10 |G|; -inf for 0 (a band's lower edge that reaches 0)."""
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(np.maximum(np.asarray(mag, float), 0.0))


def _axes(ax: Any, n: int, **subplots: Any) -> Any:
    """Return ``n`` axes: the given ones, or new ones in a column."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, axes = plt.subplots(n, 1, squeeze=False, layout="constrained", **subplots)
        return axes[:, 0] if n > 1 else axes[0, 0]
    if n > 1:
        axes = list(ax) if isinstance(ax, Sequence | np.ndarray) else []
        if len(axes) != n:
            raise ValueError(f"ax must be None or a sequence of {n} matplotlib Axes")
        return axes
    return ax


def plot_bode(
    band: BodeBand,
    references: Mapping[str, TransferFunction] | None = None,
    *,
    label: str = "jitter-aware estimate",
    ax: Any = None,
) -> Plot:
    """Bode magnitude (dB) and phase (degrees) of an estimate with its confidence band.

    The magnitude is 20 log10 |G(i 2 pi f)| on a linear dB axis, so its ticks are round
    numbers of dB whatever the range; the phase ticks are multiples of 15, 30, 45 or 90
    degrees; the frequency axis is logarithmic (Hz). The vertical range follows the curves:
    a band edge far below them (a lower edge at |G| = 0, -inf dB) leaves the axes.

    Parameters
    ----------
    band : BodeBand
        From :func:`jitterid.analysis.uncertainty.bode_band`.
    references : mapping of str to TransferFunction, optional
        Other systems to draw on the same frequencies, e.g. ``{"ordinary LS": ls.system,
        "truth": g0}``.
    label : str
        Legend label of the estimate.
    ax : pair of Axes, optional
        (magnitude axes, phase axes); new ones (a new figure) if None.

    Returns
    -------
    Plot
        ``magnitude``, ``magnitude_band``, ``phase``, ``phase_band`` and, per reference,
        ``"<name> magnitude"`` / ``"<name> phase"``; magnitudes are drawn in dB.
    """
    if not isinstance(band, BodeBand):
        raise TypeError(f"band must be a BodeBand; got {type(band).__name__}")
    from matplotlib.ticker import MaxNLocator

    ax_mag, ax_ph = _axes(ax, 2, sharex=True, figsize=(6.4, 6.0))
    pct = f"{100 * band.level:g}% band"
    mag_db = _db(band.magnitude)
    lo_db, hi_db = _db(band.magnitude_lo), _db(band.magnitude_hi)
    finite = mag_db[np.isfinite(mag_db)]
    # A lower edge at |G| = 0 is -inf dB: draw it far below the axes, not as a gap.
    floor = (float(finite.min()) if finite.size else 0.0) - 1000.0
    lo_fill = np.where(np.isneginf(lo_db), floor, lo_db)
    out: Artists = {
        "magnitude": ax_mag.semilogx(band.f, mag_db, color="C0", lw=2, label=label)[0],
        "magnitude_band": ax_mag.fill_between(
            band.f,
            lo_fill,
            hi_db,
            color="C0",
            alpha=0.25,
            lw=0,
            label=pct,
        ),
        "phase": ax_ph.semilogx(band.f, band.phase, color="C0", lw=2, label=label)[0],
        "phase_band": ax_ph.fill_between(
            band.f, band.phase_lo, band.phase_hi, color="C0", alpha=0.25, lw=0, label=pct
        ),
    }
    curves = [mag_db]
    styles = ["--", ":", "-."]
    for i, (name, tf) in enumerate((references or {}).items()):
        g = tf.frequency_response(band.f)
        style = {"color": f"C{i + 1}", "ls": styles[i % len(styles)], "lw": 1.5, "label": name}
        curves.append(_db(np.abs(g)))
        out[f"{name} magnitude"] = ax_mag.semilogx(band.f, curves[-1], **style)[0]
        out[f"{name} phase"] = ax_ph.semilogx(band.f, np.degrees(np.unwrap(np.angle(g))), **style)[
            0
        ]
    _db_limits(ax_mag, curves, lo_db, hi_db)
    ax_mag.yaxis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]))
    ax_ph.yaxis.set_major_locator(MaxNLocator(nbins=7, steps=[1, 1.5, 3, 4.5, 9, 10]))
    ax_mag.set_ylabel("|G(i 2π f)| (dB)")
    ax_ph.set_ylabel("phase (deg)")
    ax_ph.set_xlabel("frequency f (Hz)")
    ax_mag.legend(loc="best", fontsize="small")
    for a in (ax_mag, ax_ph):
        a.grid(True, which="major", alpha=0.4)
        a.grid(True, which="minor", axis="x", alpha=0.15)
    return Plot(out, (ax_mag, ax_ph))


def _db_limits(ax: Any, curves: list[Any], lo: Any, hi: Any) -> None:
    """Fit the dB axis to the curves and the band, but no more than 20 dB beyond the curves
    (a band edge at -inf dB would otherwise squash them)."""
    vals = np.concatenate([np.asarray(c)[np.isfinite(c)] for c in curves])
    if not vals.size:
        return
    c_lo, c_hi = float(vals.min()), float(vals.max())
    b_lo = np.asarray(lo)[~np.isnan(lo)]  # -inf (|G| = 0) kept: the band runs off the bottom
    b_hi = np.asarray(hi)[~np.isnan(hi)]
    bottom = max(min(c_lo, float(b_lo.min()) if b_lo.size else c_lo), c_lo - 20.0)
    top = min(max(c_hi, float(b_hi.max()) if b_hi.size else c_hi), c_hi + 20.0)
    pad = max(0.05 * (top - bottom), 0.5)
    ax.set_ylim(bottom - pad, top + pad)


def _time_unit(seconds: float) -> tuple[str, float]:
    """The SI time unit (name, scale in s) that writes ``seconds`` as a number >= 1."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if abs(seconds) >= scale:
            return unit, scale
    return "ps", 1e-12


def plot_jitter_pdf(
    band: PdfBand | JitterMeasurement,
    truth: JitterLaw | None = None,
    *,
    label: str = "estimated pdf",
    ax: Any = None,
    rng: Any = None,
) -> Plot:
    """The estimated jitter density with its band (and the true one, if known).

    Parameters
    ----------
    band : PdfBand or JitterMeasurement
        From :func:`jitterid.analysis.diagnostics.jitter_pdf_band`, drawn in seconds; or a
        :class:`~jitterid.JitterMeasurement` (:func:`jitterid.measure_jitter`), whose fitted
        law is drawn with its band (``measurement.fit.jitter_pdf_band``) over +-4 std, the
        time axis in a readable SI unit (ms, µs, ns, ps) and the density per that unit.
    truth : JitterLaw, optional
        A reference law drawn dashed.
    label : str
        Legend label of the estimate.
    ax : Axes, optional
    rng : int or Generator, optional
        For the band's draws with a measurement (default: seed 0, a reproducible figure).

    Returns
    -------
    Plot
        ``pdf``, ``band`` (absent for a known law, whose band is empty) and ``truth``.
    """
    from .metrology.meter import JitterMeasurement

    unit, scale = "s", 1.0
    if isinstance(band, JitterMeasurement):
        m = band
        std = float(m.law.std)
        if not (math.isfinite(std) and std > 0):
            raise ValueError(
                f"the measured jitter law has no spread (std {std!r}); nothing to draw"
            )
        lo, hi = m.law.support
        tau = np.linspace(max(lo, -4.5 * std), min(hi, 4.5 * std), 401)
        band = m.fit.jitter_pdf_band(tau, 0 if rng is None else rng)
        if label == "estimated pdf":
            shown = f"{std / _time_unit(std)[1]:.3g} {_time_unit(std)[0]}"
            label = (
                f"law-free: a Gaussian of the measured std {shown} (the shape not fitted)"
                if not m.law_fitted
                else f"fitted {m.family} law, std {shown}"
            )
        unit, scale = _time_unit(std)
    if not isinstance(band, PdfBand):
        raise TypeError(f"band must be a PdfBand or a JitterMeasurement; got {type(band).__name__}")
    ax = _axes(ax, 1)
    x = band.tau / scale
    out: Artists = {"pdf": ax.plot(x, band.pdf * scale, color="C0", lw=2, label=label)[0]}
    if np.any(band.hi > band.lo):
        note = f" ({', '.join(band.fixed)} fixed)" if band.fixed else ""
        out["band"] = ax.fill_between(
            x,
            band.lo * scale,
            band.hi * scale,
            color="C0",
            alpha=0.25,
            lw=0,
            label=f"{100 * band.level:g}% band{note}",
        )
    if truth is not None:
        out["truth"] = ax.plot(
            x, truth.pdf(band.tau) * scale, "k--", lw=1.5, label=f"reference {truth!r}"
        )[0]
    ax.set_xlabel(f"jitter τ ({unit})")
    ax.set_ylabel(f"density p(τ) (1/{unit})")
    # Keep the estimate readable when the band's upper edge runs off (a nearly degenerate
    # law among the draws): the band then leaves the top of the axes.
    top = 2.5 * max(float(np.max(band.pdf)), float(np.max(truth.pdf(band.tau))) if truth else 0.0)
    top = min(top, 1.15 * max(float(np.max(band.hi)), float(np.max(band.pdf))))
    ax.set_ylim(bottom=0, top=top * scale)
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(True, alpha=0.3)
    return Plot(out, (ax,))


def plot_jitter_phase(
    measurement: JitterMeasurement, y: ArrayLike, *, ax: Any = None, bins: int = 32
) -> Plot:
    """Residual variance of a sine record against the sine's phase, with the fitted model.

    The test engineer's view of jitter: the noise alone gives the flat level sigma_v^2; the
    jitter adds variance where the sine is steep (phases 0 and π, the zero crossings) and
    none at its peaks (π/2, 3π/2). The binned mean squared residuals are drawn with their
    standard errors, over the fitted noise-only level and the fitted noise + jitter
    variance binned the same way (:func:`jitterid.analysis.metrology.jitter_phase_profile`).

    Parameters
    ----------
    measurement : JitterMeasurement
        From :func:`jitterid.measure_jitter` on ``y``.
    y : array_like
        The record measured.
    ax : Axes, optional
    bins : int
        Phase bins over one period.

    Returns
    -------
    Plot
        ``measured`` (an errorbar container), ``model`` and ``noise`` (lines).
    """
    from .analysis.metrology import jitter_phase_profile

    prof = jitter_phase_profile(measurement, y, bins)
    ax = _axes(ax, 1)
    c = prof.centers
    out: Artists = {
        "measured": ax.errorbar(
            c,
            prof.resid_var,
            yerr=prof.resid_var_stderr,
            fmt="o",
            ms=4,
            color="C0",
            ecolor="C0",
            elinewidth=1,
            capsize=2,
            label="residuals: mean of (y - E y)² per bin ± 1 s.e.",
        ),
        "model": ax.plot(
            c,
            prof.model_var,
            "-",
            color="C3",
            lw=2,
            label=f"fitted noise + jitter ({measurement.family}, std "
            f"{measurement.jitter_std / _time_unit(measurement.jitter_std)[1]:.3g} "
            f"{_time_unit(measurement.jitter_std)[0]})",
        )[0],
        "noise": ax.axhline(
            prof.noise_var,
            color="k",
            ls="--",
            lw=1.5,
            label=f"fitted noise only, σ_v² = {prof.noise_var:.3g}",
        ),
    }
    ax.set_xlim(0.0, 2 * math.pi)
    ax.set_xticks(np.arange(5) * math.pi / 2, ["0", "π/2", "π", "3π/2", "2π"])
    ax.set_xlabel("phase of the fitted sine, 2π f kT + φ (rad)")
    ax.set_ylabel("residual variance (y units²)")
    ax.set_ylim(bottom=0)
    ax.set_title(
        f"f = {measurement.frequency:.6g} Hz, N = {np.size(y)}, {bins} phase bins",
        fontsize="medium",
    )
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(True, alpha=0.3)
    return Plot(out, (ax,))


def plot_residuals(detection: JitterDetection, *, ax: Any = None) -> Plot:
    """Residuals of an ordinary fit against time and against the model slope.

    With jitter the residual spread grows with |s'(kT)|: a funnel in the right panel. The
    fitted +-2 standard-deviation envelope sqrt(alpha + beta s'^2) is drawn there.

    Parameters
    ----------
    detection : JitterDetection
        From :func:`jitterid.analysis.diagnostics.detect_jitter`.
    ax : pair of Axes, optional
        (time axes, slope axes); new ones if None.

    Returns
    -------
    Plot
        ``time``, ``slope`` (scatter collections) and ``envelope`` (two lines).
    """
    if not isinstance(detection, JitterDetection):
        raise TypeError(f"detection must be a JitterDetection; got {type(detection).__name__}")
    ax_t, ax_s = _axes(ax, 2, figsize=(6.4, 6.0))
    r, d = detection.residuals, detection.slopes
    out: Artists = {
        "time": ax_t.scatter(detection.t, r, s=8, color="C0"),
        "slope": ax_s.scatter(d, r, s=8, color="C0", label="residual"),
    }
    grid = np.linspace(float(np.min(d)), float(np.max(d)), 200)
    alpha, beta = detection.coef
    sd = np.sqrt(np.maximum(alpha + beta * grid**2, 0.0))
    out["envelope"] = (
        ax_s.plot(grid, 2 * sd, "C3-", lw=1.5, label="±2 std, fitted α + β s'²")[0],
        ax_s.plot(grid, -2 * sd, "C3-", lw=1.5)[0],
    )
    ax_t.set_xlabel("nominal time kT (s)")
    ax_t.set_ylabel("residual y - ŝ(kT)")
    ax_s.set_xlabel("model slope ŝ'(kT) (per s)")
    ax_s.set_ylabel("residual y - ŝ(kT)")
    ax_s.set_title(
        f"jitter test p = {detection.pvalue:.2g}, implied std {detection.jitter_std:.3g} s",
        fontsize="medium",
    )
    ax_s.legend(loc="upper right", fontsize="small")
    for a in (ax_t, ax_s):
        a.grid(True, alpha=0.3)
    return Plot(out, (ax_t, ax_s))


def plot_gain_factor(
    f: ArrayLike,
    factor: ArrayLike,
    *,
    label: str = "|φ(f)|",
    tol: float | None = 0.01,
    ax: Any = None,
) -> Plot:
    """The LS gain factor |phi(f)| over frequency (see :func:`~jitterid.ls_gain_factor`).

    Parameters
    ----------
    f, factor : array_like
        Frequencies (Hz) and |phi(f)|.
    label : str
        Legend label.
    tol : float or None
        Draw the line 1 - tol (the tolerated gain bias); None for no line.
    ax : Axes, optional

    Returns
    -------
    Plot
        ``factor`` and, with ``tol``, ``tolerance``.
    """
    ax = _axes(ax, 1)
    out: Artists = {"factor": ax.plot(f, factor, color="C0", lw=2, label=label)[0]}
    if tol is not None:
        out["tolerance"] = ax.axhline(
            1 - tol, color="C3", ls="--", lw=1, label=f"{100 * tol:g}% gain bias"
        )
    ax.set_xlabel("frequency f (Hz)")
    ax.set_ylabel("LS gain factor |φ(f)|")
    ax.set_ylim(bottom=0, top=1.05)
    ax.legend(loc="lower left", fontsize="small")
    ax.grid(True, alpha=0.3)
    return Plot(out, (ax,))


def plot_step_response(
    band: TimeResponseBand,
    references: Mapping[str, TransferFunction] | None = None,
    *,
    label: str = "estimate",
    ax: Any = None,
) -> Plot:
    """A step or impulse response (by ``band.kind``) with its pointwise confidence band.

    Parameters
    ----------
    band : TimeResponseBand
        From :func:`jitterid.step_response` or :func:`jitterid.impulse_response`.
    references : mapping of str to TransferFunction, optional
        Other systems whose response of the same kind is drawn at the same times, e.g.
        ``{"truth": g0}``.
    label : str
        Legend label of the estimate.
    ax : Axes, optional
        New axes (a new figure) if None.

    Returns
    -------
    Plot
        ``response``, ``band`` (absent where the band is empty or NaN) and, per reference,
        its name.

    Examples
    --------
    >>> import jitterid as ji
    >>> G = ji.TransferFunction([2.0], [1.0, 2.0])
    >>> u = ji.telegraph_input(10.0, rng=1)
    >>> data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=100, noise_std=0.01, rng=2)
    >>> res = ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05))
    >>> band = ji.step_response(res, [0.0, 1.0, 3.0])
    >>> plot = ji.plot_step_response(band, references={"true": G})
    >>> type(plot).__name__
    'Plot'
    """
    if not isinstance(band, TimeResponseBand):
        raise TypeError(
            f"band must be a TimeResponseBand (jitterid.step_response); got {type(band).__name__}"
        )
    ax = _axes(ax, 1)
    out: Artists = {"response": ax.plot(band.t_s, band.response, color="C0", lw=2, label=label)[0]}
    finite = np.isfinite(band.lo) & np.isfinite(band.hi)
    if finite.any() and np.any(band.hi[finite] > band.lo[finite]):
        how = {"delta": "delta method", "sampling": "parameter draws"}.get(band.method, band.method)
        out["band"] = ax.fill_between(
            band.t_s,
            band.lo,
            band.hi,
            where=finite,
            color="C0",
            alpha=0.25,
            lw=0,
            label=f"{100 * band.level:g}% pointwise band ({how})",
        )
    styles = ["--", ":", "-."]
    for i, (name, tf) in enumerate((references or {}).items()):
        out[name] = ax.plot(
            band.t_s,
            lti_response(tf, band.t_s, band.kind),
            color=f"C{i + 1}",
            ls=styles[i % len(styles)],
            lw=1.5,
            label=name,
        )[0]
    ax.axhline(0.0, color="k", lw=0.6, alpha=0.5)
    ax.set_ylabel(
        "step response (output per unit input)"
        if band.kind == "step"
        else "impulse response g(t) (output per unit input, per s)"
    )
    ax.set_xlabel("time after the " + band.kind + " t (s)")
    ax.set_xlim(float(np.min(band.t_s)), float(np.max(band.t_s)))
    ax.legend(loc="best", fontsize="small")
    ax.grid(True, alpha=0.3)
    return Plot(out, (ax,))
