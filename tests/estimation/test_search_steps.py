"""The search loop's economy: no evaluation repeated at the point just rejected, and the scan
over a family's kinks in logarithmically many evaluations, ending where a kink-by-kink
descent ends (the referee: the minimum of a criterion known in closed form)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

import jitterid as ji
from jitterid.estimation.search import _scan, newton_search


def test_a_rejected_step_inside_the_box_is_not_evaluated_again():
    # V = x^4 / 4 with M a quarter of its curvature: the first Newton step overshoots
    points: list[float] = []

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        points.append(float(x[0]))
        return float(x[0] ** 4 / 4), x**3, np.array([[0.75 * max(x[0] ** 2, 1e-3)]])

    _, ok, msg, n = newton_search(
        evaluate, np.array([1.0]), np.array([-10.0]), np.array([10.0]), 200
    )
    assert ok, msg
    assert n == len(points)
    repeats = [a for a, b in itertools.pairwise(points) if a == b]
    assert not repeats, points


@dataclass
class _Profile:
    """A problem whose criterion is f(n) alone, n the first parameter of the family (26)."""

    f: Any
    jitter: ji.SumOfUniformsFamily = field(default_factory=ji.SumOfUniformsFamily)
    evaluations: int = 0

    def objective(self, x: np.ndarray) -> float:
        self.evaluations += 1
        return float(self.f(x[0]))


CUTS = np.arange(0.0, 21.0)


@pytest.mark.parametrize("m", [3, 8, 10, 13, 17, 19, 20])
def test_the_scan_descends_over_the_kinks_to_the_lowest_in_log_many_evaluations(m):
    # V falls over the kinks to the integer m and rises beyond; the start n = 1.5 (a piece
    # away); a kink-by-kink descent ends at m after |m - 1| + 1 evaluations
    problem = _Profile(lambda n: (n - m) ** 2)
    x = np.array([1.5, 0.3, 6.0])
    x_end, v, n_evals = _scan(problem, x, problem.objective(x), 0, CUTS)
    assert x_end[0] == m
    assert v == 0.0
    assert n_evals == problem.evaluations - 1
    # the kinks either side, the doubling and halving strides, the fractions of <= 2 pieces
    assert n_evals <= 2 + 2 * int(np.ceil(np.log2(21))) + 10
    # (the jitter std kept, the other parameters as they are)
    assert x_end[2] == 6.0
    law0, law1 = problem.jitter.law(x[:2].tolist()), problem.jitter.law(x_end[:2].tolist())
    assert law1.std == pytest.approx(law0.std, rel=1e-12)


@pytest.mark.parametrize(("g_n", "converged"), [(-1e-9, True), (-1.0, False)])
def test_exhausted_damping_where_no_step_can_gain_above_the_floor_is_converged(g_n, converged):
    # a jitter scale collapsed onto its floor (a = 1e-12, its gradient pointing out: held)
    # leaves the shape n without information (M_nn ~ 1e-17) and its gradient noise: every
    # step in n is rejected. With |g_n| times the room to n's bound below the rounding floor
    # no step could gain more than rounding: converged; with a real gradient it is a failure.
    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        v = 0.2 * x[1] + 1e-8 * (x[0] - 8.0)  # V rises in n, whatever g says
        return v, np.array([g_n, 0.2]), np.diag([1e-17, 1e-2])

    lo, hi = np.array([8.0, 1e-12]), np.array([9.0, 0.125])
    x, ok, msg, _ = newton_search(evaluate, np.array([8.0, 1e-12]), lo, hi, 200, floor=1e-4)
    assert ok is converged, msg
    assert ("rounding floor inside the bounds" in msg) is converged
    assert x[1] == 1e-12


def test_a_jitter_scale_on_its_floor_is_said_in_the_message():
    # no jitter in the data, a known third-order system: the Gaussian criterion's minimum in
    # the family (26) is zero jitter (n then means nothing), reported as such
    g = ji.TransferFunction([1.2], [1.0, 2.2, 2.4, 1.2])
    rng = np.random.default_rng(1002)
    u = ji.telegraph_input(300 * 0.25 + 2.0, rng)
    d = ji.simulate(g, u, ji.NoJitter(), 0.25, 300, 0.01, rng)
    res = ji.fit(d, g, ji.SumOfUniformsFamily(a_max=0.125), "gaussian")
    assert res.status is ji.FitStatus.CONVERGED, res.message
    assert res.jitter_std < 1e-6
    assert "the jitter scale is on its floor" in res.message
    assert "n mean nothing there" in res.message


def test_a_scan_does_not_look_inside_a_piece_it_looked_inside_before():
    # a mode inside (1, 2) (the fractions find it); a second scan from there, as the walk
    # makes after searching the piece, evaluates the kinks either side and no fraction of
    # (1, 2) again, but does those of a piece not yet seen
    problem = _Profile(lambda n: (n - 1.6) ** 2 + 0.5 * abs(n - round(n)))
    x = np.array([2.0, 0.3, 6.0])
    scanned: set[tuple[float, float]] = set()
    x1, v1, _n1 = _scan(problem, x, problem.objective(x), 0, CUTS, scanned)
    assert 1.0 < x1[0] < 2.0
    assert v1 < problem.f(2.0)
    assert scanned == {(1.0, 2.0), (2.0, 3.0)}  # (on the kink 2: the pieces either side)
    _, _, n2 = _scan(problem, x1, v1, 0, CUTS, scanned)
    assert n2 == 2  # the kinks 1 and 2 alone
    # without the memory the same scan looks inside (1, 2) again
    _, _, n3 = _scan(problem, x1, v1, 0, CUTS)
    assert n3 == 2 + 5
    # a descent that ends at a kink next to pieces not seen looks inside them
    other = _Profile(lambda n: (n - 5) ** 2)
    _, _, n4 = _scan(other, x1, other.objective(x1), 0, CUTS, scanned)
    assert scanned == {(1.0, 2.0), (2.0, 3.0), (4.0, 5.0), (5.0, 6.0)}
    assert n4 == other.evaluations - 1 > 10


@dataclass
class _Std:
    """A problem whose criterion is (std - target)^2 of the family (26)'s law (a <= T/2)."""

    target: float
    jitter: ji.SumOfUniformsFamily = field(
        default_factory=lambda: ji.SumOfUniformsFamily(a_max=0.5)
    )
    evaluations: int = 0

    def objective(self, x: np.ndarray) -> float:
        self.evaluations += 1
        return float((self.jitter.law(x[:2].tolist()).std - self.target) ** 2)


def test_a_scan_from_a_scale_on_its_bound_descends_along_the_bound():
    # at n = 8 with a on its bound T/2 the data want a larger std (that of n = 5.25, a =
    # T/2): at the same std no kink is lower (the criterion is the same), along the bound
    # n = 7, 6, 5 are; the scan ends at 5.25 (a scanned fraction of (5, 6)) with a held
    fam = ji.SumOfUniformsFamily(a_max=0.5)
    problem = _Std(fam.law([5.25, 0.5]).std)
    x = np.array([8.0, 0.5, 6.0])
    x_end, v, n = _scan(problem, x, problem.objective(x), 0, CUTS)
    assert x_end.tolist() == [5.25, 0.5, 6.0]
    assert v == 0.0
    assert n == problem.evaluations - 1 <= 2 + 2 + 2 * int(np.ceil(np.log2(21))) + 10
    # a scale inside its bounds: the same-std line alone (the std kept, whatever the
    # rounding of the equal criteria picks)
    inside = np.array([8.0, 0.4, 6.0])
    x_in, _, _ = _scan(problem, inside, problem.objective(inside), 0, CUTS)
    assert fam.law(x_in[:2].tolist()).std == pytest.approx(fam.law([8.0, 0.4]).std, rel=1e-12)
