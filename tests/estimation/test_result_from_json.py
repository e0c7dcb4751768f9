"""Issue 25, item 7: FitResult.from_json refuses what is not a result with a ValueError
naming the problem (was AttributeError, KeyError, RecursionError, ModuleNotFoundError), and
builds only jitterid's own value classes (a path through a module attribute instantiated a
scipy class)."""

import json

import numpy as np
import pytest

import jitterid as ji
from jitterid import _serial
from jitterid.estimation.result import FitResult


@pytest.fixture(scope="module")
def result():
    G = ji.TransferFunction([2.0], [1.0, 2.0])
    u = ji.telegraph_input(10.0, rng=1)
    data = ji.simulate(G, u, ji.Uniform(0.05), T=0.1, N=80, noise_std=0.01, rng=2)
    return ji.fit(data, ji.RationalModel(0, 1), ji.Uniform(0.05), method="ls")


def with_structure(result, value):
    d = json.loads(result.to_json())
    d["structure"] = value
    return json.dumps(d)


def test_the_round_trip_still_works(result):
    back = FitResult.from_json(result.to_json())
    np.testing.assert_array_equal(back.x, result.x)
    assert back.status is result.status
    assert type(back.structure) is type(result.structure)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("null", "holds NoneType"),
        ("[1, 2]", "holds list"),
        ('{"status": "CONVERGED"}', "missing field"),
        ("[" * 100_000 + "]" * 100_000, "nested more than"),
        ('{"a": ' * 5000 + "1" + "}" * 5000, "nested more than"),
        ("{not json", "Expecting"),
    ],
)
def test_what_is_not_a_result_is_a_value_error(text, match):
    with pytest.raises(ValueError, match=match):
        FitResult.from_json(text)


@pytest.mark.parametrize(
    ("tag", "match"),
    [
        ("jitterid.nope:X", "no module 'jitterid.nope'"),
        ("jitterid.systems.structures:Nope", "defines no class"),
        # a module attribute leads out of jitterid: refused before anything is built
        ("jitterid.analysis.diagnostics:stats.MonteCarloMethod", "defines no class"),
        ("jitterid.estimation.result:np.ndarray", "defines no class"),
        ("os:system", "not a jitterid class"),
        # a jitterid name that is not one of its value objects
        ("jitterid.estimation.result:FitStatus", "not a jitterid value object"),
        ("jitterid.systems.structures:ModelStructure", "not a jitterid value object"),
    ],
)
def test_only_jitterid_value_classes_are_built(result, tag, match):
    with pytest.raises(ValueError, match=match):
        FitResult.from_json(with_structure(result, {"__class__": tag, "n_resamples": 3}))


def test_a_value_object_with_wrong_fields_or_kinds(result):
    tag = "jitterid.systems.structures:RationalModel"
    with pytest.raises(ValueError, match=r"cannot build .*RationalModel"):
        FitResult.from_json(with_structure(result, {"__class__": tag, "bogus": 1}))
    with pytest.raises(ValueError, match="structure must be a Model"):
        FitResult.from_json(with_structure(result, [1, 2, 3]))
    d = json.loads(result.to_json())
    d["x"] = "abc"
    with pytest.raises(ValueError, match="not a FitResult"):
        FitResult.from_json(json.dumps(d))
    d = json.loads(result.to_json())
    d["extra"] = 1
    with pytest.raises(ValueError, match="unknown field"):
        FitResult.from_json(json.dumps(d))
    with pytest.raises(TypeError, match="dictionary"):
        FitResult.from_dict(None)


def test_decode_depth_is_bounded():
    deep = 1.0
    for _ in range(_serial.MAX_DEPTH + 5):
        deep = [deep]
    with pytest.raises(ValueError, match="nested more than"):
        _serial.decode(deep)
