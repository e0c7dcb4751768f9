"""Matplotlib figures for the diagnostics; computing lives in :mod:`jitterid.analysis.diagnostics`.

Every function takes ``ax=None`` (new axes are created) or the axes to draw on, and returns
a dict of the artists it made, in the style of python-control. Frequencies are in Hz.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .analysis.diagnostics import JitterDetection
from .analysis.uncertainty import BodeBand, PdfBand
from .jitter.laws import JitterLaw
from .systems.tf import TransferFunction

__all__ = ["plot_bode", "plot_gain_factor", "plot_jitter_pdf", "plot_residuals"]

Artists = dict[str, Any]


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
) -> Artists:
    """Bode magnitude and phase of an estimate with its confidence band.

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
        (magnitude axes, phase axes); new ones if None.

    Returns
    -------
    dict
        ``magnitude``, ``magnitude_band``, ``phase``, ``phase_band`` and, per reference,
        ``"<name> magnitude"`` / ``"<name> phase"``.
    """
    if not isinstance(band, BodeBand):
        raise TypeError(f"band must be a BodeBand; got {type(band).__name__}")
    ax_mag, ax_ph = _axes(ax, 2, sharex=True, figsize=(6.4, 6.0))
    pct = f"{100 * band.level:g}% band"
    out: Artists = {
        "magnitude": ax_mag.loglog(band.f, band.magnitude, color="C0", lw=2, label=label)[0],
        "magnitude_band": ax_mag.fill_between(
            band.f, band.magnitude_lo, band.magnitude_hi, color="C0", alpha=0.25, lw=0, label=pct
        ),
        "phase": ax_ph.semilogx(band.f, band.phase, color="C0", lw=2, label=label)[0],
        "phase_band": ax_ph.fill_between(
            band.f, band.phase_lo, band.phase_hi, color="C0", alpha=0.25, lw=0, label=pct
        ),
    }
    styles = ["--", ":", "-."]
    for i, (name, tf) in enumerate((references or {}).items()):
        g = tf.frequency_response(band.f)
        style = {"color": f"C{i + 1}", "ls": styles[i % len(styles)], "lw": 1.5, "label": name}
        out[f"{name} magnitude"] = ax_mag.loglog(band.f, np.abs(g), **style)[0]
        out[f"{name} phase"] = ax_ph.semilogx(band.f, np.degrees(np.unwrap(np.angle(g))), **style)[
            0
        ]
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")  # 0.8, not 8 x 10^-1, on narrow log ranges
    ax_mag.yaxis.set_major_formatter(plain)
    ax_mag.yaxis.set_minor_formatter(plain)
    ax_mag.set_ylabel("|G(i 2π f)|")
    ax_ph.set_ylabel("phase (deg)")
    ax_ph.set_xlabel("frequency f (Hz)")
    ax_mag.legend(loc="lower left", fontsize="small")
    for a in (ax_mag, ax_ph):
        a.grid(True, which="both", alpha=0.3)
    return out


def plot_jitter_pdf(
    band: PdfBand,
    truth: JitterLaw | None = None,
    *,
    label: str = "estimated pdf",
    ax: Any = None,
) -> Artists:
    """The estimated jitter density with its band (and the true one, if known).

    Parameters
    ----------
    band : PdfBand
        From :func:`jitterid.analysis.diagnostics.jitter_pdf_band`.
    truth : JitterLaw, optional
        A reference law drawn dashed.
    label : str
        Legend label of the estimate.
    ax : Axes, optional

    Returns
    -------
    dict
        ``pdf``, ``band`` (absent for a known law, whose band is empty) and ``truth``.
    """
    if not isinstance(band, PdfBand):
        raise TypeError(f"band must be a PdfBand; got {type(band).__name__}")
    ax = _axes(ax, 1)
    out: Artists = {"pdf": ax.plot(band.tau, band.pdf, color="C0", lw=2, label=label)[0]}
    if np.any(band.hi > band.lo):
        note = f" ({', '.join(band.fixed)} fixed)" if band.fixed else ""
        out["band"] = ax.fill_between(
            band.tau,
            band.lo,
            band.hi,
            color="C0",
            alpha=0.25,
            lw=0,
            label=f"{100 * band.level:g}% band{note}",
        )
    if truth is not None:
        out["truth"] = ax.plot(
            band.tau, truth.pdf(band.tau), "k--", lw=1.5, label=f"reference {truth!r}"
        )[0]
    ax.set_xlabel("jitter τ (s)")
    ax.set_ylabel("density p(τ) (1/s)")
    # Keep the estimate readable when the band's upper edge runs off (a nearly degenerate
    # law among the draws): the band then leaves the top of the axes.
    top = 2.5 * max(float(np.max(band.pdf)), float(np.max(truth.pdf(band.tau))) if truth else 0.0)
    ax.set_ylim(bottom=0, top=min(top, 1.15 * max(float(np.max(band.hi)), float(np.max(band.pdf)))))
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(True, alpha=0.3)
    return out


def plot_residuals(detection: JitterDetection, *, ax: Any = None) -> Artists:
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
    dict
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
    return out


def plot_gain_factor(
    f: ArrayLike,
    factor: ArrayLike,
    *,
    label: str = "|φ(f)|",
    tol: float | None = 0.01,
    ax: Any = None,
) -> Artists:
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
    dict
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
    return out
