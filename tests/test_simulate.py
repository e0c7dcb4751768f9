"""simulate() (jitterid.simulate): bad arguments are refused naming the argument, and a
realization is reproducible from its seed."""

import numpy as np
import pytest
from helpers import table2_data

import jitterid as ji


def test_bad_simulation_arguments():
    g = ji.TransferFunction([1.0], [1.0, 2.0])
    u = ji.telegraph_input(20.0, 0)
    with pytest.raises(ValueError, match="N must"):
        ji.simulate(g, u, ji.Uniform(0.5), 1.0, 3, 0.01, 0)
    with pytest.raises(ValueError, match="input ends"):
        ji.simulate(g, u, ji.Uniform(0.5), 1.0, 40, 0.01, 0)
    with pytest.raises(ValueError, match="noise_std"):
        ji.simulate(g, u, ji.Uniform(0.5), 1.0, 10, -0.01, 0)
    with pytest.raises(ValueError, match="not stable"):
        ji.simulate(ji.TransferFunction([1.0], [1.0, -2.0]), u, ji.Uniform(0.5), 1.0, 10, 0.01, 0)
    with pytest.raises(ValueError, match="a"):
        ji.Uniform(-0.5)
    with pytest.raises(ValueError, match="outside its bounds"):
        ji.PolePairGain().system([1.0, 0.5, 2.0])


def test_simulation_is_reproducible_from_the_seed():
    a, b = table2_data(21), table2_data(21)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(a.y, table2_data(22).y)
