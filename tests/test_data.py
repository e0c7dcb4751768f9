"""SampledData (jitterid.data) refuses bad data with a ValueError naming what is wrong."""

import numpy as np
import pytest

import jitterid as ji


def test_bad_data_is_refused():
    u = ji.telegraph_input(20.0, 0)
    with pytest.raises(ValueError, match="y contains"):
        ji.SampledData([1.0, np.nan, 2.0, 3.0], 1.0, u)
    with pytest.raises(ValueError, match="at least 4"):
        ji.SampledData([1.0, 2.0], 1.0, u)
    with pytest.raises(ValueError, match="T must"):
        ji.SampledData([1.0, 2.0, 3.0, 4.0], 0.0, u)
    with pytest.raises(ValueError, match="noise_std"):
        ji.SampledData([1.0, 2.0, 3.0, 4.0], 1.0, u, noise_std=-1)
    with pytest.raises(ValueError, match="instants"):
        ji.SampledData([1.0, 2.0, 3.0, 4.0], 1.0, u, instants=[0.0, 1.0])
