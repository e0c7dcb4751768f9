"""User control of the search (jitterid.systems.constrained): Constrained structures (start values,
bounds, fixed parameters) in Python and the fit command's --start, --bounds and --fix."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

import jitterid as ji
from jitterid import _serial
from jitterid.cli import main
from jitterid.estimation import jacobians
from jitterid.estimation.estimators import method_names
from jitterid.estimation.problem import Problem
from jitterid.systems.structures import ModelStructure

T, N, NOISE = 0.5, 80, 0.02
TRUTH = {"k0": 6.25, "pr": -1.5, "pi": 2.0}


@pytest.fixture(scope="module")
def data() -> ji.SampledData:
    u = ji.telegraph_input(N * T + 2, 1)
    return ji.simulate(
        ji.PolePairGain().system(list(TRUTH.values())), u, ji.Uniform(0.3), T, N, NOISE, 2
    )


# ------------------------------------------------------------------ independent referees
class KnownGain(ModelStructure):
    """The referee for ``fixed={"k0": 6.25}``: the pole pair with k0 written in."""

    param_names = ("pr", "pi")  # type: ignore[assignment]
    bounds = ((-np.inf, -1e-6), (1e-3, np.inf))  # type: ignore[assignment]

    def system(self, params):
        pr, pi = self._check(params)
        return ji.TransferFunction(np.array([6.25]), np.array([1.0, -2.0 * pr, pr * pr + pi * pi]))

    def starts(self, T):
        return [s[1:] for s in ji.PolePairGain().starts(T)]


class KnownReal(ModelStructure):
    """The referee for ``fixed={"pr": -1.5}``: k0 and pi free, k0 still a gain."""

    param_names = ("k0", "pi")  # type: ignore[assignment]
    bounds = ((-np.inf, np.inf), (1e-3, np.inf))  # type: ignore[assignment]

    @property
    def gain_params(self):
        return (0,)

    def system(self, params):
        k0, pi = self._check(params)
        return ji.TransferFunction(np.array([k0]), np.array([1.0, 3.0, 2.25 + pi * pi]))

    def starts(self, T):
        return [s[[0, 2]] for s in ji.PolePairGain().starts(T)]


class TwoPoles(ModelStructure):
    """G = p q / ((s + p)(s + q)): symmetric in (p, q), so the criterion has two equal
    minima, (p, q) and (q, p); the start decides which one a search finds."""

    param_names = ("p", "q")  # type: ignore[assignment]
    bounds = ((1e-3, np.inf), (1e-3, np.inf))  # type: ignore[assignment]

    def system(self, params):
        p, q = self._check(params)
        return ji.TransferFunction(np.array([p * q]), np.array([1.0, p + q, p * q]))

    def starts(self, T):
        return [np.array([0.5, 5.0])]


def differences(structure, theta, n, h=1e-6):
    """Central differences of structure.system(): d(num, den)/dtheta, num padded to n."""
    theta = np.asarray(theta, float)
    pad = lambda c: np.r_[np.zeros(n - c.size), c]
    dnum, dden = np.zeros((theta.size, n)), np.zeros((theta.size, n))
    for i in range(theta.size):
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        a, b = structure.system(up), structure.system(down)
        dnum[i] = (pad(a.num) - pad(b.num)) / (2 * h)
        dden[i] = (pad(a.den) - pad(b.den)) / (2 * h)
    return dnum, dden


# ------------------------------------------------------------------ the structure
def test_names_bounds_system_and_gains():
    c = ji.Constrained(ji.PolePairGain(), fixed={"k0": 6.25}, bounds={"pr": (-3, None)})
    assert c.param_names == ("pr", "pi")
    assert c.bounds == ((-3.0, -1e-6), (1e-3, np.inf))
    assert c.fixed == {"k0": 6.25}
    assert c.user_bounds == {"pr": (-3.0, np.inf)}
    np.testing.assert_array_equal(c.system([-1.5, 2.0]).den, [1.0, 3.0, 6.25])
    np.testing.assert_array_equal(c.system({"pr": -1.5, "pi": 2.0}).num, [6.25])
    assert c.gain_params == ()  # the gain is fixed: the data's scaling would move it
    assert ji.Constrained(ji.PolePairGain(), fixed={"pr": -1.5}).gain_params == (0,)
    assert ji.Constrained(ji.PolePairGain(), start={"k0": 1.0}).gain_params == ()
    assert ji.Constrained(ji.PolePairGain(), bounds={"k0": (0, None)}).gain_params == ()
    r = ji.Constrained(ji.RationalModel(1, 2), fixed={"a1": 3.0})
    assert r.param_names == ("b1", "b0", "a0")
    assert r.gain_params == (0, 1)
    # everything fixed: a known system
    k = ji.Constrained(ji.PolePairGain(), fixed=TRUTH)
    assert k.param_names == ()
    assert k.bounds == ()
    np.testing.assert_array_equal(k.system().den, [1.0, 3.0, 6.25])
    assert [s.size for s in k.starts(T)] == [0]


def test_starts_put_the_users_first_inside_the_bounds():
    inner = ji.PolePairGain()
    c = ji.Constrained(inner, fixed={"k0": 6.25}, bounds={"pr": (-1.0, -0.2)}, start={"pi": 2.5})
    starts = c.starts(T)
    first = inner.starts(T)[0]
    np.testing.assert_array_equal(starts[0], [np.clip(first[1], -1.0, -0.2), 2.5])
    lo, hi = np.array(c.bounds).T
    for s in starts:
        assert s[1] == 2.5
        assert np.all((lo <= s) & (s <= hi))
    assert len({tuple(s) for s in starts}) == len(starts)  # no repeats
    full = ji.Constrained(inner, start={"k0": 5.0, "pr": -1.0, "pi": 1.0})
    assert [s.tolist() for s in full.starts(T)] == [[5.0, -1.0, 1.0]]


@pytest.mark.parametrize(
    ("inner", "kw", "theta"),
    [
        (ji.PolePairGain(), {"fixed": {"k0": 6.25}}, [-1.5, 2.0]),
        (ji.PolePairGain(), {"fixed": {"pr": -1.5}, "bounds": {"pi": (0.5, 5)}}, [6.25, 2.0]),
        (ji.RationalModel(1, 3), {"fixed": {"b1": 0.5, "a1": 2.0}}, [1.0, 3.0, 0.7]),
    ],
)
def test_coefficient_jacobian_against_differences_of_system(inner, kw, theta):
    c = ji.Constrained(inner, **kw)
    n = c.system(theta).den.size
    closed = c.coefficient_jacobian(theta, n)
    assert closed is not None
    for got, want in zip(closed, differences(c, theta, n), strict=True):
        np.testing.assert_allclose(got, want, atol=1e-7)
    # the modal fast path takes this closed form (no differences of the wrapper)
    for got, want in zip(
        c.coefficient_derivatives(np.asarray(theta, float), n), closed, strict=True
    ):
        np.testing.assert_array_equal(got, want)


def test_an_inner_closed_form_for_another_map_is_not_used():
    class LogGain(ji.PolePairGain):  # redefines the map below PolePairGain's closed form
        def system(self, params):
            p = np.asarray(params, float)
            return super().system([np.exp(p[0]), p[1], p[2]])

    assert ji.Constrained(LogGain(), fixed={"pr": -1.5}).coefficient_jacobian([1.8, 2.0], 3) is None


def test_moment_derivatives_are_the_inner_ones_free_rows(data):
    """The wrapper's dm_k/dtheta through the modal fast path against a second route: the
    inner structure's at the same system, rows of the free parameters."""
    f = ji.default_frequencies(N, T)
    law = ji.Uniform(0.3)
    c = ji.Constrained(ji.PolePairGain(), fixed={"pi": 2.0})
    mine = jacobians.moment_derivatives(
        Problem(data, c, law, "bcls", f, None), np.array([6.0, -1.4])
    )
    ref = jacobians.moment_derivatives(
        Problem(data, ji.PolePairGain(), law, "bcls", f, None), np.array([6.0, -1.4, 2.0])
    )
    np.testing.assert_allclose(mine[0].mean, ref[0].mean, rtol=1e-12)
    np.testing.assert_allclose(mine[2], ref[2][[0, 1]], rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"fixed": {"k": 1.0}}, r"fixed: unknown parameter\(s\) 'k' \(did you mean 'k0'\?\)"),
        ({"start": {"PR": -1.0}}, r"did you mean 'pr'"),
        ({"bounds": {"pr": (-1, -2)}}, r"bounds\['pr'\].*low end must be below"),
        ({"bounds": {"pr": (1, 2)}}, r"bounds\['pr'\].*leaves nothing"),
        ({"bounds": {"pr": 3}}, r"bounds\['pr'\] must be a pair"),
        ({"start": {"pr": 1.0}}, r"start\['pr'\] = 1 is outside its bounds"),
        ({"start": {"pr": -5.0}, "bounds": {"pr": (-3, -1)}}, r"start\['pr'\] = -5 is outside"),
        ({"fixed": {"pi": 0.0}}, r"fixed\['pi'\] = 0 is outside the bounds"),
        ({"fixed": {"pi": "2"}}, r"fixed\['pi'\] must be a finite number"),
        ({"fixed": {"pi": np.nan}}, r"fixed\['pi'\] must be a finite number"),
        ({"fixed": {"pi": 2.0}, "start": {"pi": 2.0}}, r"start: \['pi'\] is fixed"),
    ],
)
def test_bad_arguments_name_the_argument_and_the_fix(kw, match):
    with pytest.raises(ValueError, match=match):
        ji.Constrained(ji.PolePairGain(), **kw)


def test_wrong_kinds_of_object_are_type_errors():
    with pytest.raises(TypeError, match="fixed must be a dict by parameter name"):
        ji.Constrained(ji.PolePairGain(), fixed=[("pi", 2.0)])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="structure must be an LTI model structure"):
        ji.Constrained(ji.SineWave())  # type: ignore[arg-type]


# ------------------------------------------------------------------ fits
@pytest.mark.parametrize("method", ["ls", "bcls", "asml", "gaussian", "ml"])
@pytest.mark.parametrize(("fixed", "referee"), [("k0", KnownGain()), ("pr", KnownReal())])
def test_a_fixed_parameter_gives_the_fit_without_it(data, method, fixed, referee):
    """Fixed at its true value, a parameter gives the same estimates as a structure written
    by hand without it (whose derivatives are differences, not the inner closed form)."""
    law = ji.NoJitter() if method == "ls" else ji.Uniform(0.3)
    c = ji.Constrained(ji.PolePairGain(), fixed={fixed: TRUTH[fixed]})
    res, ref = ji.fit(data, c, law, method), ji.fit(data, referee, law, method)
    assert res.success
    assert ref.success
    assert res.names == ref.names
    np.testing.assert_allclose(res.x, ref.x, rtol=2e-5)
    np.testing.assert_allclose(res.cost, ref.cost, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(np.sqrt(np.diag(res.cov)), np.sqrt(np.diag(ref.cov)), rtol=1e-3)
    np.testing.assert_allclose(res.system.den, ref.system.den, rtol=2e-5)


@pytest.mark.parametrize(
    ("method", "family"),
    [
        (m, f) for m in method_names() for f in (False, True) if not (m == "ls" and f)
    ],  # ls: no family
)
def test_every_method_fits_a_constrained_structure(data, method, family):
    jitter = (
        ji.UniformFamily() if family else (ji.NoJitter() if method == "ls" else ji.Uniform(0.3))
    )
    c = ji.Constrained(
        ji.PolePairGain(), fixed={"k0": 6.25}, bounds={"pi": (0.5, 5)}, start={"pr": -1.0}
    )
    res = ji.fit(data, c, jitter, method)
    assert res.success, res.message
    assert res.layout.system == ("pr", "pi")
    assert res.system.num.tolist() == [6.25]
    assert res.structure.fixed == {"k0": 6.25}
    back = ji.FitResult.from_json(res.to_json())
    assert back.structure == c
    assert back.params == res.params
    np.testing.assert_array_equal(back.predict(data), res.predict(data))
    band = ji.bode_band(back, [0.05, 0.2, 0.5])
    assert np.all(band.magnitude_lo <= band.magnitude)
    assert np.all(band.magnitude <= band.magnitude_hi)


def test_every_parameter_fixed_estimates_the_jitter_alone(data):
    res = ji.fit(
        data, ji.Constrained(ji.PolePairGain(), fixed=TRUTH), ji.UniformFamily(), "gaussian"
    )
    assert res.success
    assert res.names[:1] == ("a",)
    assert "k0" not in res.names
    assert res.params["a"] == pytest.approx(0.3, rel=0.3)
    np.testing.assert_array_equal(res.system.den, [1.0, 3.0, 6.25])


def test_bounds_are_respected_and_an_estimate_on_one_is_at_bound(data):
    free = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), "bcls")
    assert free.success
    assert free.params["pr"] < -1.2
    c = ji.Constrained(ji.PolePairGain(), bounds={"pr": (-1.0, -0.1)})
    res = ji.fit(data, c, ji.Uniform(0.3), "bcls")
    assert res.status is ji.FitStatus.AT_BOUND
    assert res.params["pr"] == pytest.approx(-1.0, abs=1e-9)
    assert "pr" in res.message
    assert "the bound -1 you set" in res.message
    # a bound that does not bind changes nothing
    loose = ji.fit(
        data,
        ji.Constrained(ji.PolePairGain(), bounds={"pr": (-5.0, -0.1)}),
        ji.Uniform(0.3),
        "bcls",
    )
    assert loose.success
    np.testing.assert_allclose(loose.x, free.x, rtol=1e-5)


def test_the_start_decides_which_of_two_optima_is_found():
    """Two equal minima, (p, q) = (1, 3) and (3, 1): the default start finds the first, a
    user start near the second finds that one."""
    u = ji.telegraph_input(N * T + 2, 3)
    d = ji.simulate(TwoPoles().system([1.0, 3.0]), u, ji.NoJitter(), T, N, 0.005, 4)
    default = ji.fit(d, TwoPoles(), ji.NoJitter(), "ls")
    assert default.success
    np.testing.assert_allclose(default.x, [1.0, 3.0], rtol=0.05)
    c = ji.Constrained(TwoPoles(), start={"p": 5.0, "q": 0.5})
    assert c.starts(T)[0].tolist() == [5.0, 0.5]
    swapped = ji.fit(d, c, ji.NoJitter(), "ls")
    assert swapped.success
    np.testing.assert_allclose(swapped.x, [3.0, 1.0], rtol=0.05)
    np.testing.assert_allclose(swapped.cost, default.cost, rtol=1e-6)


def test_json_codec_round_trip():
    c = ji.Constrained(
        ji.Constrained(ji.RationalModel(0, 2), fixed={"a1": 3.0}),
        bounds={"a0": (0, None), "b0": (None, 10)},
        start={"a0": 6.0},
    )
    text = json.dumps(_serial.encode(c))
    assert '"bounds"' in text
    assert "user_bounds" not in text
    back = _serial.decode(json.loads(text))
    assert back == c
    assert hash(back) == hash(c)
    assert back.user_bounds == {"b0": (-np.inf, 10.0), "a0": (0.0, np.inf)}
    np.testing.assert_array_equal(back.system([2.0, 6.0]).den, [1.0, 3.0, 6.0])


# ------------------------------------------------------------------ command line
def run(*args: str | Path) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("lab")
    res = run("simulate", "--out", d, "--seed", "3", "--N", "60")
    assert res.exit_code == 0, res.output
    return d


def fit_args(lab: Path, out: Path, *extra: str) -> list[str | Path]:
    return [
        "fit",
        lab / "data.csv",
        "--input",
        lab / "input.csv",
        "--model",
        "polepair",
        "--jitter",
        "uniform",
        "--method",
        "bcls",
        "--out",
        out,
        "--no-plots",
        "-q",
        *extra,
    ]


@pytest.mark.parametrize(
    ("extra", "option", "text"),
    [
        (["--fix", "k0"], "--fix", "write NAME=VALUE"),
        (["--fix", "=1"], "--fix", "write NAME=VALUE"),
        (["--fix", "k0=abc"], "--fix", "'abc' is not a number"),
        (["--fix", "k0=inf"], "--fix", "finite number"),
        (["--fix", "k0=1", "--fix", "k0=2"], "--fix", "k0 is given twice"),
        (["--fix", "kO=1"], "--fix", "did you mean 'k0'?"),
        (["--fix", "a=0.3"], "--fix", "--jitter known:uniform:a=VALUE"),
        (["--fix", "noise_std=0.1"], "--fix", "--noise-std"),
        (["--fix", "pi=-1"], "--fix", "outside the bounds"),
        (["--start", "pr"], "--start", "write NAME=VALUE"),
        (["--start", "pr=x"], "--start", "not a number"),
        (["--start", "p=-1"], "--start", "did you mean"),
        (["--start", "pr=2"], "--start", "outside its bounds"),
        (["--start", "pr=-1", "--fix", "pr=-1"], "--start", "is fixed"),
        (["--bounds", "pr=-1"], "--bounds", "NAME=LO:HI"),
        (["--bounds", "pr=-1:-3"], "--bounds", "must be below the high end"),
        (["--bounds", "pr=-3:-3"], "--bounds", "must be below the high end"),
        (["--bounds", "pr=:"], "--bounds", "sets no bound"),
        (["--bounds", "pr=a:b"], "--bounds", "not a number"),
        (["--bounds", "pr=1:2"], "--bounds", "leaves nothing"),
        (["--bounds", "a=0:0.5"], "--bounds", "--jitter uniform:a_max=VALUE"),
        (["--bounds", "pr=-3:", "--bounds", "pr=:-1"], "--bounds", "pr is given twice"),
    ],
)
def test_bad_constraint_options_are_usage_errors_naming_the_option(
    lab, tmp_path, extra, option, text
):
    res = run(*fit_args(lab, tmp_path / "out", *extra))
    assert res.exit_code == 2, res.output
    assert f"Invalid value for '{option}'" in res.output
    assert text in " ".join(res.output.split())
    assert "Traceback" not in res.output
    assert not (tmp_path / "out").exists()


def test_every_parameter_fixed_on_the_command_line(lab, tmp_path):
    """The jitter alone is estimated; --method ls, with nothing to estimate, is refused."""
    fix = ["--fix", "k0=6.25", "--fix", "pr=-1.5", "--fix", "pi=2"]
    res = run(*fit_args(lab, tmp_path / "out", *fix))
    assert res.exit_code in (0, 3), res.output
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    assert set(result["parameters"]) == {"a"}
    assert result["model"]["fixed"] == {"k0": 6.25, "pr": -1.5, "pi": 2.0}
    args = fit_args(lab, tmp_path / "ls", *fix)
    args[args.index("bcls")] = "ls"
    args[args.index("uniform")] = "known:uniform:a=0.5"
    res = run(*args)
    assert res.exit_code == 2
    assert "nothing to estimate" in res.output


def test_cli_fit_with_fixed_and_bounded_parameters_writes_them(lab, tmp_path):
    out = tmp_path / "fit"
    res = run(*fit_args(lab, out, "--fix", "k0=6.25", "--bounds", "pr=-3:", "--start", "pi=2"))
    assert res.exit_code == 0, res.output
    result = json.loads((out / "result.json").read_text())
    model = result["model"]
    assert model["fixed"] == {"k0": 6.25}
    assert model["bounds"] == {"pr": [-3.0, None]}
    assert model["start"] == {"pi": 2.0}
    assert model["param_names"] == ["pr", "pi"]
    assert model["formula"] == "G(s) = k0 / ((s - pr)^2 + pi^2)"
    assert set(result["parameters"]) == {"a", "pr", "pi"}
    assert set(result["ordinary_ls"]["parameters"]) == {"pr", "pi"}
    assert result["system"]["num"] == [6.25]
    assert -3.0 <= result["parameters"]["pr"] < 0
    report = (out / "report.md").read_text()
    assert "**Constraints**: fixed k0 = 6.25" in report


def test_cli_without_constraints_is_unchanged(lab, tmp_path):
    out = tmp_path / "fit"
    res = run(*fit_args(lab, out))
    assert res.exit_code == 0, res.output
    model = json.loads((out / "result.json").read_text())["model"]
    assert set(model) == {"spec", "formula", "param_names"}


def test_a_bounded_gain_keeps_its_start_inside_the_bounds():
    """fit's ordinary start gives each start its least-squares gain; for a structure whose
    gain parameter is bounded that scaling could leave the bounds (scipy then refused the
    start: "Initial guess is outside of provided bounds"). The scaled start is now used only
    where it stays inside."""

    @dataclasses.dataclass(frozen=True)
    class SmallGain(ji.RationalModel):
        @property
        def bounds(self):  # type: ignore[override]
            return ((0.0, 1.0), (-np.inf, np.inf))

    rng = np.random.default_rng(5)
    u = ji.telegraph_input(90.0, rng)
    data = ji.simulate(
        ji.TransferFunction([2.0], [1.0, 1.0]),
        u,
        ji.Uniform(0.3),
        T=1.0,
        N=80,
        noise_std=0.01,
        rng=rng,
    )
    res = ji.fit(data, SmallGain(0, 1), ji.Uniform(0.3), "bcls")
    assert res.params["b0"] == pytest.approx(1.0)
    assert res.status is ji.FitStatus.AT_BOUND
