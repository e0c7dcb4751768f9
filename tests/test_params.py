"""The parameter layout (jitterid.params.ParamLayout): blocks by name, conversions between
vectors, dicts and fit results, and errors naming the fix."""

import numpy as np
import pytest
from helpers import table2_data

import jitterid as ji
from jitterid.params import ParamLayout


# ------------------------------------------------------------------ the parameter layout
def test_layout_blocks_and_conversions():
    lay = ParamLayout.build(
        ji.SumOfUniformsFamily(), ji.PolePairGain(), ji.RationalNoise(0, 1), noise_std=True
    )
    assert lay.names == ("n", "a", "k0", "pr", "pi", "hb0", "ha0", "noise_std")
    x = np.arange(8.0)
    assert lay.block(x, "jitter").tolist() == [0, 1]
    assert lay.block(x, "system").tolist() == [2, 3, 4]
    assert lay.block(x, "noise").tolist() == [5, 6]
    assert lay.block(x, "noise_std").tolist() == [7]
    np.testing.assert_array_equal(lay.vector(lay.to_dict(x)), x)
    np.testing.assert_array_equal(lay.vector(list(x)), x)
    with pytest.raises(ValueError, match="did you mean 'k0'"):
        lay.vector({**lay.to_dict(x), "K0": 1.0})
    with pytest.raises(ValueError, match="missing value"):
        lay.vector({"n": 1})
    with pytest.raises(ValueError, match="must have 8 values"):
        lay.vector([1, 2])
    with pytest.raises(ValueError, match="block must be one of"):
        lay.block(x, "plant")


def test_layout_takes_a_fit_result_by_name():
    data = table2_data(12, known_noise=False)
    res = ji.fit(data, ji.PolePairGain(), ji.Uniform(0.5), "gaussian")
    assert "noise_std" in res.names
    lay = ParamLayout.build(None, ji.PolePairGain())
    np.testing.assert_array_equal(lay.vector(res), res.x[:3])
