"""The Monte Carlo report (jitterid.experiments.report): summary statistics of converged fits,
and the flags on differences from the paper beyond Monte Carlo error."""

import dataclasses
import re

import numpy as np
import pytest
from helpers import tiny_experiment

from jitterid.experiments.report import (
    markdown_report,
    summarize,
)
from jitterid.experiments.store import Estimate


# ------------------------------------------------------------------ report
def _fake(exp, values_by_method, case="u"):
    return [
        Estimate(case, r, m, {"k0": v}, {}, 0.2, 0.0, 1.0, True, "CONVERGED", "", 1, 0.1)
        for m, vals in values_by_method.items()
        for r, v in enumerate(vals)
    ]


def test_summary_statistics_are_mean_std_and_sem_of_converged_fits():
    exp = tiny_experiment()
    rng = np.random.default_rng(0)
    vals = rng.normal(6.0, 0.3, 40)
    est = _fake(exp, {"ls": vals, "bcls": vals + 1})
    est.append(dataclasses.replace(est[0], realization=99, success=False, params={"k0": 1e9}))
    s = summarize(exp, est)["u", "ls"]
    assert (s.total, s.converged) == (41, 40)
    assert s.stats["k0"].mean == pytest.approx(vals.mean())
    assert s.stats["k0"].std == pytest.approx(vals.std(ddof=1))
    assert s.stats["k0"].sem == pytest.approx(vals.std(ddof=1) / np.sqrt(40))


def test_report_flags_a_difference_from_the_paper_beyond_monte_carlo_error():
    exp = dataclasses.replace(
        tiny_experiment(),
        paper_table=2,
        paper_labels=(("ls", "LS"), ("bcls", "BCLS")),
        cases=(dataclasses.replace(tiny_experiment().cases[0], paper_case=1),),
    )
    rng = np.random.default_rng(1)
    noise = rng.normal(0, 1, 128)
    noise = (noise - noise.mean()) / noise.std(ddof=1)
    # LS: exactly the paper's mean and std of k0; BCLS: mean 1 (paper 6.2536) -> flagged
    est = _fake(exp, {"ls": 5.8468 + 0.1723 * noise, "bcls": 1.0 + 0.0479 * noise})
    text = markdown_report(exp, est, "jitterid test")
    ls_line = next(ln for ln in text.splitlines() if ln.startswith("| LS (`ls`) | mean ± SEM"))
    bcls_line = next(ln for ln in text.splitlines() if ln.startswith("| BCLS (`bcls`) | mean ±"))
    assert "5.8468 ± 0.0152" in ls_line
    assert "⚑" not in ls_line.split("|")[3]
    assert "⚑" in bcls_line.split("|")[3]
    flagged = text.split("Beyond Monte Carlo error")[1]
    assert "BCLS mean of k0: z = " in flagged
    assert "BCLS std" not in flagged
    assert not re.search(r"(?<!BC)LS (mean|std)", flagged)
    assert "| LS (`ls`) | mean, paper | 5.8468 |" in text


def test_report_header_counts_how_every_estimators_fits_ended():
    # issue 24: a reader sees over how many fits each row is before reading it
    exp = dataclasses.replace(tiny_experiment(), runs=10)
    est = _fake(exp, {"ls": np.ones(5), "bcls": np.ones(4)})
    est.append(
        dataclasses.replace(est[-1], realization=7, success=False, status="OPTIMISER_FAILED")
    )
    text = markdown_report(exp, est, "jitterid test")
    line = next(ln for ln in text.splitlines() if ln.startswith("- How the fits ended"))
    assert "CONVERGED 5 (of 5)" in line
    assert "CONVERGED 4, OPTIMISER_FAILED 1 (of 5)" in line
