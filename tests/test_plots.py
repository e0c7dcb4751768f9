"""Plot functions: draw what they are given, on the axes given, and return the artists."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

import jitterid as ji
from jitterid import plots
from jitterid.analysis.diagnostics import JitterDetection
from jitterid.analysis.uncertainty import BodeBand, PdfBand


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture
def band() -> BodeBand:
    f = np.geomspace(0.01, 0.5, 50)
    g = ji.PolePairGain().system([6.25, -1.5, 2.0]).frequency_response(f)
    mag, ph = np.abs(g), np.degrees(np.unwrap(np.angle(g)))
    return BodeBand(f, mag, 0.9 * mag, 1.1 * mag, ph, ph - 5, ph + 5, 0.95)


def test_bode_draws_the_band_and_references(band):
    ref = ji.TransferFunction([5.0], [1.0, 3.0, 5.0])
    art = plots.plot_bode(band, {"other": ref})
    np.testing.assert_array_equal(art["magnitude"].get_ydata(), band.magnitude)
    np.testing.assert_array_equal(art["phase"].get_xdata(), band.f)
    np.testing.assert_allclose(art["other magnitude"].get_ydata(), np.abs(ref.frequency_response(band.f)))
    verts = art["magnitude_band"].get_paths()[0].vertices
    assert verts[:, 1].min() == pytest.approx(band.magnitude_lo.min())
    assert verts[:, 1].max() == pytest.approx(band.magnitude_hi.max())
    assert art["magnitude"].axes is not art["phase"].axes


def test_bode_uses_the_given_axes(band):
    _, axes = plt.subplots(2, 1)
    art = plots.plot_bode(band, ax=axes)
    assert art["magnitude"].axes is axes[0]
    assert art["phase"].axes is axes[1]
    with pytest.raises(ValueError, match="sequence of 2 matplotlib Axes"):
        plots.plot_bode(band, ax=axes[0])
    with pytest.raises(TypeError, match="band must be a BodeBand"):
        plots.plot_bode(None)  # type: ignore[arg-type]


def test_jitter_pdf_band_and_truth():
    tau = np.linspace(-1, 1, 101)
    law = ji.Uniform(0.5)
    pdf = law.pdf(tau)
    art = plots.plot_jitter_pdf(
        PdfBand(tau, pdf, 0.8 * pdf, 1.2 * pdf, 0.9, ()), truth=ji.Uniform(0.6)
    )
    np.testing.assert_array_equal(art["pdf"].get_ydata(), pdf)
    np.testing.assert_allclose(art["truth"].get_ydata(), ji.Uniform(0.6).pdf(tau))
    assert "band" in art
    known = plots.plot_jitter_pdf(PdfBand(tau, pdf, pdf, pdf, 0.9, ()))
    assert "band" not in known


def test_residual_panels_and_envelope():
    rng = np.random.default_rng(0)
    t = np.arange(30.0)
    slopes = rng.normal(size=30)
    r = rng.normal(size=30) * 0.1
    det = JitterDetection(
        3.0, 0.001, 0.2, (0.1, 0.3), 0.01, np.array([1e-4, 0.04]), 0.95, t, r, slopes
    )
    _, axes = plt.subplots(1, 2)
    art = plots.plot_residuals(det, ax=axes)
    np.testing.assert_array_equal(art["time"].get_offsets(), np.c_[t, r])
    np.testing.assert_array_equal(art["slope"].get_offsets(), np.c_[slopes, r])
    upper = art["envelope"][0]
    x = upper.get_xdata()
    np.testing.assert_allclose(upper.get_ydata(), 2 * np.sqrt(1e-4 + 0.04 * x**2))
    assert art["slope"].axes is axes[1]


def test_gain_factor_plot():
    f = np.linspace(0, 0.5, 20)
    art = plots.plot_gain_factor(f, ji.ls_gain_factor(ji.Uniform(0.5), f), tol=0.05)
    np.testing.assert_allclose(art["factor"].get_ydata(), np.abs(np.sinc(f)))
    assert art["tolerance"].get_ydata()[0] == pytest.approx(0.95)
    assert "tolerance" not in plots.plot_gain_factor(f, np.ones(20), tol=None)
