"""Loading a signal record with no input (a sine for the jitter meter), issue 26 item 5."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import jitterid as ji


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_a_y_only_file_loads_as_samples_with_t(tmp_path: Path) -> None:
    y = np.sin(0.3 * np.arange(50))
    p = _write(tmp_path / "sine.csv", "y\n" + "".join(f"{float(v)!r}\n" for v in y))
    ds = ji.load(p, T="2us", require_input=False)
    assert abs(ds.data.T - 2e-6) < 1e-18
    np.testing.assert_array_equal(ds.data.y, y)
    assert ds.data.u is None
    assert any("k = 0, 1" in n for n in ds.notes)
    # the T metadata line does as well
    p2 = _write(tmp_path / "sine2.csv", "# T: 0.5\ny\n" + "".join(f"{float(v)!r}\n" for v in y))
    assert ji.load(p2, require_input=False).data.T == 0.5


def test_a_y_only_file_without_t_says_how(tmp_path: Path) -> None:
    p = _write(tmp_path / "sine.csv", "y\n" + "".join(f"{v}\n" for v in range(10)))
    with pytest.raises(ji.DataFileError, match=r"give T \(load\(path, T=\.\.\.\)"):
        ji.load(p, require_input=False)


def test_a_headerless_column_of_numbers_says_how(tmp_path: Path) -> None:
    p = _write(tmp_path / "sine.csv", "".join(f"{np.sin(k):.6f}\n" for k in range(10)))
    with pytest.raises(ji.DataFileError, match=r"holds numbers, not column names.*header line 'y'"):
        ji.load(p, T=1.0, require_input=False)


def test_a_record_without_input_names_require_input(tmp_path: Path) -> None:
    p = _write(tmp_path / "sine.csv", "k,y\n" + "".join(f"{k},{np.sin(k)}\n" for k in range(10)))
    with pytest.raises(ji.DataFileError, match="require_input=False"):
        ji.load(p, T=1.0)
