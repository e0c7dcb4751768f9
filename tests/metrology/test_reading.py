"""Reading a measurement: the law's BIC evidence and the Nyquist zones (issue 26, item 5)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation.result import FitStatus
from jitterid.metrology.meter import LawCandidate
from jitterid.metrology.reading import law_evidence, nyquist_zones

T, N, F, SIGMA = 1e-3, 400, 123.0, 50e-6


@pytest.fixture(scope="module")
def m() -> ji.JitterMeasurement:
    rng = np.random.default_rng(0)
    t = np.arange(N) * T + SIGMA * rng.standard_normal(N)
    y = np.sin(2 * np.pi * F * t) + 1e-2 * rng.standard_normal(N)
    return ji.measure_jitter(y, T, laws=["gaussian"], method="gaussian")


def _with_laws(m: ji.JitterMeasurement, bics: dict[str, float]) -> ji.JitterMeasurement:
    laws = tuple(
        LawCandidate(name, -b / 2, 6, b, b, 5e-5, FitStatus.CONVERGED) for name, b in bics.items()
    )
    return dataclasses.replace(m, laws=laws, family=min(bics, key=bics.__getitem__))


@pytest.mark.parametrize(
    ("bics", "verdict", "delta"),
    [
        ({"gaussian": -100.0}, "assumed", math.inf),
        ({"uniform": -100.0, "gaussian": -97.8}, "undetermined", 2.2),  # the margin
        ({"gaussian": -100.0, "uniform": -94.0, "dual-dirac": -80.0}, "chosen", 6.0),
        ({"gaussian": -100.0, "uniform": -94.1}, "undetermined", 5.9),
    ],
)
def test_law_verdict_follows_the_bic_margin(
    m: ji.JitterMeasurement, bics: dict[str, float], verdict: str, delta: float
) -> None:
    ev = law_evidence(_with_laws(m, bics))
    assert ev.verdict == verdict
    assert ev.delta_bic == pytest.approx(delta)
    assert ev.determined == (verdict == "chosen")


def test_a_failed_rival_does_not_count(m: ji.JitterMeasurement) -> None:
    mm = _with_laws(m, {"gaussian": -100.0, "uniform": -99.0})
    laws = (mm.laws[0], dataclasses.replace(mm.laws[1], status=FitStatus.NOT_FINITE))
    ev = law_evidence(dataclasses.replace(mm, laws=laws))
    assert ev.verdict == "assumed"
    assert "no other family's fit converged" in ev.message


def test_a_law_free_measurement_says_no_law_was_fitted(m: ji.JitterMeasurement) -> None:
    """The law-free moment route (the default laws with method="gaussian") fits no law:
    before session 26 the evidence said "law assumed (law-free) ... its shape is not
    measured" beside a message giving the measured kurtosis."""
    rng = np.random.default_rng(0)
    t = np.arange(N) * T + SIGMA * rng.standard_normal(N)
    y = np.sin(2 * np.pi * F * t) + 1e-2 * rng.standard_normal(N)
    free = ji.measure_jitter(y, T, method="gaussian")
    assert free.family == "law-free"
    ev = law_evidence(free)
    assert ev.verdict == "assumed"
    assert ev.message.startswith("no law fitted (law-free)")
    assert "kurtosis" in ev.message
    assert law_evidence(m).message.startswith("law assumed (gaussian)")


def test_an_undetermined_law_is_said_in_the_summary(m: ji.JitterMeasurement) -> None:
    text = _with_laws(m, {"uniform": -100.0, "gaussian": -97.8}).summary()
    assert "law undetermined" in text
    assert "Delta BIC = 2.2" in text


def test_zones_scale_the_jitter_by_the_frequency(m: ji.JitterMeasurement) -> None:
    zones = nyquist_zones(m, 5)
    fs = 1 / T
    f1 = m.frequency
    assert [z.frequency_hz for z in zones] == pytest.approx(
        [f1, fs - f1, fs + f1, 2 * fs - f1, 2 * fs + f1]
    )
    lo, hi = m.interval()
    for z in zones:
        assert z.jitter_std_s == pytest.approx(m.jitter_std * f1 / z.frequency_hz)
        assert z.interval_s == pytest.approx((lo * f1 / z.frequency_hz, hi * f1 / z.frequency_hz))
    assert [z.fitted for z in zones] == [True, False, False, False, False]


def test_zones_of_a_tone_measured_above_nyquist(m: ji.JitterMeasurement) -> None:
    # measured in zone 3 (f = fs + f1): the listing marks zone 3, zone 1 carries 9x the jitter
    fs = 1 / T
    up = dataclasses.replace(
        m, frequency=fs + m.frequency, jitter_std=m.jitter_std * m.frequency / (fs + m.frequency)
    )
    zones = nyquist_zones(up, 4)
    assert [z.fitted for z in zones] == [False, False, True, False]
    assert zones[0].jitter_std_s == pytest.approx(m.jitter_std)


@pytest.mark.parametrize("bad", [0, 65, 2.0, True])
def test_zones_refuse_a_bad_count(m: ji.JitterMeasurement, bad: object) -> None:
    with pytest.raises(ValueError, match="zones"):
        nyquist_zones(m, bad)  # type: ignore[arg-type]


def test_summary_offers_and_shows_the_converter_figures(m: ji.JitterMeasurement) -> None:
    assert "m.with_converter(y)" in m.summary()
    rng = np.random.default_rng(0)
    t = np.arange(N) * T + SIGMA * rng.standard_normal(N)
    y = np.sin(2 * np.pi * F * t) + 1e-2 * rng.standard_normal(N)
    with_figs = m.with_converter(y, full_scale=2.0)
    assert with_figs.converter is not None
    assert with_figs.jitter_std == m.jitter_std
    assert "ENOB" in with_figs.summary()
    assert "dBFS" in with_figs.summary()


def test_a_far_better_family_that_did_not_settle_unsettles_the_measurement(monkeypatch):
    """Where the family that fits best ends with a status that is not a success (here made
    UNIDENTIFIABLE), the measurement is not reported CONVERGED with the best of the rest:
    before, a 12-bit record with Gaussian jitter was reported uniform, CONVERGED, 1444
    below the Gaussian in ln L, its interval 4 errors off the truth."""
    from jitterid.metrology import meter

    rng = np.random.default_rng(3)
    t = np.arange(400) + 0.05 * rng.standard_normal(400)
    y = np.sin(2 * np.pi * 0.1234 * t) + 1e-3 * rng.standard_normal(400)
    m = ji.measure_jitter(y, 1.0, laws=["gaussian", "uniform"])
    assert m.status is FitStatus.CONVERGED  # the control
    assert m.family == "gaussian"
    fit_one = meter._fit_one

    def unsettled(data, model, family, *args, **kwargs):
        r = fit_one(data, model, family, *args, **kwargs)
        if isinstance(family, ji.GaussianFamily):
            r = dataclasses.replace(r, status=FitStatus.UNIDENTIFIABLE, message="(the test's)")
        return r

    monkeypatch.setattr(meter, "_fit_one", unsettled)
    m = ji.measure_jitter(y, 1.0, laws=["gaussian", "uniform"])
    assert m.family == "uniform"
    assert m.status is FitStatus.UNIDENTIFIABLE
    assert "the gaussian family fits the record better than the uniform" in m.message
    assert "(the test's)" in m.message
