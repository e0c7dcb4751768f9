"""Converter figures (IEEE 1241) against textbook values and a second, frequency-domain route."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jitterid.metrology.converter import (
    converter_figures,
    separate_aperture_jitter,
    significant_harmonics,
)

T = 1e-6


def _quantise(x: np.ndarray, bits: int, full_scale: float = 2.0) -> np.ndarray:
    q = full_scale / 2**bits
    return q * np.round(x / q)


@pytest.mark.parametrize("bits", [6, 8, 10, 12, 14])
@pytest.mark.parametrize("full_scale", [2.0, None])
def test_enob_of_an_ideal_quantiser_is_its_bits(bits: int, full_scale: float | None) -> None:
    # a full-scale, non-coherent sine through an ideal N-bit quantiser: NAD = q / sqrt(12)
    N, f = 1 << 14, 12_468.9
    q = 2.0 / 2**bits
    x = (1 - q / 2) * np.sin(2 * np.pi * f * np.arange(N) * T + 0.3)
    fig = converter_figures(_quantise(x, bits), T, f, full_scale=full_scale)
    assert abs(fig.enob_bits - bits) < 0.1
    # the textbook SINAD of an ideal quantiser, 6.02 N + 1.76 dB
    assert abs(fig.sinad_db - (6.0206 * bits + 1.761)) < 0.6
    assert not fig.coherent


@pytest.mark.parametrize("cycles", [1237.0, 1237.37])  # coherent, and not
def test_thd_and_harmonics_of_known_amplitudes(cycles: float) -> None:
    N = 1 << 14
    f = cycles / (N * T)
    ph = 2 * np.pi * f * np.arange(N) * T + 0.2
    a2, a3 = 1e-3, 5e-4
    rng = np.random.default_rng(0)
    y = np.sin(ph) + a2 * np.sin(2 * ph + 1) + a3 * np.sin(3 * ph + 2)
    y = y + 1e-6 * rng.standard_normal(N)
    fig = converter_figures(y, T, f)
    assert fig.coherent == (cycles == round(cycles))
    assert fig.thd_db == pytest.approx(20 * math.log10(math.hypot(a2, a3)), abs=0.01)
    hd = {h.order: h for h in fig.harmonics}
    assert hd[2].dbc == pytest.approx(20 * math.log10(a2), abs=0.01)
    assert hd[3].dbc == pytest.approx(20 * math.log10(a3), abs=0.01)
    assert hd[2].significant
    assert hd[3].significant
    assert not hd[4].significant
    assert not hd[5].significant
    # SFDR is set by HD2; SINAD counts the harmonics, SNR does not
    assert fig.spur_is_harmonic == 2
    assert fig.sfdr_db == pytest.approx(60.0, abs=0.01)
    assert fig.snr_db == pytest.approx(10 * math.log10(0.5 / 1e-12), abs=0.2)
    sinad = 10 * math.log10(0.5 / (1e-12 + 0.5 * (a2**2 + a3**2)))
    assert fig.sinad_db == pytest.approx(sinad, abs=0.01)


def test_snr_and_noise_floor_of_known_white_noise() -> None:
    N, f, A, sv = 1 << 14, 23_456.7, 0.8, 1e-3
    rng = np.random.default_rng(5)
    y = A * np.sin(2 * np.pi * f * np.arange(N) * T) + sv * rng.standard_normal(N)
    fig = converter_figures(y, T, f)
    # the mean square of N residuals has a relative sd of sqrt(2 / N): 0.048 dB here
    truth = 10 * math.log10(0.5 * A**2 / sv**2)
    assert fig.snr_db == pytest.approx(truth, abs=4 * 4.343 * math.sqrt(2 / N))
    density = sv**2 / (0.5 / T)  # one-sided, y^2 / Hz
    assert fig.noise_floor_dbc_hz == pytest.approx(10 * math.log10(density / (0.5 * A**2)), abs=0.2)
    # without spurs SFDR is set by the noise's largest line: about SNR + 10 log10(N / 2)
    # less the largest of N / 2 exponential draws, ln(N / 2) + 0.577 in power (Gumbel)
    expect = truth + 10 * math.log10(N / 2) - 10 * math.log10(math.log(N / 2) + 0.5772)
    assert abs(fig.sfdr_db - expect) < 3.0
    assert fig.spur_is_harmonic == 0


def test_coherent_record_agrees_with_the_dft_bins() -> None:
    # second route: on a coherent record every tone sits on a bin, so the textbook
    # frequency-domain computation (rectangular window, power per bin) is exact
    N, cycles = 4096, 301
    f = cycles / (N * T)
    rng = np.random.default_rng(7)
    ph = 2 * np.pi * f * np.arange(N) * T
    y = 0.9 * np.sin(ph + 0.4) + 2e-3 * np.cos(2 * ph) + 7e-4 * np.sin(4 * ph + 1) + 0.05
    y = y + 3e-4 * rng.standard_normal(N)
    fig = converter_figures(y, T, f)
    X = np.fft.rfft(y) / N
    power = 2 * np.abs(X) ** 2  # one-sided power per bin
    power[N // 2] /= 2  # the Nyquist bin has no mirror image
    p1 = power[cycles]
    harm = sum(power[h * cycles] for h in range(2, 6))
    noise = power[1:].sum() - p1 - harm
    assert fig.snr_db == pytest.approx(10 * math.log10(p1 / noise), abs=1e-6)
    assert fig.sinad_db == pytest.approx(10 * math.log10(p1 / (noise + harm)), abs=1e-6)
    assert fig.thd_db == pytest.approx(10 * math.log10(harm / p1), abs=1e-6)
    assert fig.amplitude == pytest.approx(math.sqrt(2 * p1), rel=1e-9)
    spur = max(power[k] for k in range(1, N // 2) if k != cycles)
    assert fig.sfdr_db == pytest.approx(10 * math.log10(p1 / spur), abs=1e-6)


def test_non_harmonic_spur_sets_the_sfdr() -> None:
    N, f, fs_spur = 1 << 14, 37_123.4, 123_456.7
    rng = np.random.default_rng(1)
    t = np.arange(N) * T
    y = np.sin(2 * np.pi * f * t) + 1e-3 * np.sin(2 * np.pi * fs_spur * t + 0.7)
    y = y + 1e-5 * rng.standard_normal(N)
    fig = converter_figures(y, T, f)
    assert fig.sfdr_db == pytest.approx(60.0, abs=0.05)
    assert fig.spur_hz == pytest.approx(fs_spur, abs=0.05 / (N * T))
    assert fig.spur_is_harmonic == 0


def test_harmonics_that_alias_onto_the_tone_are_not_fitted() -> None:
    # f = fs / 4: HD2 lands on Nyquist, HD3 on the tone, HD4 on DC, HD5 on the tone
    N = 1024
    f = 0.25 / T
    y = np.sin(2 * np.pi * f * np.arange(N) * T + 0.3)
    y = y + 1e-4 * np.random.default_rng(0).standard_normal(N)
    fig = converter_figures(y, T, f)
    assert [h.separable for h in fig.harmonics] == [False, False, False, False]
    assert all(math.isnan(h.amplitude) for h in fig.harmonics)
    assert any("cannot be told" in n for n in fig.notes)
    assert math.isfinite(fig.snr_db)


def test_significant_harmonics() -> None:
    N, f = 4096, 97_300.0
    rng = np.random.default_rng(2)
    ph = 2 * np.pi * f * np.arange(N) * T
    clean = np.sin(ph) + 1e-4 * rng.standard_normal(N)
    assert significant_harmonics(clean, T, f) == 1
    assert significant_harmonics(clean + 1e-3 * np.sin(3 * ph), T, f) == 3
    assert significant_harmonics(clean + 1e-3 * np.sin(5 * ph), T, f, harmonics=4) == 1


def test_jitter_alone_gives_the_jitter_limited_snr() -> None:
    # independent route: a full-scale tone with jitter and no other error has the SNR
    # -20 log10(2 pi f sigma) that the figures quote for the measured jitter
    import jitterid as ji

    N, f, sigma = 1 << 13, 40_123.4, 4e-9  # 2 pi f sigma = 1.0e-3 rad: 60 dB
    rng = np.random.default_rng(11)
    y = np.sin(2 * np.pi * f * (np.arange(N) * T + sigma * rng.standard_normal(N)))
    y = y + 1e-7 * rng.standard_normal(N)
    m = ji.measure_jitter(y, T, f, laws=["gaussian"], method="gaussian", resolution=1e-7)
    fig = converter_figures(y, T, measurement=m)
    assert fig.frequency_hz == m.frequency
    assert fig.jitter_std_s == m.jitter_std
    assert fig.jitter_limited_snr_db == pytest.approx(
        -20 * math.log10(2 * math.pi * m.frequency * m.jitter_std), rel=1e-12
    )
    assert fig.snr_db == pytest.approx(fig.jitter_limited_snr_db, abs=0.2)
    lo, hi = fig.jitter_limited_snr_interval_db
    assert lo < fig.jitter_limited_snr_db < hi
    assert fig.snr_without_jitter_db > fig.snr_db + 20  # the jitter was the only error
    d = fig.to_dict()
    assert d["jitter_limited_snr_db"] == pytest.approx(fig.jitter_limited_snr_db)
    assert "jitter-limited SNR" in "\n".join(fig.summary_lines())


def _pair(rng: np.random.Generator, sj: float, sv: float, N: int) -> list[np.ndarray]:
    out = []
    for f in (1.13e6, 97.3e6):
        t = np.arange(N) * 1e-9 + sj * rng.standard_normal(N)
        out.append(0.9 * np.sin(2 * np.pi * f * t + 0.5) + sv * rng.standard_normal(N))
    return out


def test_two_frequency_separation_recovers_jitter_and_noise() -> None:
    rng = np.random.default_rng(4)
    sj, sv = 3e-12, 2e-4
    est = []
    for _ in range(60):
        sep = separate_aperture_jitter(_pair(rng, sj, sv, 4096), 1e-9)
        est.append((sep.jitter_std_s, sep.jitter_std_stderr_s, sep.noise_std))
    arr = np.array(est)
    # unbiased within its Monte Carlo error, and the stated errors match the spread
    assert abs(arr[:, 0].mean() - sj) < 4 * arr[:, 0].std() / math.sqrt(len(arr))
    assert 0.75 < arr[:, 1].mean() / arr[:, 0].std() < 1.33
    assert abs(arr[:, 2].mean() - sv) < 0.02 * sv
    assert sep.resolved


def test_two_frequency_separation_without_jitter_is_an_upper_bound() -> None:
    rng = np.random.default_rng(8)
    sep = separate_aperture_jitter(_pair(rng, 0.0, 2e-4, 4096), [1e-9, 1e-9])
    assert not sep.resolved
    assert "upper bound" in sep.message
    assert sep.jitter_interval_s[0] == 0.0
    assert sep.jitter_interval_s[1] > 0


@pytest.mark.parametrize(
    ("args", "kwargs", "words"),
    [
        (([np.zeros(100)], 1e-9), {}, "at least two"),
        (([np.ones(100), np.ones(100)], [1e-9]), {}, "one value per record"),
    ],
)
def test_separation_refuses_bad_input(args: tuple, kwargs: dict, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        separate_aperture_jitter(*args, **kwargs)


def test_equal_slopes_are_refused() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(2048) * 1e-9
    y = [np.sin(2 * np.pi * 5e6 * t) + 1e-4 * rng.standard_normal(t.size) for _ in range(2)]
    with pytest.raises(ValueError, match="low and one at a high"):
        separate_aperture_jitter(y, 1e-9, [5e6, 5e6])


@pytest.mark.parametrize(
    ("y", "kwargs", "exc", "words"),
    [
        (np.ones(100), {}, ValueError, "constant"),
        (np.ones(5), {}, ValueError, "at least"),
        (np.sin(np.arange(100.0)), {"full_scale": -1.0}, ValueError, "full_scale"),
        (np.sin(np.arange(100.0)), {"harmonics": 0}, ValueError, "harmonics"),
        (np.sin(np.arange(100.0)), {"harmonics": 2.5}, TypeError, "harmonics"),
    ],
)
def test_figures_refuse_bad_input(y: np.ndarray, kwargs: dict, exc: type, words: str) -> None:
    with pytest.raises(exc, match=words):
        converter_figures(y, 1.0, 0.1234, **kwargs)


def test_a_tone_above_full_scale_is_noted() -> None:
    y = 1.5 * np.sin(2 * np.pi * 0.1234 * np.arange(512.0))
    fig = converter_figures(y, 1.0, 0.1234, full_scale=2.0)
    assert any("exceeds the full scale" in n for n in fig.notes)
    assert fig.amplitude_dbfs > 0
