"""Issue 25, item 10: `SampledData` printed every sample (19,368 characters at N = 1000); the
data and its inputs print in one short line whatever N."""

import numpy as np

import jitterid as ji


def test_a_record_prints_short_whatever_its_length():
    for n in (1000, 100_000):
        rng = np.random.default_rng(1)
        u = ji.telegraph_input(n + 2.0, rng)
        d = ji.simulate(
            ji.TransferFunction([1.0], [1.0, 1.0]), u, ji.Uniform(0.2), 1.0, n, 0.01, rng
        )
        text = repr(d)
        assert len(text) < 400, text
        assert f"y=array({n} values in [" in text
        assert "u=PiecewiseConstant(times=array(" in text
    m = ji.Multisine(np.arange(1, 200) * 0.01, np.ones(199), end=100.0)
    assert len(repr(m)) < 300
    small = ji.SampledData(np.array([1.0, 2.0, 3.0, 4.0]), 0.5)
    assert repr(small) == "SampledData(y=[1.0, 2.0, 3.0, 4.0], T=0.5)"
