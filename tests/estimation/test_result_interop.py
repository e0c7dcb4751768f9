"""FitResult.to_scipy() and to_control() describe the fitted G(s) exactly."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy import signal

import jitterid as ji


@pytest.fixture(scope="module")
def result() -> ji.FitResult:
    rng = np.random.default_rng(2)
    u = ji.telegraph_input(62.0, rng)
    data = ji.simulate(
        ji.PolePairGain().system([6.25, -1.5, 2.0]), u, ji.Uniform(0.3), 1.0, 60, 0.01, rng
    )
    return ji.fit(data, ji.PolePairGain(), ji.Uniform(0.3), "bcls")


def test_to_scipy_has_the_same_frequency_response(result):
    f = np.array([0.0, 0.05, 0.2, 0.5, 2.0])
    lti = result.to_scipy()
    assert isinstance(lti, signal.lti)
    _, h = signal.freqresp(lti, w=2 * np.pi * f)  # scipy works in rad/s
    np.testing.assert_allclose(h, result.system.frequency_response(f), rtol=1e-12)
    np.testing.assert_allclose(np.sort_complex(lti.poles), np.sort_complex(result.system.poles))


def test_to_control_has_the_same_frequency_response(result):
    control = pytest.importorskip("control")  # installed with the dev extra
    f = np.array([0.0, 0.05, 0.2, 0.5, 2.0])
    tf = result.to_control()
    assert isinstance(tf, control.TransferFunction)
    h = np.array([complex(tf(2j * np.pi * fi)) for fi in f])
    np.testing.assert_allclose(h, result.system.frequency_response(f), rtol=1e-12)
    assert control.dcgain(tf) == pytest.approx(result.system.dcgain)


def test_to_control_without_the_extra_says_how_to_install(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)  # import control -> ImportError
    with pytest.raises(ImportError, match=r"pip install 'jitterid\[control\]'"):
        result.to_control()
