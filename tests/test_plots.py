"""Plot functions: draw what they are given, on the axes given, and return the artists."""

from __future__ import annotations

import itertools

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


def db(x):
    return 20 * np.log10(x)


def test_bode_draws_the_band_and_references_in_db(band):
    ref = ji.TransferFunction([5.0], [1.0, 3.0, 5.0])
    art = plots.plot_bode(band, {"other": ref})
    np.testing.assert_allclose(art["magnitude"].get_ydata(), db(band.magnitude))
    np.testing.assert_array_equal(art["phase"].get_xdata(), band.f)
    np.testing.assert_allclose(
        art["other magnitude"].get_ydata(), db(np.abs(ref.frequency_response(band.f)))
    )
    verts = art["magnitude_band"].get_paths()[0].vertices
    assert verts[:, 1].min() == pytest.approx(db(band.magnitude_lo).min())
    assert verts[:, 1].max() == pytest.approx(db(band.magnitude_hi).max())
    assert art["magnitude"].axes is not art["phase"].axes
    # A small object out, python-control style: the artists by name, the figure and axes.
    assert isinstance(art, plots.Plot)
    assert art.axes == (art["magnitude"].axes, art["phase"].axes)
    assert art.figure is art["magnitude"].figure
    assert art.legend is art.axes[0].get_legend()
    assert "dB" in art.axes[0].get_ylabel()


def _tick_labels(ax, which):
    """The visible, non-empty tick labels of an axis (of a figure drawn already)."""
    axis = ax.yaxis if which == "y" else ax.xaxis
    return [t for t in axis.get_ticklabels(which="both") if t.get_visible() and t.get_text()]


@pytest.mark.parametrize(
    "f", [np.geomspace(0.01, 0.5, 50), np.geomspace(1e-3, 50, 200), np.geomspace(0.2, 0.3, 40)]
)
def test_bode_ticks_are_round_and_do_not_overlap(f):
    """The issue: a linear magnitude with every minor tick labelled, overlapping. Now dB
    ticks at multiples of 1, 2, 2.5 or 5 x 10^k, phase at multiples of 15 degrees, and no
    two labels on an axis overlap, over a narrow and a wide range."""
    g = ji.TransferFunction([1.0, 2.0], [1.0, 0.6, 9.0, 1.0]).frequency_response(f)
    mag, ph = np.abs(g), np.degrees(np.unwrap(np.angle(g)))
    art = plots.plot_bode(BodeBand(f, mag, 0.0 * mag, 2 * mag, ph, ph - 5, ph + 5, 0.95))
    ax_mag, ax_ph = art.axes
    step = np.diff(ax_mag.get_yticks())[0]
    mant = step / 10 ** np.floor(np.log10(step))
    assert min(abs(mant - m) for m in (1, 2, 2.5, 5)) < 1e-9
    assert np.allclose(np.mod(ax_ph.get_yticks(), 15), 0) or np.allclose(
        np.mod(ax_ph.get_yticks(), 1.5), 0
    )
    # The -inf dB lower edge (|G| = 0) does not set the range: the curve fills the axes.
    lo, _ = ax_mag.get_ylim()
    assert np.isfinite(lo)
    assert lo > db(mag).min() - 30
    art.figure.canvas.draw()  # once: the labels' places do not change between draws
    renderer = art.figure.canvas.get_renderer()
    for ax, which in ((ax_mag, "y"), (ax_ph, "y"), (ax_ph, "x")):
        boxes = [t.get_window_extent(renderer) for t in _tick_labels(ax, which)]
        assert len(boxes) >= 2
        for a, b in itertools.pairwise(boxes):
            assert not a.overlaps(b), (which, [t.get_text() for t in _tick_labels(ax, which)])


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


def test_jitter_pdf_of_a_moment_route_measurement_is_drawn_at_its_std():
    """``measure_jitter(method="gaussian")``'s law drawn over +-4.5 of the measured std, in
    ps, with a band. Before session 26 the moment route's fit carried a jitter of 1e-18 s
    (the family's scale read at a std of 1 s, clipped by its bounds): the report's pdf was
    a curve of std 1e-6 ps with no band beside a measured 2 ps."""
    rng = np.random.default_rng(3)
    N, T = 8192, 1e-9
    tau = 2e-12 * rng.standard_normal(N)
    y = 0.95 * np.sin(2 * np.pi * 97.3e6 * (np.arange(N) * T + tau))
    y += 30e-6 * rng.standard_normal(N)
    m = ji.measure_jitter(y, T, method="gaussian", laws=["gaussian"])
    art = plots.plot_jitter_pdf(m)
    x = art["pdf"].get_xdata()
    assert np.max(x) == pytest.approx(4.5 * m.jitter_std * 1e12, rel=1e-6)
    assert "band" in art
    assert art["pdf"].axes.get_xlabel() == "jitter τ (ps)"
    # law-free (the default laws): a Gaussian of the measured std, said to be one
    free = ji.measure_jitter(y, T, method="gaussian")
    assert free.family == "law-free"
    label = plots.plot_jitter_pdf(free)["pdf"].get_label()
    assert label.startswith("law-free: a Gaussian of the measured std"), label


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
    assert art.axes == tuple(axes)
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
