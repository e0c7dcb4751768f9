"""Issue 25, item 5: caches are not state. A FitResult or an OrderSelection pickles to the
same size after residuals()/predict() as before (TransferFunction._states_memo travelled:
9 kB -> 222 kB at N = 2000), and every class that memoises follows the one rule of
jitterid._state."""

import dataclasses
import importlib
import inspect
import pickle
import pkgutil
from functools import cached_property

import numpy as np
import pytest

import jitterid as ji
from jitterid._state import CachesAreNotState, cache_names

# Problem never leaves fit() (it is not pickled); estimation/problem.py is being rewritten,
# and its caches are to be declared with cache_field() there (issue 25 report).
NOT_YET: set[str] = set()


@pytest.fixture(scope="module")
def lab():
    rng = np.random.default_rng(1)
    truth = ji.PolePairGain().system([6.25, -1.5, 2.0])
    u = ji.telegraph_input(2002.0, rng)
    return ji.simulate(truth, u, ji.Uniform(0.5), T=1.0, N=2000, noise_std=0.01, rng=rng)


def test_a_fit_pickles_to_the_same_size_after_residuals_and_predict(lab):
    fit = ji.fit(lab, ji.PolePairGain(), ji.Uniform(0.5), method="ls")
    before = len(pickle.dumps(fit))
    r0 = fit.residuals(lab)
    fit.predict(lab)
    assert fit.system._states_memo is not None  # the memo was filled ...
    assert len(pickle.dumps(fit)) == before  # ... and does not travel
    back = pickle.loads(pickle.dumps(fit))
    assert back.system._states_memo is None
    np.testing.assert_array_equal(back.residuals(lab), r0)  # made again, same numbers


def test_an_order_selection_pickles_to_the_same_size_after_use(lab):
    sel = ji.select_order(lab, [ji.RationalModel(0, 1), ji.PolePairGain()], ji.Uniform(0.5), "ls")
    for row in sel.rows:
        row.result.residuals(lab)
    size = len(pickle.dumps(sel))
    for row in sel.rows:  # forget every memo by hand: the size must not change
        cls = type(row.result.system)
        props = {k for k, v in vars(cls).items() if isinstance(v, cached_property)}
        for key in [*props, "_states_memo"]:
            row.result.system.__dict__.pop(key, None)
    assert len(pickle.dumps(sel)) == size


def test_cached_properties_and_cache_fields_are_left_out_and_made_again():
    G = ji.TransferFunction([2.0], [1.0, 3.0, 2.0])
    G.poles  # noqa: B018 - fills the cached property
    assert "poles" in G.__dict__
    back = pickle.loads(pickle.dumps(G))
    assert "poles" not in back.__dict__
    np.testing.assert_array_equal(np.sort(back.poles), np.sort(G.poles))
    lik = ji.ExactLikelihood(ji.RationalModel(0, 1), ji.Uniform(0.05), None, 0.1, 4, 0.01)
    lik._cache[(1.0,)] = "x"
    lik._spares.append("y")
    back = pickle.loads(pickle.dumps(lik))
    assert back._cache == {}
    assert back._spares == []
    assert back._memo is None
    assert lik._cache  # the original keeps its caches


def _classes():
    for mod in pkgutil.walk_packages(ji.__path__, "jitterid."):
        if mod.name.startswith("jitterid.cli"):
            continue
        module = importlib.import_module(mod.name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == mod.name:
                yield cls


def test_every_class_that_memoises_follows_the_rule():
    """A cached property or a field named as a memo/cache makes a class a memoiser: it must
    derive from CachesAreNotState and declare such fields with cache_field()."""
    offenders = []
    seen = 0
    for cls in _classes():
        name = f"{cls.__module__}.{cls.__qualname__}"
        props = [k for k, v in vars(cls).items() if isinstance(v, cached_property)]
        memo_fields = [
            f.name
            for f in (dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ())
            if "memo" in f.name or "cache" in f.name
        ]
        if not (props or memo_fields) or name in NOT_YET:
            continue
        seen += 1
        declared = {f.name for f in cache_names(cls)[1]}
        if not issubclass(cls, CachesAreNotState) or set(memo_fields) - declared:
            offenders.append((name, props, sorted(set(memo_fields) - declared)))
    assert seen >= 8
    assert not offenders, offenders
