"""The meter's likelihood starts for the laws after the first (jitterid.metrology.meter):
under a law the moment route inverts (the uniform), the start is the moment route's, not
the Gaussian criterion's budgeted search; under the others that search runs without a
restart or a covariance. The referee: the same record measured with the Gaussian
criterion's start, the likelihood's maximum the same."""

from __future__ import annotations

import math

import numpy as np
import pytest

import jitterid as ji
from jitterid.metrology import meter

T = 1e-3
F = 123.0


def _uniform_record(seed: int, N: int = 2048) -> np.ndarray:
    """A 123 Hz tone at 1 kHz, uniform jitter at 0.3 rad, noise 1e-2."""
    rng = np.random.default_rng(seed)
    sj = 0.3 / (2 * math.pi * F)
    tau = sj * math.sqrt(3) * rng.uniform(-1, 1, N)
    y = np.sin(2 * math.pi * F * (np.arange(N) * T + tau) + 0.4)
    return y + 1e-2 * rng.standard_normal(N)


class _Starts:
    """The Gaussian criterion's searches the meter runs, by family, with their options."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.calls: list[tuple[str, dict]] = []
        inner = meter.fit

        def recorded(data, model, family, *args, **kw):  # type: ignore[no-untyped-def]
            self.calls.append((type(family).__name__, kw))
            return inner(data, model, family, *args, **kw)

        monkeypatch.setattr(meter, "fit", recorded)


def test_a_later_law_the_moments_invert_starts_from_them(monkeypatch):
    """A uniform record, the default laws: the uniform (not ranked out) starts from the
    moment route, no Gaussian-criterion search under it; the law and the estimate are those
    of the measurement whose uniform starts from that search (within 0.05 stated errors),
    where that search ran without a restart and without a covariance."""
    y = _uniform_record(1)
    starts = _Starts(monkeypatch)
    m = ji.measure_jitter(y, T)
    assert m.family == "uniform"
    assert "UniformFamily" not in [name for name, _ in starts.calls]
    starts.calls.clear()
    monkeypatch.setattr(meter, "ROUTE_LAWS", ("gaussian", "free"))
    ref = ji.measure_jitter(y, T)
    uniform = [kw for name, kw in starts.calls if name == "UniformFamily"]
    assert uniform, starts.calls
    assert all(kw["restart"] is False and kw["cov_type"] == "none" for kw in uniform)
    assert ref.family == "uniform"
    assert abs(ref.jitter_std - m.jitter_std) <= 0.05 * m.jitter_std_stderr
