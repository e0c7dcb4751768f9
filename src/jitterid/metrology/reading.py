"""Reading a jitter measurement: how firmly the law is chosen, and which Nyquist zone.

Two things a :class:`~jitterid.JitterMeasurement` cannot settle from the samples alone, said
plainly rather than left for the reader to miss:

- **the law** (:func:`law_evidence`): the family with the lowest BIC is chosen, but a BIC
  margin of a few units is weak evidence (Kass & Raftery: below 2 "not worth more than a
  bare mention", 2-6 "positive", above 6 "strong"). Below ``LAW_MARGIN_BIC`` the law is
  reported *undetermined*: the jitter std does not rest on the shape (the families agree on
  it where the data cannot tell them apart), and no pdf is drawn as if the shape were known;
- **the Nyquist zone** (:func:`nyquist_zones`): sampled at T, a tone at f and its aliases
  m/T +- f give the same samples, and with the jitter's scale free each fits as well, with
  the jitter std scaled by the ratio of the frequencies (the samples see only f times the
  jitter). Without the tone's frequency given, the zone is an assumption; the zones'
  jitter stds are listed so that the right one can be read off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

from ..estimation.result import FitStatus


class JitterMeasurement(Protocol):
    """What the reading reads of a :class:`jitterid.metrology.meter.JitterMeasurement` (a
    protocol here: the meter, above this module, adds its lines to its summary)."""

    @property
    def T(self) -> float: ...
    @property
    def family(self) -> str: ...
    @property
    def law_fitted(self) -> bool: ...
    @property
    def frequency(self) -> float: ...
    @property
    def jitter_std(self) -> float: ...
    @property
    def laws(self) -> Any: ...
    @property
    def converter(self) -> Any: ...

    def interval(self, level: float = ...) -> tuple[float, float]: ...


__all__ = [
    "LAW_MARGIN_BIC",
    "LawEvidence",
    "ZoneCandidate",
    "law_evidence",
    "nyquist_zones",
    "summary_extras",
]

#: The BIC margin over the runner-up family below which the law is undetermined.
LAW_MARGIN_BIC = 6.0


@dataclass(frozen=True)
class LawEvidence:
    """How firmly a measurement's jitter law is chosen.

    Attributes
    ----------
    verdict : str
        ``"chosen"`` (a BIC margin of at least ``margin`` over every other family that
        fitted), ``"undetermined"`` (a smaller margin) or ``"assumed"`` (one family only
        was fitted: its shape was given, not measured).
    delta_bic : float
        The runner-up's BIC minus the chosen one's (inf when no other family fitted).
    runner_up : str or None
        The runner-up family's name.
    margin : float
        The margin used.
    message : str
        The verdict in words.
    """

    verdict: str
    delta_bic: float
    runner_up: str | None
    margin: float
    message: str

    @property
    def determined(self) -> bool:
        """Whether the data chose the law (``verdict == "chosen"``)."""
        return self.verdict == "chosen"


def law_evidence(m: JitterMeasurement, margin: float = LAW_MARGIN_BIC) -> LawEvidence:
    """The BIC margin of a measurement's law over the runner-up family, and its verdict.

    Parameters
    ----------
    m : JitterMeasurement
        From :func:`jitterid.measure_jitter`.
    margin : float
        The smallest BIC margin that chooses a law (default ``LAW_MARGIN_BIC``, 6:
        "strong" evidence, posterior odds about 20 to 1).

    Returns
    -------
    LawEvidence

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> from jitterid.metrology.reading import law_evidence
    >>> rng = np.random.default_rng(0)
    >>> k = np.arange(400)
    >>> y = np.sin(2 * np.pi * 123 * (k * 1e-3 + 50e-6 * rng.standard_normal(400)))
    >>> m = ji.measure_jitter(y + 1e-2 * rng.standard_normal(400), 1e-3, laws=["gaussian"])
    >>> law_evidence(m).verdict
    'assumed'
    """
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a finite BIC difference >= 0; got {margin!r}")
    ok = (FitStatus.CONVERGED, FitStatus.AT_BOUND)
    others = [
        c
        for c in m.laws
        if c.name != m.family
        and (c.status in ok or getattr(c, "ranked_out", False))  # ranked out: a BIC bound
        and math.isfinite(c.bic)
    ]
    chosen = next((c for c in m.laws if c.name == m.family), None)
    if chosen is None or not others:
        tried = len(m.laws)
        why = "only this family was fitted" if tried <= 1 else "no other family's fit converged"
        words = f"law assumed ({m.family}): {why}, so its shape is not measured"
        if not m.law_fitted:  # (the moment route: the std whatever the law)
            words = (
                "no law fitted (law-free): the std from the moments, its interval holding "
                "whatever the law's shape; the kurtosis, where the moments tell it, is in the "
                "message"
            )
        return LawEvidence("assumed", math.inf, None, float(margin), words)
    best_other = min(others, key=lambda c: c.bic)
    delta = best_other.bic - chosen.bic
    if delta >= margin:
        return LawEvidence(
            "chosen",
            delta,
            best_other.name,
            float(margin),
            f"law {m.family} chosen by Delta BIC = {delta:.1f} over {best_other.name}",
        )
    return LawEvidence(
        "undetermined",
        delta,
        best_other.name,
        float(margin),
        f"law undetermined: {m.family} leads {best_other.name} by Delta BIC = {delta:.1f} < "
        f"{margin:g}, weak evidence; the jitter std does not rest on the shape (the families "
        f"give {_std(m, m.family)} and {_std(m, best_other.name)}), but the pdf is not known",
    )


def _std(m: JitterMeasurement, name: str) -> str:
    c = next(c for c in m.laws if c.name == name)
    return f"{c.jitter_std_s:.4g} s"


@dataclass(frozen=True)
class ZoneCandidate:
    """The tone in one Nyquist zone, and the jitter std the record then implies.

    Attributes
    ----------
    zone : int
        1 for ``[0, fs/2]``, 2 for ``[fs/2, fs]``, ...
    frequency_hz : float
        The tone's frequency if it lies in this zone.
    jitter_std_s : float
        The jitter std the record implies then (the measured one times the fitted frequency
        over this one).
    interval_s : (float, float)
        Its 95 % interval, scaled alike.
    fitted : bool
        Whether this is the zone the measurement was made in.
    """

    zone: int
    frequency_hz: float
    jitter_std_s: float
    interval_s: tuple[float, float]
    fitted: bool


def nyquist_zones(m: JitterMeasurement, zones: int = 4) -> tuple[ZoneCandidate, ...]:
    """The jitter std a measurement implies if its tone lies in each of the first Nyquist zones.

    With the jitter's scale free the samples see only the phase noise 2 pi f sigma, so the
    tone's alias in zone ``z`` (``f_z = (z // 2) / T +- f_1``) fits the record as well, with
    the jitter std ``sigma f / f_z`` (``f`` the measured frequency). Give the frequency
    (``frequency=``, ``--frequency``) when the tone is not in the first zone.

    Parameters
    ----------
    m : JitterMeasurement
        From :func:`jitterid.measure_jitter`.
    zones : int
        How many zones to list (1..64).

    Returns
    -------
    tuple of ZoneCandidate
        Zone 1 first.

    Examples
    --------
    >>> import numpy as np
    >>> import jitterid as ji
    >>> from jitterid.metrology.reading import nyquist_zones
    >>> rng = np.random.default_rng(0)
    >>> k = np.arange(400)
    >>> y = np.sin(2 * np.pi * 123 * (k * 1e-3 + 50e-6 * rng.standard_normal(400)))
    >>> m = ji.measure_jitter(y + 1e-2 * rng.standard_normal(400), 1e-3, laws=["gaussian"])
    >>> [round(z.frequency_hz) for z in nyquist_zones(m, 3)]
    [123, 877, 1123]
    """
    if isinstance(zones, bool) or not isinstance(zones, int) or not 1 <= zones <= 64:
        raise ValueError(f"zones must be an integer in 1..64; got {zones!r}")
    fs = 1.0 / m.T
    f = float(m.frequency)
    r = (f / fs) % 1.0
    f1 = min(r, 1.0 - r) * fs
    lo, hi = m.interval(0.95)
    out = []
    for z in range(1, zones + 1):
        base = (z // 2) * fs
        fz = base + f1 if z % 2 else base - f1
        if fz <= 0:
            continue
        scale = f / fz
        out.append(
            ZoneCandidate(
                z,
                fz,
                m.jitter_std * scale,
                (lo * scale, hi * scale),
                abs(fz - f) <= 1e-9 * max(f, fz),
            )
        )
    return tuple(out)


def summary_extras(m: JitterMeasurement) -> list[str]:
    """The lines :meth:`JitterMeasurement.summary` adds: the law's evidence (when the data
    did not choose it) and the converter figures (or how to get them)."""
    lines = []
    ev = law_evidence(m)
    if ev.verdict != "chosen":
        lines.append(f"  note: {ev.message}")
    if m.converter is not None:
        lines.extend(m.converter.summary_lines())
    else:
        lines.append(
            "  converter figures (SNR, SINAD, ENOB, THD, SFDR): m.with_converter(y) adds them"
        )
    return lines
