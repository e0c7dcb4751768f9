"""The Box-Jenkins criteria (jitterid.estimation.bjcriteria): their limit without coloured
noise (the OE criteria), their analytic gradients and Jacobians against central differences,
and their Fisher matrices against Monte Carlo and a dense second route."""

import dataclasses

import numpy as np
import pytest
from helpers import SLOW_NOISE, central_differences, table2_data

import jitterid as ji
from jitterid.estimation.bjcriteria import BJProblem
from jitterid.estimation.problem import Problem

T = 1.0
TRUTH = np.array([6.25, -1.5, 2.0])
Z_MAX = 4.5  # |z| bound for Monte Carlo comparisons (two-sided p = 7e-6 per comparison)


@pytest.mark.parametrize("method", ["bcls", "wbcls", "asml", "asml-diag", "gaussian"])
def test_bj_criteria_reduce_to_the_oe_ones_as_the_coloured_noise_vanishes(method):
    data = table2_data(3, n=64)
    faint = ji.NoiseModel(ji.TransferFunction([1e-9], [1.0, 1.0]))  # variance 5e-19
    f = ji.default_frequencies(64, T)
    bj = BJProblem(data, ji.PolePairGain(), ji.Uniform(0.5), ji.KnownNoise(faint), method, f, 0.01)
    oe = Problem(data, ji.PolePairGain(), ji.Uniform(0.5), method, f, 0.01)
    x = np.array([6.0, -1.4, 2.1])
    assert bj.objective(x) == pytest.approx(oe.objective(x), rel=1e-9)
    np.testing.assert_allclose(bj.grad_y(x), oe.grad_y(x), rtol=1e-7, atol=1e-9)


# --------------------------------------------------------------------------- derivatives


def _bj_problem(method, jitter, n=60, noise=None, seed=1):
    """A BJ problem on data with slow coloured noise; the input covers wide jitter too."""
    rng = np.random.default_rng(seed)
    u = ji.telegraph_input(n * T + 8, rng)
    law = jitter if isinstance(jitter, ji.JitterLaw) else ji.Uniform(0.5)
    data = ji.simulate(
        ji.PolePairGain().system(TRUTH), u, law, T, n, 0.01, rng, noise_model=SLOW_NOISE
    )
    f = ji.default_frequencies(n, T)
    return BJProblem(
        data, ji.PolePairGain(), jitter, noise or ji.RationalNoise(0, 1), method, f, None
    )


# (jitter, parameter point): known uniform jitter, a free jitter family (JBJ), a Gaussian
# jitter wider than T (near lags by quadrature: the finite-difference path), a second-order
# noise model with a zero; points away from the truth, including the noise parameters.
DERIVATIVE_CASES = [
    (ji.Uniform(0.5), None, [6.0, -1.4, 2.1, 0.07, 0.08, 0.012]),
    (ji.Uniform(0.5), None, [6.5, -1.6, 1.9, 0.3, 1.5, 0.05]),
    (ji.UniformFamily(), None, [0.42, 6.1, -1.45, 2.05, 0.05, 0.2, 0.02]),
    (ji.Gaussian(0.4), None, [6.0, -1.4, 2.1, 0.3, 0.5, 0.02]),
    (ji.Uniform(0.5), ji.RationalNoise(1, 2), [6.0, -1.4, 2.1, 0.1, 0.2, 0.9, 0.4, 0.015]),
]


@pytest.mark.parametrize("method", ["gaussian", "asml", "asml-diag"])
@pytest.mark.parametrize(
    ("jitter", "noise", "x"), DERIVATIVE_CASES, ids=["u", "u-far", "jbj", "gauss", "order2"]
)
def test_bj_gradient_is_the_derivative_of_the_criterion(method, jitter, noise, x):
    """The analytic dV/dx of every joint BJ criterion (system, jitter, noise parameters and
    sigma_w) against central differences of V itself."""
    problem = _bj_problem(method, jitter, noise=noise)
    x = np.array(x)
    v, g, M = problem.objective_gradient(x)
    assert v == pytest.approx(problem.objective(x), rel=1e-12)
    fd = central_differences(problem.objective, x)
    np.testing.assert_allclose(g, fd, rtol=2e-5, atol=2e-6 * np.max(np.abs(fd)))
    assert np.all(np.linalg.eigvalsh(M) > 0)


@pytest.mark.parametrize(
    ("jitter", "noise", "x"), DERIVATIVE_CASES, ids=["u", "u-far", "jbj", "gauss", "order2"]
)
def test_gaussian_grad_y_jacobian_is_the_derivative_of_grad_y(jitter, noise, x):
    """The closed-form d^2 V / dx dy^T of the Gaussian BJ criterion (used by the covariance)
    against central differences of dV/dy; the gradient alone equals objective_gradient's."""
    problem = _bj_problem("gaussian", jitter, noise=noise)
    x = np.array(x)
    G = problem.grad_y_jacobian(x)
    fd = central_differences(problem.grad_y, x)
    np.testing.assert_allclose(G, fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd)))
    np.testing.assert_array_equal(problem.gradient(x), problem.objective_gradient(x)[1])


@pytest.mark.parametrize("method", ["bcls", "wbcls"])
def test_least_squares_jacobian_with_frozen_weights_is_the_derivative_of_the_residuals(method):
    """bcls and wbcls with R frozen at ``weights_at`` (the OE fix carried over to BJ: the
    literal (20) with R(theta) in the search is biased): -L^{-1} dmu against differences."""
    problem = _bj_problem(method, ji.Uniform(0.5))
    x = np.array([6.0, -1.4, 2.1, 0.07, 0.08, 0.012])
    if method == "wbcls":
        problem = dataclasses.replace(problem, pinned=x[3:], weights_at=x * 1.01)
        with pytest.raises(ValueError, match="literal wbcls"):
            dataclasses.replace(problem, weights_at=None).jacobian(x)
    J = problem.jacobian(x)[:, :3]
    fd = central_differences(problem.residuals, x)[:3].T
    np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-7 * np.max(np.abs(fd)))


@pytest.mark.parametrize("R", [300, pytest.param(1500, marks=pytest.mark.slow)])
def test_gaussian_fisher_matrix_is_the_expected_hessian_by_monte_carlo(R):
    """V = -2 ln L, so E[dV dV^T] = 2 E[d^2 V] = 2 M at the true parameters (information
    identity). Draws y ~ N(m, Sigma_y) of the model at x (dense Cholesky), the analytic
    gradient of each: the mean of g g^T / 2 against M (probe estimate of its trace term;
    exact mean term). Standard error of each entry from the spread over draws: R = 300 draws
    in the default run (the fast version), 1500 with -m slow."""
    problem = _bj_problem("gaussian", ji.Uniform(0.5), n=60)
    x = np.array([6.25, -1.5, 2.0, 0.06, 0.1, 0.01])
    _, _, M = problem.objective_gradient(x)
    mean = problem.moments(x).mean
    root = np.linalg.cholesky(problem.covariance(x).dense())
    rng = np.random.default_rng(8)
    G = []
    for _ in range(R):
        y = mean + root @ rng.standard_normal(mean.size)
        p = dataclasses.replace(problem, data=ji.SampledData(y, T, problem.data.u))
        G.append(p.objective_gradient(x)[1])
    G = np.array(G)
    outer = G[:, :, None] * G[:, None, :] / 2
    est, se = outer.mean(axis=0), outer.std(axis=0, ddof=1) / np.sqrt(R)
    scale = np.sqrt(np.outer(np.diag(M), np.diag(M)))
    # Within the Monte Carlo error plus the probes' (16 probes: ~35 % of the trace term,
    # which is a small part of the system block), relative to the diagonal scale.
    assert np.all(np.abs(est - M) < Z_MAX * se + 0.35 * scale), (est - M) / scale
    assert np.all(np.abs(np.diag(est) - np.diag(M)) < Z_MAX * np.diag(se) + 0.35 * np.diag(M))
    # the system block is dominated by the exact 2 dm^T S^-1 dm: 5 % there
    sys = slice(0, 3)
    assert np.all(
        np.abs(est[sys, sys] - M[sys, sys]) < Z_MAX * se[sys, sys] + 0.05 * scale[sys, sys]
    )


def test_gaussian_fisher_probes_converge_to_the_dense_trace(monkeypatch):
    """Second route for M: dense 2 dm^T S^-1 dm + tr(S^-1 dS_i S^-1 dS_j) with dm, dS by
    central differences of the moments and of the dense Sigma_y. With many probes the
    estimate must agree to ~5 %; with one probe (a wrong estimator is also 'an estimate')
    it must not match this well, which shows the test can fail."""
    import jitterid.estimation.bjcriteria as bjc

    problem = _bj_problem("gaussian", ji.Uniform(0.5), n=40)
    x = np.array([6.0, -1.4, 2.1, 0.07, 0.3, 0.012])
    dm = central_differences(lambda z: problem.moments(z).mean, x)
    S = problem.covariance(x).dense()
    dS = central_differences(lambda z: problem.covariance(z).dense(), x)
    Si = np.linalg.inv(S)
    A = np.einsum("ij,pjk->pik", Si, dS)
    exact = 2 * dm @ Si @ dm.T + np.einsum("pij,qji->pq", A, A)
    scale = np.sqrt(np.outer(np.diag(exact), np.diag(exact)))
    errors = {}
    for k in (1, 4000):
        monkeypatch.setattr(bjc, "PROBES", k)
        fresh = _bj_problem("gaussian", ji.Uniform(0.5), n=40)  # the same problem, new probes
        errors[k] = np.max(np.abs(fresh.objective_gradient(x)[2] - exact) / scale)
    assert errors[4000] < 0.05, errors
    assert errors[1] > 3 * errors[4000], errors


@pytest.mark.parametrize("method", ["asml", "asml-diag"])
def test_frequency_domain_fisher_matches_a_dense_second_route(method):
    """asml (22), asml-diag (23): M = 2 Re dmu^H R^-1 dmu + tr(R^-1 dR_i R^-1 dR_j) (diagonal
    R for asml-diag) with dmu and the dense dR by central differences of mu and of R_Y."""
    problem = _bj_problem(method, ji.Uniform(0.5), n=40)
    x = np.array([6.0, -1.4, 2.1, 0.07, 0.3, 0.012])
    d, f = problem.data, problem.freqs
    mu = lambda z: ji.dtft(problem.moments(z).mean, d.T, f)
    dmu = central_differences(lambda z: np.r_[mu(z).real, mu(z).imag], x)
    dmu = dmu[:, : f.size] + 1j * dmu[:, f.size :]
    R = problem.covariance(x).dft(d.T, f)
    dRr = central_differences(lambda z: problem.covariance(z).dft(d.T, f).real, x)
    dRi = central_differences(lambda z: problem.covariance(z).dft(d.T, f).imag, x)
    dR = dRr + 1j * dRi
    if method == "asml-diag":
        R = np.diag(np.diag(R).real)
        dR = np.array([np.diag(np.diag(m).real) for m in dR])
    Ri = np.linalg.inv(R)
    A = np.einsum("ij,pjk->pik", Ri, dR)
    ref = 2 * (dmu.conj() @ Ri @ dmu.T).real + np.einsum("pij,qji->pq", A, A).real
    M = problem.objective_gradient(x)[2]
    np.testing.assert_allclose(M, ref, rtol=1e-5, atol=1e-6 * np.max(np.abs(ref)))
