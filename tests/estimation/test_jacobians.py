"""The O(N) moment path, its chunking, and the analytic derivatives of every criterion
(jitterid.estimation.jacobians).

Each analytic quantity is checked against central differences of the function it
differentiates (the referee), on small problems: known-jitter OE and a JOE family, with the
noise std known and estimated.
"""

import numpy as np
import pytest
from helpers import TABLE2_N, TABLE2_NOISE, TABLE2_T, TABLE2_TRUTH, table2_data

import jitterid as ji
from jitterid.estimation import jacobians as _jacobians
from jitterid.estimation.likelihood import _modal_gradient, _pole_sensitivity
from jitterid.estimation.problem import Problem, adjoint_dtft
from jitterid.moments import modal as _modal
from jitterid.moments.quadrature import jitter_nodes
from jitterid.moments.sample import sample_moments

T, N, NOISE = 1.0, 60, 0.01
TRUTH = np.array([6.25, -1.5, 2.0])


def _data(law, seed=5, n=N, structure=None, theta=TRUTH):
    rng = np.random.default_rng(seed)
    structure = structure or ji.PolePairGain()
    u = ji.telegraph_input(n * T + 2, rng)
    return ji.simulate(structure.system(theta), u, law, T, n, NOISE, rng)


def _central(fun, x, rel=1e-6):
    """Central differences of ``fun`` (any shape) in every coordinate of ``x``."""
    cols = []
    for i in range(x.size):
        h = rel * max(abs(x[i]), 1e-2)
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        cols.append((np.asarray(fun(up)) - np.asarray(fun(down))) / (2 * h))
    return np.array(cols)


# ---------------------------------------------------------------------------- moment path
LAWS = [ji.Uniform(0.5), ji.Gaussian(0.15), ji.SumOfUniforms(1.5, 0.5), ji.SumOfUniforms(2.0, 0.3)]
SYSTEMS = [
    ji.TransferFunction([6.25], [1.0, 3.0, 6.25]),
    ji.TransferFunction([0.5, 1.0, 2.0, 3.0], [1.0, 4.0, 6.0, 4.5]),  # feedthrough: jumps
    ji.TransferFunction([2.0], [1.0, 2.0]),
]


@pytest.mark.parametrize("law", LAWS, ids=repr)
@pytest.mark.parametrize("system", SYSTEMS, ids=["pair", "feedthrough", "real"])
def test_segment_path_matches_evaluating_the_signal_at_every_node(law, system):
    rng = np.random.default_rng(11)
    resp = system.response(ji.telegraph_input(N * T + 2, rng))
    fast = sample_moments(resp, law, T, N)
    mean, var = np.empty(N), np.empty(N)
    for ch in jitter_nodes(law, T, N, resp.breaks, resp.rate):
        s = resp(ch.t)
        mean[ch.k0 : ch.k1] = ch.expect(s)
        var[ch.k0 : ch.k1] = ch.expect((s - mean[ch.k0 : ch.k1][ch.owner]) ** 2)
    np.testing.assert_allclose(fast.mean, mean, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast.var, var, rtol=0, atol=1e-13)


@pytest.mark.parametrize("law", LAWS, ids=repr)
def test_chunked_and_unchunked_evaluations_agree(law):
    n = 400
    u = ji.telegraph_input(n * T + 2, np.random.default_rng(12))
    structure, theta = ji.RationalModel(1, 3), np.array([0.5, 2.0, 4.0, 6.0, 4.5])
    tf = structure.system(theta)
    tab = _modal.tables(tf, u)
    dtab = _modal.derivative_tables(tf, u, _modal.modal_sensitivity(structure, theta, tf))
    rate = tf.response(u).rate
    whole = _modal.modal_moments(_modal.SegmentPlan(law, T, n, u, rate, chunk=n), tab, dtab)
    parts = _modal.modal_moments(_modal.SegmentPlan(law, T, n, u, rate, chunk=37), tab, dtab)
    for a, b in zip(whole, parts, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * max(1.0, float(np.max(np.abs(a)))))


def test_no_jitter_is_the_signal_at_the_nominal_instants():
    data = _data(ji.Uniform(0.5))
    tf = ji.PolePairGain().system(TRUTH)
    plan = _modal.SegmentPlan(ji.NoJitter(), T, N, data.u, 2.5)
    mean, var, _, _ = _modal.modal_moments(plan, _modal.tables(tf, data.u))
    np.testing.assert_allclose(mean, tf.response(data.u)(data.t_nominal), rtol=0, atol=1e-14)
    np.testing.assert_allclose(var, 0.0, atol=1e-28)


def test_kept_plans_are_bounded_and_shared():
    _modal.clear_plans()
    data = _data(ji.Uniform(0.5))
    f = ji.default_frequencies(N, T)
    bcls = Problem(data, ji.PolePairGain(), ji.Uniform(0.5), "bcls", f, None)
    gauss = Problem(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", f, NOISE)
    bcls.moments(TRUTH)
    gauss.moments(TRUTH * 1.01)
    assert len(_modal._plans) == 1  # one node geometry for both criteria
    fam = Problem(data, ji.PolePairGain(), ji.SumOfUniformsFamily(), "bcls", f, None)
    for n in np.linspace(0.5, 3.0, 9):
        fam.moments(np.r_[n, 0.4, TRUTH])
    assert len(_modal._plans) <= _modal._PLANS_KEPT
    _modal.clear_plans()


# ---------------------------------------------------------------------------- sensitivities
@pytest.mark.parametrize("system", SYSTEMS, ids=["pair", "feedthrough", "real"])
def test_switch_state_sensitivity_matches_differences_in_the_poles(system):
    u = ji.telegraph_input(200.0, 3)
    exact = system.switch_state_sensitivity(u)
    p = system.poles
    keep = p.imag >= 0
    np.testing.assert_allclose(
        exact[:, keep], _pole_sensitivity(system, u), rtol=0, atol=1e-7 * np.max(np.abs(exact))
    )
    # Shifting every pole by h moves each state column by dx/dp h (a column depends on its own
    # pole only): a fourth-order central difference in the shift.
    h = 1e-3

    def states(shift):
        moved = ji.TransferFunction([1.0], np.real(np.poly(p + shift)))
        cols = [int(np.argmin(np.abs(moved.poles - (q + shift)))) for q in p]
        return moved.switch_states(u)[:, cols]

    fd = (8 * (states(h) - states(-h)) - (states(2 * h) - states(-2 * h))) / (12 * h)
    np.testing.assert_allclose(fd, exact, rtol=0, atol=1e-8 * np.max(np.abs(exact)))


@pytest.mark.parametrize(
    ("structure", "theta"),
    [
        (ji.PolePairGain(), TRUTH),
        (ji.RationalModel(2, 3), np.array([0.5, 1.0, 3.0, 4.0, 6.0, 4.5])),
        (ji.RationalModel(1, 1), np.array([0.5, 2.0, 3.0])),
    ],
    ids=["polepair", "rational23", "biproper"],
)
def test_modal_sensitivity_matches_the_likelihoods_differences(structure, theta):
    tf = structure.system(theta)
    exact = _modal.modal_sensitivity(structure, theta, tf)
    reference = _modal_gradient(structure, theta, tf)
    assert reference is not None
    for a, b in zip(exact, reference, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * max(1.0, float(np.max(np.abs(b)))))


# ---------------------------------------------------------------------------- criteria
CASES = [
    ("oe", ji.Uniform(0.5), np.array([6.0, -1.4, 2.1])),
    ("joe", ji.SumOfUniformsFamily(), np.array([1.6, 0.31, 6.0, -1.4, 2.1])),
]


def _problem(case, method, noise):
    _name, jitter, x = case
    data = _data(ji.SumOfUniforms(2.0, 0.3))
    pb = Problem(data, ji.PolePairGain(), jitter, method, ji.default_frequencies(N, T), noise)
    return pb, (np.r_[x, 0.02] if pb.estimates_noise else x)


def _check_columns(analytic, reference, jitter_params, tol_system=1e-7, tol_jitter=1e-4):
    """Column-wise relative agreement. The jitter shape parameter n has a one-sided difference
    (step sqrt(eps), error ~1e-5) in the analytic path, so jitter columns agree less tightly;
    the scale a is exact (see the test of (M3) below)."""
    for i in range(analytic.shape[-1]):
        a, b = analytic[..., i], reference[..., i]
        tol = tol_jitter if i < jitter_params else tol_system
        assert np.max(np.abs(a - b)) <= tol * np.max(np.abs(b)), (i, np.max(np.abs(a - b)))


@pytest.mark.parametrize(
    ("case", "method"),
    [(CASES[0], "ls")] + [(c, m) for c in CASES for m in ("bcls", "wbcls")],
    ids=["oe-ls", "oe-bcls", "oe-wbcls", "joe-bcls", "joe-wbcls"],
)
def test_least_squares_jacobians_match_differences_of_the_residuals(case, method):
    pb, x = _problem(case, method, NOISE)
    J = pb.jacobian(x)
    _check_columns(J, _central(pb.residuals, x).T, pb.n_jitter)


@pytest.mark.parametrize("case", CASES, ids=["oe", "joe"])
def test_frozen_wbcls_jacobian_matches_differences(case):
    """With R frozen at weights_at (what fit uses), the residuals' Jacobian has no dR term."""
    _name, jitter, x = case
    data = _data(ji.SumOfUniforms(2.0, 0.3))
    pb = Problem(
        data, ji.PolePairGain(), jitter, "wbcls", ji.default_frequencies(N, T), NOISE, x * 1.02
    )
    _check_columns(pb.jacobian(x), _central(pb.residuals, x).T, pb.n_jitter)


def test_jacobian_of_a_model_with_feedthrough():
    """A biproper model: D and its derivative enter c_j = u_j G(0) and s jumps at switches."""
    structure, theta = ji.RationalModel(2, 2), np.array([0.5, 2.0, 6.25, 3.0, 6.25])
    data = _data(ji.Uniform(0.5), structure=structure, theta=theta)
    pb = Problem(data, structure, ji.Uniform(0.5), "bcls", ji.default_frequencies(N, T), None)
    x = theta * 1.05
    _check_columns(pb.jacobian(x), _central(pb.residuals, x).T, 0)


@pytest.mark.parametrize("case", CASES, ids=["oe", "joe"])
@pytest.mark.parametrize("method", ["gaussian", "asml-diag", "asml"])
@pytest.mark.parametrize("noise", [NOISE, None], ids=["known-noise", "estimated-noise"])
def test_gradients_match_differences_of_the_criterion(case, method, noise):
    pb, x = _problem(case, method, noise)
    value, grad, info = pb.objective_gradient(x)
    assert value == pytest.approx(pb.objective(x), rel=1e-12)
    _check_columns(grad[None, :], _central(pb.objective, x)[None, :], pb.n_jitter)
    assert np.allclose(info, info.T)
    assert np.all(np.linalg.eigvalsh(info) > -1e-9 * np.max(info))


@pytest.mark.parametrize(
    ("family", "xj"),
    [
        (ji.UniformFamily(), [0.4]),
        (ji.GaussianFamily(), [0.12]),
        (ji.SumOfUniformsFamily(), [1.6, 0.35]),
    ],
    ids=["uniform", "gaussian", "sum-of-uniforms"],
)
@pytest.mark.parametrize(
    ("structure", "theta"),
    [(ji.PolePairGain(), TRUTH), (ji.RationalModel(2, 2), np.array([0.5, 2.0, 6.25, 3.0, 6.25]))],
    ids=["strictly-proper", "feedthrough"],
)
def test_scale_derivative_matches_differences_of_the_moments(family, xj, structure, theta):
    """(M3): E[s' tau] / a, plus the jumps of s at switches when the model has feedthrough."""
    data = _data(ji.Uniform(0.3), n=80, structure=structure, theta=theta)
    pb = Problem(data, structure, family, "gaussian", ji.default_frequencies(80, T), NOISE)
    x = np.r_[xj, theta]
    _, _, dm, dw = _jacobians.moment_derivatives(pb, x)
    i = len(xj) - 1  # the scale a
    h = 1e-5 * x[i]
    up, down = x.copy(), x.copy()
    up[i] += h
    down[i] -= h
    mu, md = _jacobians.moments(pb, up), _jacobians.moments(pb, down)
    for analytic, ref in (
        (dm[i], (mu.mean - md.mean) / (2 * h)),
        (dw[i], (mu.var - md.var) / (2 * h)),
    ):
        assert np.max(np.abs(analytic - ref)) <= 1e-7 * np.max(np.abs(ref))


def test_moment_derivatives_with_a_multisine_input_fall_back_to_differences():
    u = ji.Multisine([0.05, 0.13], [1.0, 0.5], end=80.0)
    data = ji.simulate(ji.PolePairGain().system(TRUTH), u, ji.Uniform(0.5), T, 60, NOISE, 3)
    pb = Problem(
        data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", ji.default_frequencies(60, T), NOISE
    )
    _, grad, _ = pb.objective_gradient(TRUTH)
    _check_columns(
        grad[None, :], _central(pb.objective, TRUTH, rel=1e-5)[None, :], 0, tol_system=1e-5
    )


def test_expected_hessian_of_the_gaussian_criterion_is_close_to_its_hessian_at_the_optimum():
    data = _data(ji.Uniform(0.5), n=400)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method="gaussian")
    pb = Problem(
        data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian", ji.default_frequencies(400, T), NOISE
    )
    _, grad, info = pb.objective_gradient(res.x)
    H = _central(lambda z: pb.objective_gradient(z)[1], res.x, rel=1e-5)
    assert np.max(np.abs(grad / np.sqrt(np.diag(info)))) < 1e-3  # stationary
    scale = np.sqrt(np.outer(np.diag(H), np.diag(H)))
    assert np.max(np.abs(info - H) / scale) < 0.2


@pytest.mark.parametrize("method", ["gaussian", "asml-diag"])
def test_newton_search_ends_where_a_tight_quasi_newton_search_ends(method):
    from scipy.optimize import minimize

    data = _data(ji.Uniform(0.5), seed=9, n=200)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), method=method, noise_std=NOISE)
    assert res.success
    pb = Problem(
        data, ji.PolePairGain(), ji.Uniform(0.5), method, ji.default_frequencies(200, T), NOISE
    )
    ref = minimize(
        lambda z: pb.objective_gradient(z)[:2],
        res.x * 1.01,
        jac=True,
        method="BFGS",
        options={"gtol": 1e-9},
    )
    assert res.cost <= ref.fun + 1e-7 * abs(ref.fun)
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-5)


def test_adjoint_dtft_on_the_dft_grid_is_the_direct_sum():
    rng = np.random.default_rng(2)
    n = 64
    f = ji.default_frequencies(n, T)
    z = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    direct = np.exp(2j * np.pi * np.outer(np.arange(n) * T, f)) @ z
    np.testing.assert_allclose(adjoint_dtft(z, T, f, n), direct, rtol=0, atol=1e-12)
    off = f + 0.1 / (n * T)  # off the grid: the chunked sum
    np.testing.assert_allclose(
        adjoint_dtft(z, T, off, n),
        np.exp(2j * np.pi * np.outer(np.arange(n) * T, off)) @ z,
        atol=1e-12,
    )


def test_derivative_cache_follows_the_parameter_vector():
    pb, x = _problem(CASES[0], "gaussian", None)
    first = _jacobians.moment_derivatives(pb, x)
    assert _jacobians.moment_derivatives(pb, x) is first
    other = _jacobians.moment_derivatives(pb, x * 1.001)
    assert other is not first
    assert not np.array_equal(other[2], first[2])


# ---------------------------------------------------------------------------- n of (26)
def _table2_family(method):
    data = table2_data(0, ji.SumOfUniforms(2, 1 / (2 * np.sqrt(3))))
    f = ji.default_frequencies(TABLE2_N, TABLE2_T)
    return Problem(data, ji.PolePairGain(), ji.SumOfUniformsFamily(), method, f, TABLE2_NOISE)


def _in_piece(pb, n):
    """Search n within its smooth piece, as the piece walk does (the differences' bounds)."""
    pb.restrict(((float(np.floor(n)), float(np.ceil(n))), *pb.bounds[1:]))


def _kink_row(method, n, piece, monkeypatch):
    """n's row (m, then Var where the criterion reads it) of the moment derivatives at
    Table 2's system with n in ``piece`` (no difference taken: asserted), a difference
    quotient of the moments in n at a signed step h, and _differenced's row."""
    pb = _table2_family(method)
    pb.restrict((piece, *pb.bounds[1:]))
    x = np.r_[n, 0.3, TABLE2_TRUTH * 1.01]
    calls, differenced = _counting_differences(monkeypatch)
    _, _, dm, dw = _jacobians.moment_derivatives(pb, x)
    assert 0 not in calls
    var = pb.needs_variances

    def stacked(v):
        mv = _jacobians.moments(pb, v)
        return np.r_[mv.mean, mv.var] if var else mv.mean

    base = stacked(x)

    def step(h):
        moved = x.copy()
        moved[0] += h
        return (stacked(moved) - base) / h

    ref_m, ref_v = differenced(pb, x, 0, variance=var, shape=True)
    got = np.r_[dm[0], dw[0]] if var else dm[0]
    return got, step, (np.r_[ref_m, ref_v] if var else ref_m)


def _counting_differences(monkeypatch):
    calls = []
    differenced = _jacobians._differenced

    def counted(problem, x, i, **kw):
        calls.append(i)
        return differenced(problem, x, i, **kw)

    monkeypatch.setattr(_jacobians, "_differenced", counted)
    return calls, differenced


@pytest.mark.parametrize("method", ["gaussian", "bcls"])
@pytest.mark.parametrize("n", [0.4, 1.6, 2.02, 2.5, 7.3])
def test_shape_derivative_of_the_family_26_is_closed_form_and_matches_differences(
    n, method, monkeypatch
):
    """dm, dVar in n from the family's closed-form dp/dn at the base law's nodes (Table 2's
    system, n in (0, 1), (1, 2), (2, 3) just above 2 (the window form) and mid-piece,
    (7, 8)), against _differenced (central differences of the moments, step 1e-5 max(n, 1):
    its own error is 1e-8-4e-7 of the largest value here, from the quadrature's rounding over
    the step) and, tighter, against Richardson-extrapolated central differences at steps
    2e-3 and 1e-3 (O(h^4) ~ 1e-11; rounding ~1e-13 / h), within 5e-8 (measured <= 3.5e-8)."""
    pb = _table2_family(method)
    _in_piece(pb, n)
    x = np.r_[n, 0.3, TABLE2_TRUTH * 1.01]
    calls, differenced = _counting_differences(monkeypatch)
    _, _, dm, dw = _jacobians.moment_derivatives(pb, x)
    assert 0 not in calls  # n's row from the closed form, not from differences
    var = pb.needs_variances
    ref_m, ref_v = differenced(pb, x, 0, variance=var, shape=True)

    def stacked(v):
        mv = _jacobians.moments(pb, v)
        return np.r_[mv.mean, mv.var] if var else mv.mean

    def central(h):
        up, down = x.copy(), x.copy()
        up[0] += h
        down[0] -= h
        return (stacked(up) - stacked(down)) / (2 * h)

    rich = (4 * central(1e-3) - central(2e-3)) / 3
    got = np.r_[dm[0], dw[0]] if var else dm[0]
    assert np.max(np.abs(got - rich)) <= 5e-8 * np.max(np.abs(rich))
    for a, b in ((dm[0], ref_m), (dw[0], ref_v)):
        if b is not None:
            assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(b))


@pytest.mark.parametrize("method", ["gaussian", "bcls"])
@pytest.mark.parametrize(("n", "piece"), [(0.0, (0.0, 1.0)), (2.0, (2.0, 3.0)), (5.0, (5.0, 6.0))])
def test_shape_derivative_of_the_family_26_from_above_a_kink_is_the_scales(
    n, piece, method, monkeypatch
):
    """n on an integer at the bottom of the piece searched (the bound 0, a kink): the row
    from above is -a / (2 (n + 1)) x the scale's (JitterFamily.scale_equivalent), with no
    difference taken. Referees: forward differences of the moments into the piece at steps
    8e-3, 4e-3, 2e-3, Richardson-extrapolated twice (measured 8e-9-5e-8 of the largest
    value: truncation at n = 0, the quadrature's rounding over the step at n = 5; the
    plain forward difference at 2e-3 is off by 3e-4-2e-3), within 1e-7, and _differenced
    (the route this replaces) within 1e-6. Can fail: with the factor's sign flipped or
    without its 1/2 the rows differ by 100 %."""
    got, step, ref = _kink_row(method, n, piece, monkeypatch)
    d1, d2, d3 = step(8e-3), step(4e-3), step(2e-3)
    r1, r2 = 2 * d2 - d1, 2 * d3 - d2
    rich = (4 * r2 - r1) / 3
    assert np.max(np.abs(got - rich)) <= 1e-7 * np.max(np.abs(rich))
    assert np.max(np.abs(got - ref)) <= 1e-6 * np.max(np.abs(ref))


@pytest.mark.parametrize("method", ["gaussian", "bcls"])
@pytest.mark.parametrize(("n", "piece"), [(1.0, (0.0, 1.0)), (2.0, (1.0, 2.0)), (5.0, (4.0, 5.0))])
def test_shape_derivative_of_the_family_26_from_below_a_kink_is_a_combination_of_laws(
    n, piece, method, monkeypatch
):
    """n on an integer at the top of the piece searched: the row from below is -(m - m_L)/2
    (JitterFamily.below_kink; L the sum of n - 1 of the n + 1 uniforms, at n = 1 the point
    mass), and dVar alike, with no difference taken. Referee: backward differences of the
    moments at steps 1e-4, 2.5e-5, 6.25e-6, Richardson-extrapolated twice in the square root
    of the step (the law's widths move like the square root of the distance below an
    integer; measured 4e-7-8e-6 of the largest value, the quadrature's rounding over the
    smallest step), within 3e-5; _differenced (the route this replaces, off by 1.4e-7 at
    n = 1 and 9e-5-1.3e-4 above, its sqrt(h) error) within 1e-3. Can fail: a coefficient off
    by its sign or its 1/2 is off by 100 %."""
    got, step, ref = _kink_row(method, n, piece, monkeypatch)
    d = [step(-1e-4 / 4**k) for k in range(3)]
    r1 = [2 * d[k + 1] - d[k] for k in range(2)]
    rich = (4 * r1[1] - r1[0]) / 3
    assert np.max(np.abs(got - rich)) <= 3e-5 * np.max(np.abs(rich))
    assert np.max(np.abs(got - ref)) <= 1e-3 * np.max(np.abs(ref))


@pytest.mark.parametrize(("n", "piece"), [(2.0, (1.0, 3.0)), (2 - 5e-10, (1.0, 2.0))])
def test_shape_derivative_of_the_family_26_is_differenced_where_there_is_no_closed_form(
    n, piece, monkeypatch
):
    """On an integer n inside the box searched (no side to take) and less than 1e-9 below
    one the family gives no dp/dn: n's row is the difference route's (central across the
    kink; one-sided into the piece searched)."""
    pb = _table2_family("gaussian")
    pb.restrict((piece, *pb.bounds[1:]))
    x = np.r_[n, 0.3, TABLE2_TRUTH * 1.01]
    calls, differenced = _counting_differences(monkeypatch)
    _, _, dm, dw = _jacobians.moment_derivatives(pb, x)
    assert calls == [0]
    ref_m, ref_v = differenced(pb, x, 0, variance=True, shape=True)
    np.testing.assert_array_equal(dm[0], ref_m)
    np.testing.assert_array_equal(dw[0], ref_v)


def test_the_shape_pass_reuses_the_base_laws_kept_plan(monkeypatch):
    """Along the modal path the n pass lays out no nodes: the base law's kept plan (built
    with its geometry) reweighted by dp/dn gives what a plan laid out for dp/dn gives."""
    pb = _table2_family("gaussian")
    x = np.r_[2.5, 0.3, TABLE2_TRUTH * 1.01]
    _jacobians.moment_derivatives(pb, x)  # the base law's plan is kept after this pass
    law, sig, _ = pb.split(x)
    mom = _jacobians.moments(pb, x)
    built = []
    build = _modal.SegmentPlan._build

    def counted(self):
        built.append(self.law)
        return build(self)

    monkeypatch.setattr(_modal.SegmentPlan, "_build", counted)
    dm, dv = _jacobians._law_derivative(pb, x, law, sig, 0, mom.mean, True)
    assert not built
    d, seg = pb.data, sig.modal_segments
    dlaw = _jacobians._PdfDerivative(pb.jitter, [2.5, 0.3], law, 0)
    poles = seg.system.modal.poles
    fresh = _modal.SegmentPlan(dlaw, d.T, d.N, d.u, float(np.max(np.abs(poles))), poles=poles)
    mean, var, _, _ = _modal.modal_moments(fresh, _modal.tables(seg.system, d.u), keep=False)
    assert built  # (the referee laid its nodes out)
    np.testing.assert_allclose(dm, mean, rtol=0, atol=1e-14 * np.max(np.abs(mean)))
    ref_v = var + 2 * mean * (mean - mom.mean)
    np.testing.assert_allclose(dv, ref_v, rtol=0, atol=1e-14 * np.max(np.abs(ref_v)))
