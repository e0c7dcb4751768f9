"""Memory estimates (jitterid.estimation.resources): a fit estimates its memory before it starts
and refuses, with the figure and the fix, anything above the budget
(``JITTERID_MEMORY_BUDGET``), instead of running for minutes and then dying of a MemoryError (ML
at N = 1e5 of the lab setting needed > 8 GB; BCLS at N = 1e7 took 485 s at 8 GB).

The budget is set small here so that the refusals trigger at small N; nothing is timed."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import jitterid as ji
from jitterid._checks import TooLargeError
from jitterid.cli import main
from jitterid.estimation import likelihood as likelihood_module
from jitterid.estimation import resources
from jitterid.io import save_data

G = ji.TransferFunction([6.25], [1.0, 3.0, 6.25])


def _paper(n: int, seed: int = 1) -> ji.SampledData:
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n + 5.0, rng)
    return ji.simulate(G, u, ji.Uniform(0.5), 1.0, n, 0.01, rng)


def _lab(n: int, seed: int = 1) -> ji.SampledData:
    g = ji.TransferFunction([4.0, 8.0], np.polymul([1.0, 4.0], [1.0, 2.0, 2.0]))
    rng = np.random.default_rng(seed)
    u = ji.zoh_input(rng.choice([-1.0, 1.0], n + 20), 0.5)
    return ji.simulate(g, u, ji.Gaussian(0.08), 0.5, n, 0.02, rng)


class _Counted(ji.PolePairGain):
    """The pole-pair structure, counting the systems it builds: every evaluation of a fit's
    criterion builds one, so a fit refused before any work has built none."""

    built = 0

    def system(self, params):
        type(self).built += 1
        return super().system(params)


def test_a_moment_fit_over_the_budget_is_refused_before_any_work(monkeypatch):
    d = _paper(2000)
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "1e6")  # 1 MB; the estimate is 2 MB
    monkeypatch.setattr(_Counted, "built", 0)
    with pytest.raises(TooLargeError) as err:
        ji.fit(d, _Counted(), ji.Uniform(0.5), "bcls")
    assert _Counted.built == 0  # refused before any evaluation
    msg = str(err.value)
    assert "N = 2000 samples with 3 parameters" in msg
    assert "GB of memory" in msg
    assert "JITTERID_MEMORY_BUDGET" in msg
    assert "fewer samples" in msg
    assert isinstance(err.value, ValueError)  # every argument error of fit is a ValueError


def test_the_moment_estimate_scales_with_n_and_the_parameters():
    assert resources.moment_bytes(10**7, 3) == pytest.approx(1e10)  # measured 8.6 GB at 1e6 x 10
    assert resources.moment_bytes(2 * 10**5, 5) == pytest.approx(
        2 * resources.moment_bytes(10**5, 5)
    )


def test_ml_whose_rule_cannot_fit_is_refused_before_the_first_stage(monkeypatch):
    d = _paper(2000)
    # bcls fits the budget (2 MB); the likelihood's rule needs at least 112e3 nodes (22 MB)
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "5e6")
    assert ji.fit(d, _Counted(), ji.Uniform(0.5), "bcls").success
    assert _Counted.built > 0  # the referee: a fit that runs builds systems
    monkeypatch.setattr(_Counted, "built", 0)
    with pytest.raises(TooLargeError, match="quadrature nodes for the exact likelihood") as err:
        ji.fit(d, _Counted(), ji.Uniform(0.5), "ml")
    assert _Counted.built == 0  # refused before the BCLS stage
    assert "method 'gaussian' or 'asml-diag'" in str(err.value)


def test_ml_is_refused_when_its_designed_rule_is_over_the_budget(monkeypatch):
    # the lab setting: the lower bound up front (3 nodes per sample, 2 MB) passes, the
    # designed (windowed) rule (1.6e5 nodes, one chunk of them streamed at 600 bytes each:
    # ~100 MB) does not. (Every design is checked: a rule designed at a larger noise level
    # may pass and be built first.)
    d = _lab(1000)
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "5.5e7")
    with pytest.raises(TooLargeError, match=r"exact likelihood of N = 1000 samples") as err:
        ji.fit(d, ji.RationalModel(1, 3), ji.Gaussian(0.08), "ml")
    assert "per sample" in str(err.value)
    # the same guard holds for the Cramer-Rao bound, which builds the same rule
    with pytest.raises(TooLargeError, match="exact likelihood"):
        ji.crb(
            ji.RationalModel(1, 3),
            ji.Gaussian(0.08),
            d.u,
            0.5,
            1000,
            0.02,
            [4.0, 8.0, 6.0, 10.0, 8.0],
        )


def test_the_node_estimate_matches_the_rule_that_is_built():
    d = _lab(1000)
    lik = likelihood_module.ExactLikelihood(
        ji.RationalModel(1, 3), ji.Gaussian(0.08), d.u, 0.5, 1000, 0.02
    )
    x = np.array([4.0, 8.0, 6.0, 10.0, 8.0])
    lik.design(x)
    law, resp, _ = lik.split(x)  # the signal: the system's response to d.u
    built = sum(nd.t.size for nd in lik._nodes(x, law, resp))
    est = resources.likelihood_nodes(law, 0.5, 1000, np.r_[resp.breaks, lik._cuts], resp.rate, 8)
    assert 0.9 * built < est < 1.15 * built  # 3.62e5 estimated, 3.54e5 built
    lower = resources.likelihood_nodes(law, 0.5, 1000, d.u.times, 0.0)
    assert lower < built


def test_ordinary_fits_are_not_refused_with_the_default_budget(monkeypatch):
    monkeypatch.delenv("JITTERID_MEMORY_BUDGET", raising=False)
    d = _paper(200)
    for method in ("bcls", "ml"):
        assert ji.fit(d, ji.PolePairGain(), ji.Uniform(0.5), method).success


def test_the_cli_refuses_in_one_line(tmp_path, monkeypatch):
    d = _paper(2000)
    save_data(tmp_path / "d.csv", d)
    ji.save_input(tmp_path / "u.csv", d.u)
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "1e6")
    res = CliRunner().invoke(
        main,
        [
            "fit",
            str(tmp_path / "d.csv"),
            "--input",
            str(tmp_path / "u.csv"),
            "--model",
            "polepair",
            "--jitter",
            "known:uniform:a=0.5",
            "--out",
            str(tmp_path / "o"),
            "--no-plots",
            "--quiet",
        ],
    )
    assert res.exit_code not in (0, None)
    assert isinstance(res.exception, SystemExit)
    assert "Traceback" not in res.output
    assert "JITTERID_MEMORY_BUDGET" in res.output
    assert "internal error" not in res.output


def test_a_rule_over_its_share_of_the_budget_is_streamed_not_refused(monkeypatch):
    """Lab setting, N = 4000: 6.3e5 nodes, more than a quarter of a 200 MB budget holds
    (2.5e5 at 200 bytes): the rule is made again chunk by chunk at each evaluation (one
    chunk: ~100 MB), with the values of the rule kept in memory."""
    d = _lab(4000)
    x = np.array([4.0, 8.0, 6.0, 10.0, 8.0])
    args = (ji.RationalModel(1, 3), ji.Gaussian(0.08), d.u, 0.5, 4000, 0.02)
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "1e10")
    kept = likelihood_module.ExactLikelihood(*args)
    ref = kept.logpdf(x, d.y)
    assert not any(r.streamed for r in kept._cache.values())
    monkeypatch.setenv("JITTERID_MEMORY_BUDGET", "2e8")
    lik = likelihood_module.ExactLikelihood(*args)
    np.testing.assert_allclose(lik.logpdf(x, d.y), ref, rtol=0, atol=1e-12)
    assert all(r.streamed for r in lik._cache.values())
