"""Issue 25, item 11: with a jitter family, BCLS (a criterion on the samples' mean) can leave
the jitter scale low on a correctly specified record; the LACK_OF_FIT check then said to try
other starts or structures, none of which applies. It now says what it found (the estimated
jitter is too small for the residuals) and points to 'gaussian' or 'ml'. Its false-alarm rate
on correctly specified fits is measured over several settings (slow test)."""

import numpy as np
import pytest

import jitterid as ji

G = ji.PolePairGain().system([6.25, -1.5, 2.0])
SETTINGS = {  # name: (true law, family, N, noise std)
    "uniform-200": (ji.Uniform(0.5), ji.UniformFamily(), 200, 0.01),
    "triangular-200": (ji.SumOfUniforms(1, 0.5), ji.SumOfUniformsFamily(), 200, 0.01),
    "gaussian-200": (ji.Gaussian(0.15), ji.GaussianFamily(), 200, 0.01),
    "uniform-1000": (ji.Uniform(0.5), ji.UniformFamily(), 1000, 0.01),
    "uniform-200-noisy": (ji.Uniform(0.5), ji.UniformFamily(), 200, 0.05),
}


def record(setting: str, r: int) -> ji.SampledData:
    law, _, N, noise = SETTINGS[setting]
    rng = np.random.default_rng(
        np.random.SeedSequence(2025, spawn_key=(list(SETTINGS).index(setting), r))
    )
    u = ji.telegraph_input(N + 5.0, rng)
    return ji.simulate(G, u, law, T=1.0, N=N, noise_std=noise, rng=rng)


def test_the_check_says_the_jitter_scale_is_too_small_and_what_to_use():
    data = record("uniform-200", 36)  # one of the flagged records (found by scanning r)
    res = ji.fit(data, ji.PolePairGain(), ji.UniformFamily(), method="bcls")
    assert res.status is ji.FitStatus.LACK_OF_FIT, res.message
    assert "the jitter law estimated (std" in res.message
    assert "is too small for the residuals" in res.message
    assert "'gaussian' or 'ml'" in res.message
    assert "other starts" not in res.message
    fixed = ji.fit(data, ji.PolePairGain(), ji.UniformFamily(), method="gaussian")
    assert fixed.status is not ji.FitStatus.LACK_OF_FIT, fixed.message
    assert fixed.jitter_std > res.jitter_std


@pytest.mark.slow
def test_false_alarm_rate_on_correctly_specified_bcls_fits():
    """32 records per setting, 160 fits: measured 2 LACK_OF_FIT (1.25 %, 95 % CI 0.2-4.4 %;
    both gaussian-200); with another 160 seeds 6 (3.8 %): 8 / 320 = 2.5 % (1.1-4.9 %), none at
    N = 1000 or noise 0.05. The bound below is 10 %."""
    flagged = {}
    for setting, (_, fam, _, _) in SETTINGS.items():
        flagged[setting] = sum(
            ji.fit(record(setting, r), ji.PolePairGain(), fam, method="bcls").status
            is ji.FitStatus.LACK_OF_FIT
            for r in range(32)
        )
    total = sum(flagged.values())
    print("LACK_OF_FIT per 32 correctly specified fits:", flagged, f"total {total} / 160")
    assert total <= 16, flagged  # 10 %
    assert max(flagged.values()) <= 6, flagged
