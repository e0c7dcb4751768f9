"""Issue 25, item 9: select_order(method="ls", family) returned no choice (every row an
error) where its docstring says it raises: fit refuses ls with a family for every
candidate, so selection refuses it before any fit."""

import numpy as np
import pytest

import jitterid as ji


def test_ls_with_a_jitter_family_is_refused_up_front(monkeypatch):
    G = ji.TransferFunction([2.0], [1.0, 2.0])
    u = ji.telegraph_input(30.0, rng=1)
    data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=200, noise_std=0.01, rng=2)
    calls = []
    monkeypatch.setattr(ji.analysis.selection, "fit", lambda *a, **k: calls.append(a))
    with pytest.raises(ValueError, match="method 'ls' ignores the jitter"):
        ji.select_order(
            data, [ji.RationalModel(0, 1), ji.RationalModel(0, 2)], ji.UniformFamily(), "ls"
        )
    assert calls == []  # nothing was fitted
    with pytest.raises(ValueError, match="ignores the jitter"):
        ji.fit(data, ji.RationalModel(0, 1), ji.UniformFamily(), method="ls")
    assert np.isfinite(data.y).all()
