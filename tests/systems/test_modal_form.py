"""One public home of the modal form (TransferFunction.modal), and the signal capability
(Signal.modal_segments) that the moments' segment route asks for instead of a type."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray
from scipy import signal as sps

import jitterid as ji
from jitterid.systems.model import ModalSegments, Signal

G = ji.TransferFunction([1.0, 0.5, 3.0], [1.0, 1.2, 4.0, 2.0])  # a real pole and a complex pair
U = ji.telegraph_input(40.0, rng=3)
T, N = 0.5, 60


def test_the_modal_form_is_the_partial_fraction_expansion():
    m = G.modal
    r, p, k = sps.residue(G.num, G.den)
    order = [int(np.argmin(np.abs(p - q))) for q in m.poles]
    np.testing.assert_allclose(m.residues, r[order], rtol=1e-12)
    np.testing.assert_allclose(m.poles, p[order], rtol=1e-12)
    assert m.direct == 0.0
    assert k.size == 0
    _, rho, pk, cols = m.kept()
    assert pk.size == 2
    assert np.all(pk.imag >= 0)
    np.testing.assert_array_equal(pk, m.poles[cols])
    pair = pk.imag > 0
    np.testing.assert_allclose(rho[pair], 2 * m.residues[cols][pair])
    np.testing.assert_allclose(rho[~pair], m.residues[cols][~pair])
    biproper = ji.TransferFunction([2.0, 1.0], [1.0, 4.0])
    assert biproper.modal.direct == 2.0


def test_an_unstable_system_has_no_modal_form():
    with pytest.raises(ValueError, match="not stable"):
        _ = ji.TransferFunction([1.0], [1.0, -1.0]).modal


def test_the_response_declares_its_segments_only_for_a_piecewise_constant_input():
    seg = G.response(U).modal_segments
    assert isinstance(seg, ModalSegments)
    assert seg.system is G
    assert seg.u is U
    ms = ji.Multisine([0.1], [1.0], end=100.0)
    assert G.response(ms).modal_segments is None
    delayed = ji.TransferFunction([1.0], [1.0, 1.0], delay_s=0.2).response(U)
    assert delayed.modal_segments is None  # its jitter-equivalent inner response has them
    assert delayed.jitter_equivalent(ji.Uniform(0.1))[1].modal_segments is not None


class Wrapped(Signal):
    """A signal of its own class that is an LTI response and says so."""

    def __init__(self, inner: ji.Response) -> None:
        self.inner, self.calls = inner, 0
        self.breaks, self.rate = inner.breaks, inner.rate
        self.start, self.end = inner.start, inner.end

    def __call__(self, t: ArrayLike) -> NDArray[np.float64]:
        self.calls += 1
        return self.inner(t)

    @property
    def modal_segments(self) -> ModalSegments | None:
        return self.inner.modal_segments


def test_a_signal_that_declares_its_segments_takes_the_segment_route():
    resp = G.response(U)
    sig = Wrapped(resp)
    got = ji.sample_moments(sig, ji.Uniform(0.2), T, N)
    assert sig.calls == 0  # before: a type test sent it node by node
    want = ji.sample_moments(resp, ji.Uniform(0.2), T, N)
    np.testing.assert_array_equal(got.mean, want.mean)
    np.testing.assert_array_equal(got.var, want.var)
