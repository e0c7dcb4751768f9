"""The structured likelihood's search where ln L is rough on the Newton step's scale
(jitterid.metrology.sinelik_fit: ROUGH_GAIN, ROUGH_STEPS): a quantised record's bins
against a noise std on its floor make the quadratic model's predicted gain say nothing of
the gain left, and the search must end where its steps stall, saying so."""

from __future__ import annotations

import numpy as np

import jitterid as ji
from jitterid.metrology import sinelik_fit
from jitterid.metrology.sinelik_loglik import SineLikelihood


class _Misleading(SineLikelihood):
    """A likelihood whose score in the offset carries a constant bias of 3 of its standard
    errors: the Newton step follows it and fails, the damped steps gain little (what a
    rough ln L does to the search: its slope on the step's scale is not the slope that a
    step can climb)."""

    def scores_information(self, x, stride=1):  # type: ignore[no-untyped-def]
        ll, g, opg, info = super().scores_information(x, stride)
        g = g.copy()
        c = self.nj + 3
        g[c] += 3.0 * np.sqrt(info[c, c])
        return ll, g, opg, info


def _search(monkeypatch, rough_steps: int):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(3)
    N, T, f = 400, 1.0, 0.123
    t = np.arange(N) * T + 0.3 * rng.standard_normal(N) / (2 * np.pi * f)
    y = np.sin(2 * np.pi * f * t + 0.4) + 0.02 + 0.05 * rng.standard_normal(N)
    start = [0.36 / (2 * np.pi * f), 1.0, 0.4, f, 0.02, 0.05]
    monkeypatch.setattr(sinelik_fit, "SineLikelihood", _Misleading)
    monkeypatch.setattr(sinelik_fit, "ROUGH_STEPS", rough_steps)
    return sinelik_fit._search(y, T, ji.SineWave(), ji.GaussianFamily(), start, 1e-6, 100, None)[0]


def test_a_search_whose_newton_steps_keep_failing_ends_where_they_stall(monkeypatch):
    """With the rule, the search ends after ROUGH_STEPS rough steps, CONVERGED, its message
    naming the roughness (18 passes); without it (ROUGH_STEPS out of reach) it crawls on
    until 3 steps gain below 1e-4 each (33 passes), to the same jitter within 0.1 of its
    stated error. Can fail: a rule that never fires, or fires before the estimate settles."""
    fast = _search(monkeypatch, sinelik_fit.ROUGH_STEPS)
    slow = _search(monkeypatch, 10**9)
    assert fast.status is ji.FitStatus.CONVERGED
    assert "rough" in fast.message
    assert "rough" not in slow.message
    assert fast.nfev < slow.nfev - 5
    se = fast.stderr["sigma"]
    assert abs(fast.x[0] - slow.x[0]) < 0.1 * se
