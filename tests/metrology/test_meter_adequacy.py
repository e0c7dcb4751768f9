"""The meter's model-adequacy checks (issue 25 item 2): a record that is not one jittered tone
is never reported as a measurement.

Referees: records made here with numpy whose defect is known by construction (a second
tone, clipping, no tone, a tone at fs), clean records for the false-alarm rate, and the
null distributions the tests are built on (white noise: the largest of M exponential
periodogram ordinates; the F test's Bonferroni bound).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology import adequacy
from jitterid.metrology.meter import _judge

T, F = 1e-3, 123.0


def _issue_records():
    """The four records of issue 25 item 2, verbatim."""
    r = np.random.default_rng(0)
    k = np.arange(400)
    t = k * 1e-3 + 50e-6 * r.standard_normal(400)
    n = 1e-2 * r.standard_normal(400)
    return {
        "two tones": np.sin(2 * np.pi * 123 * t + 0.3) + np.sin(2 * np.pi * 301 * t + 1.1) + n,
        "clipped": np.clip(1.3 * np.sin(2 * np.pi * 123 * t + 0.3), -1, 1) + n,
        "no tone": np.sin(0.3) + n + 0 * t,
        "f = fs": np.sin(2 * np.pi * 1000 * t + 0.3) + n,
    }


@pytest.mark.parametrize(
    ("name", "status", "kind"),
    [
        ("two tones", ji.FitStatus.LACK_OF_FIT, "lines"),
        ("clipped", ji.FitStatus.LACK_OF_FIT, "lines"),
        ("no tone", ji.FitStatus.NOT_SIGNIFICANT, "no-tone"),
        ("f = fs", ji.FitStatus.NOT_SIGNIFICANT, "no-tone"),
    ],
)
def test_the_issue_records_are_not_reported_as_measurements(name, status, kind):
    """Before: CONVERGED on all four (20.6 ns +- NaN, 11.5 ps +- NaN, a 65.6 Hz 'tone',
    1.85 ms at 130 Hz)."""
    m = ji.measure_jitter(_issue_records()[name], 1e-3, laws=["gaussian"])
    assert m.status is status, (m.status, m.message)
    assert kind in {f.kind for f in m.findings}
    assert m.message  # says what was found and what to do
    assert kind != "lines" or "harmonics=" in m.message or "second tone" in m.message


def test_the_second_tone_is_named_and_clipping_as_harmonics():
    recs = _issue_records()
    two = ji.measure_jitter(recs["two tones"], 1e-3, method="gaussian")
    lines = two.findings[0].message
    assert "122.5 Hz" in lines or "123 Hz" in lines  # the tone that was not fitted
    clipped = ji.measure_jitter(recs["clipped"], 1e-3, method="gaussian")
    assert "harmonic 3" in clipped.message
    assert "clips" in clipped.message


def test_a_quantised_clipped_record_is_seen_piled_on_its_rails():
    """A 10-bit converter driven 20 % beyond full scale: the top and bottom codes hold
    about a fifth of the samples each; the fitted sine puts a handful there."""
    rng = np.random.default_rng(3)
    N = 2000
    t = np.arange(N) * T + 20e-6 * rng.standard_normal(N)
    x = 1.2 * np.sin(2 * np.pi * F * t + 0.4) + 1e-3 * rng.standard_normal(N)
    q = 2 / 1024
    y = np.clip(np.round(x / q) * q, -1, 1 - q)
    m = ji.measure_jitter(y, T, method="gaussian")
    assert m.status is ji.FitStatus.LACK_OF_FIT
    kinds = {f.kind for f in m.findings}
    assert "clipping" in kinds
    assert "rail" in m.message


def test_a_tone_on_a_folding_frequency_is_refused_as_unidentifiable():
    """A coherent tone at fs/4 visits four phases; one within a bin of Nyquist repeats two."""
    rng = np.random.default_rng(4)
    N = 512
    k = np.arange(N)
    for f in (250.0, 500.0 - 0.5 / (N * T)):
        y = np.sin(2 * np.pi * f * (k * T + 5e-6 * rng.standard_normal(N)) + 0.7)
        y += 1e-3 * rng.standard_normal(N)
        m = ji.measure_jitter(y, T, frequency=f, method="gaussian")
        assert m.status is ji.FitStatus.UNIDENTIFIABLE, (f, m.message)
        assert "folding" in {x.kind for x in m.findings}
        assert "fs/2" in m.message


def test_the_folding_check_refuses_only_phases_where_the_slope_cannot_vary():
    """The referee: the variance of cos(2 phi_k + 2 phi) over the samples, minimised over
    the tone's phase phi by brute force (0.5 where the phases cover the period). Coherent
    at fs/P: P = 4 leaves four phases whose slopes are equal in size at phi = pi/4 (spread
    0: refused); P = 3, 5, 6, 7, 8 have spread 0.5 (measured). Before session 26 every P
    below 8 was refused (fewer than 8 of 16 phase bins)."""
    from jitterid.metrology.adequacy import folding_check

    Ts, N = 1e-9, 1024
    k = np.arange(N)
    for P in (3, 4, 5, 6, 7, 8):
        phis = np.linspace(0, np.pi, 181)
        brute = min(float(np.var(np.cos(2 * (2 * np.pi * k / P + p)))) for p in phis)
        finding = folding_check(1 / (P * Ts), Ts, N)
        assert (finding is not None) == (brute < 0.1), (P, brute, finding)
        assert (P == 4) == (finding is not None)


def test_a_coherent_tone_at_fs_over_7_is_measured():
    """1 GHz at 7 GS/s, exactly coherent (every seventh sample repeats the phase), 100 fs
    of Gaussian jitter, 20 uV of noise, N = 4096: before session 26 UNIDENTIFIABLE ("sampled
    at only 7 of 16 phase bins"); its seven phases have slopes of four different sizes
    whatever the tone's phase, and the moment route measures it (16 records: at least 13
    intervals cover the truth); the likelihood on one record as well."""
    Ts, N, sj = 1 / 7e9, 4096, 100e-15
    t = np.arange(N) * Ts
    covered = 0
    for seed in range(16):
        rng = np.random.default_rng(seed)
        tau = sj * rng.standard_normal(N)
        y = 0.49 * np.sin(2 * np.pi * 1e9 * (t + tau) + rng.uniform(0, 2 * np.pi))
        y += 20e-6 * rng.standard_normal(N)
        m = ji.measure_jitter(y, Ts, method="gaussian")
        assert "folding" not in {x.kind for x in m.findings}, m.message
        assert m.status is ji.FitStatus.CONVERGED, m.message
        lo, hi = m.interval()
        covered += lo <= sj <= hi
        if seed == 0:
            ml = ji.measure_jitter(y[:2048], Ts, laws=["gaussian"])
            assert ml.status is ji.FitStatus.CONVERGED, ml.message
            assert abs(ml.jitter_std - sj) < 3 * ml.jitter_std_stderr
    assert covered >= 13, covered


def test_white_noise_is_not_measured():
    """A record with no tone at all: NOT_SIGNIFICANT, or a ValueError naming it where the
    periodogram's peak sits on DC or Nyquist (no sine can even be fitted there)."""
    for seed in range(6):
        y = np.random.default_rng(40 + seed).standard_normal(256)
        try:
            m = ji.measure_jitter(y, T, method="gaussian")
        except ValueError as exc:
            message = str(exc)
        else:
            message = "no tone" if m.status is ji.FitStatus.NOT_SIGNIFICANT else m.message
        assert "no tone" in message


def test_nan_stderr_is_never_next_to_converged():
    rng = np.random.default_rng(5)
    t = np.arange(400) * T + 50e-6 * rng.standard_normal(400)
    y = np.sin(2 * np.pi * F * t) + 1e-2 * rng.standard_normal(400)
    m = ji.measure_jitter(y, T, method="gaussian")
    assert m.status is ji.FitStatus.CONVERGED
    broken = dataclasses.replace(m.fit, cov=np.full_like(m.fit.cov, np.nan))
    status, message = _judge(ji.FitStatus.CONVERGED, "", broken, ())
    assert status is ji.FitStatus.UNIDENTIFIABLE
    assert "standard error" in message


def test_the_line_test_keeps_its_false_alarm_rate_on_white_noise():
    """Referee: the largest of M Exp(1) ordinates; 600 white records, alpha = 0.01."""
    rng = np.random.default_rng(6)
    hits = 0
    for _ in range(600):
        z = rng.standard_normal(500)
        hits += bool(adequacy.residual_lines(z, np.ones(500), T, F))
    assert hits <= 15, hits  # expected 6; P(X > 15 | 600, 0.01) < 1e-3


def test_the_line_test_finds_a_weak_spur():
    rng = np.random.default_rng(7)
    N = 4000
    k = np.arange(N)
    z = rng.standard_normal(N) + 0.15 * np.sin(2 * np.pi * 0.2013 * k)
    lines = adequacy.residual_lines(z, np.ones(N), 1.0, 0.10065)
    assert lines
    assert lines[0].frequency_hz == pytest.approx(0.2013, abs=1.5 / N)
    assert lines[0].harmonic == 2  # 0.2013 = 2 x 0.10065
    other = adequacy.residual_lines(z, np.ones(N), 1.0, 0.137)
    assert other[0].harmonic == 0


def test_no_tone_is_significant_in_white_noise():
    rng = np.random.default_rng(8)
    fired = 0
    for _ in range(200):
        y = rng.standard_normal(300)
        f0 = min(ji.metrology.periodogram_peak(y, 1.0), 0.5 - 1 / 300)
        fit3 = ji.metrology.sine_fit_3(y, np.arange(300.0), f0)
        ss = float(fit3.residuals @ fit3.residuals)
        fired += adequacy.tone_significance(y, ss) < adequacy.ALPHA_TONE
    assert fired <= 2, fired  # Bonferroni: at most alpha = 1e-3 per record


def _clean(seed, law="gaussian", N=400, theta=0.3):
    rng = np.random.default_rng(seed)
    std = theta / (2 * np.pi * F)
    if law == "gaussian":
        tau = std * rng.standard_normal(N)
    else:
        tau = rng.uniform(-std * np.sqrt(3), std * np.sqrt(3), N)
    phase = rng.uniform(0, 2 * np.pi)
    t = np.arange(N) * T + tau
    return 1.3 * np.sin(2 * np.pi * F * t + phase) + 0.2 + 1e-2 * rng.standard_normal(N)


def test_clean_records_are_not_flagged_small():
    """A fast version of the slow false-alarm test: 24 clean records (Gaussian and uniform
    jitter), at most 2 flagged (the checks' rate is about 1-2 %). The record's own law is
    given, which keeps the fast route on the moments at 0.3 rad (with several laws it hands
    that spread to the likelihood: the slow test)."""
    flagged = 0
    for s in range(12):
        for law in ("gaussian", "uniform"):
            m = ji.measure_jitter(_clean(700 + s, law), T, method="gaussian", laws=[law])
            flagged += bool(m.findings)
    assert flagged <= 2, flagged


@pytest.mark.slow
@pytest.mark.parametrize("law", ["gaussian", "uniform"])
@pytest.mark.parametrize("theta", [0.01, 0.3])
def test_false_alarm_rate_on_clean_records(law, theta):
    """60 clean records per cell: the checks flag at most 5 % (measured: 2 % at 0.3 rad
    Gaussian over 200 records). A "sharp-edges" finding is not a false alarm: it says that
    the fitted uniform's edges are sharper than the record resolves, where its interval is
    measured too narrow (jitterid.metrology.edges); these uniform records at 0.3 rad are in
    that regime (the noise blurs the edges over 2-4 x the spacing of the jitter values), and
    every one of them says so (counted as a false alarm, this cell failed 60 / 60 from
    session 15, when the finding was added, to session 17, when this slow test was run)."""
    records = [
        ji.measure_jitter(_clean(900 + s, law, theta=theta), T, method="gaussian")
        for s in range(60)
    ]
    flagged = sum(any(f.kind != "sharp-edges" for f in m.findings) for m in records)
    assert flagged <= 3, flagged
    edges = sum(any(f.kind == "sharp-edges" for f in m.findings) for m in records)
    if law == "uniform" and theta == 0.3:
        assert edges == 60, edges
    else:
        assert edges == 0, edges


@pytest.mark.slow
def test_false_alarm_rate_with_the_likelihood():
    """The default route (exact likelihood, two families) on 30 clean records."""
    flagged = sum(
        bool(ji.measure_jitter(_clean(1100 + s), T, laws=["gaussian", "uniform"]).findings)
        for s in range(30)
    )
    assert flagged <= 2, flagged


def test_the_command_line_says_it_too(tmp_path):
    """Issue 25: the same through ``jitterid jitter`` (it exited 0 with CONVERGED)."""
    from click.testing import CliRunner

    from jitterid.cli import main

    y = _issue_records()["two tones"]
    path = tmp_path / "two.csv"
    rows = "".join(f"{k},{float(v)!r}\n" for k, v in enumerate(y))
    path.write_text("# T: 1\n# time_unit: ms\nk,y\n" + rows)
    res = CliRunner().invoke(main, ["jitter", str(path), "--law", "gaussian"])
    assert res.exit_code != 0, res.output
    assert "LACK_OF_FIT" in res.output


def test_a_tiny_record_is_measured_and_a_zero_record_refused():
    """The constant-record threshold is relative to the record's size (issue 25, item 9): a
    tone of 1e-14 (a pA sensor in amperes) is a record, an all-zero one is not."""
    t = np.arange(400) * 1e-3
    rng = np.random.default_rng(0)
    y = 1e-14 * np.sin(2 * np.pi * 123 * t + 0.3) + 1e-17 * rng.standard_normal(400)
    m = ji.measure_jitter(y, 1e-3, laws=["gaussian"], method="gaussian")
    assert m.frequency == pytest.approx(123.0, rel=1e-3)
    with pytest.raises(ValueError, match="constant"):
        ji.measure_jitter(np.zeros(400), 1e-3)
