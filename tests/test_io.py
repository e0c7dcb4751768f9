"""Loader and writer: round trips, units, and a clear error for every malformed file."""

from __future__ import annotations

import hashlib
import json
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jitterid as ji
from jitterid.io import DataFileError, load, save_data, save_input

T = 1.0
N = 40


@pytest.fixture(scope="module")
def sim() -> tuple[ji.SampledData, ji.PiecewiseConstant]:
    rng = np.random.default_rng(11)
    u = ji.telegraph_input(N * T + 1.0, rng)
    g = ji.PolePairGain().system([6.25, -1.5, 2.0])
    return ji.simulate(g, u, ji.Uniform(0.5), T, N, 0.01, rng), u


def _csv(
    path: Path, header: str, rows: list[list[object]], meta: dict[str, object] | None = None
) -> Path:
    lines = [f"# {k}: {v}" for k, v in (meta or {}).items()]
    lines.append(header)
    lines += [",".join(str(c) for c in r) for r in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _grid_rows(n: int = 8, t0: float = 0.0, dt: float = 0.5) -> list[list[object]]:
    return [[repr(t0 + k * dt), repr(float(np.sin(k))), repr(float(k % 2))] for k in range(n)]


# ------------------------------------------------------------------------------ round trips


@pytest.mark.parametrize("ext", ["csv", "npz"])
@pytest.mark.parametrize("t0", [0.0, 12.0])
def test_round_trip_switch_input(tmp_path, sim, ext, t0):
    data, u = sim
    save_data(tmp_path / f"d.{ext}", data, t0=t0)
    save_input(tmp_path / f"u.{ext}", u, t0=t0)
    ds = load(tmp_path / f"d.{ext}", tmp_path / f"u.{ext}")
    assert np.array_equal(ds.data.y, data.y)
    assert ds.data.T == data.T
    assert ds.t0 == pytest.approx(t0)
    # The loaded input drives the same system to the same output (exact response).
    g = ji.PolePairGain().system([6.25, -1.5, 2.0])
    t = np.linspace(-0.5, N * T, 333)
    np.testing.assert_allclose(g.response(ds.data.u)(t), g.response(u)(t), atol=1e-12)
    assert ds.sources[0].sha256 == hashlib.sha256((tmp_path / f"d.{ext}").read_bytes()).hexdigest()
    assert ds.sources[1].role == "input"
    assert ds.units["frequency"] == "Hz"


def test_round_trip_index_column_and_zoh_input(tmp_path, sim):
    data, _ = sim
    levels = np.random.default_rng(3).choice([-1.0, 1.0], size=N + 5)
    u = ji.zoh_input(levels, T, start=-2 * T)  # the DAC started two samples early
    save_data(tmp_path / "d.csv", data, t0=4 * T, index=True)
    save_input(tmp_path / "u.csv", u, t0=4 * T, T=T)
    ds = load(tmp_path / "d.csv", tmp_path / "u.csv")
    assert ds.t0 == pytest.approx(4 * T)
    t = ds.data.t_nominal + 0.3 * T
    np.testing.assert_array_equal(ds.data.u(t), u(t))
    np.testing.assert_array_equal(ds.data.u(t), levels[2 : 2 + N])


def test_u_column_is_a_zero_order_hold_on_the_grid(tmp_path):
    rows = [[k, np.cos(k), (-1.0) ** k] for k in range(6)]
    path = _csv(tmp_path / "d.csv", "k,y,u", rows, {"T": 0.25})
    ds = load(path)
    assert ds.data.T == 0.25
    t = 0.25 * np.arange(6) + 0.1
    np.testing.assert_array_equal(ds.data.u(t), [(-1.0) ** k for k in range(6)])
    # the last value is held on past the grid (for the jitter's tail), and the notes say so
    assert ds.data.u.end > 6 * 0.25 + 10
    assert ds.data.u(6 * 0.25 + 5.0) == pytest.approx(-1.0)
    assert any("last value" in n for n in ds.notes)


def test_time_unit_is_converted_to_seconds(tmp_path):
    rows = [[2.0 * k, np.sin(k), 1.0] for k in range(6)]
    ms = load(_csv(tmp_path / "ms.csv", "t,y,u", rows, {"time_unit": "ms"}))
    step = ms.data.T
    assert step == pytest.approx(2e-3)
    s_rows = [[2e-3 * k, np.sin(k), 1.0] for k in range(6)]
    s = load(_csv(tmp_path / "s.csv", "t,y,u", s_rows))
    assert s.data.T == pytest.approx(step)  # noqa: SIM300
    assert ms.units["time"] == "s"


def test_metadata_from_sidecar_and_noise_std(tmp_path):
    rows = [[k, np.sin(k), 1.0] for k in range(6)]
    path = _csv(tmp_path / "d.csv", "k,y,u", rows)
    (tmp_path / "d.json").write_text(json.dumps({"T": 0.5, "noise_std": 0.02, "y_unit": "V"}))
    ds = load(path)
    assert ds.data.T == 0.5
    assert ds.data.noise_std == 0.02
    assert ds.units["y"] == "V"
    assert load(path, noise_std=0.5).data.noise_std == 0.5


def test_t_column_infers_T_and_tolerates_print_rounding(tmp_path):
    rows = [[f"{k / 3:.6f}", 1.0, 0.0] for k in range(30)]  # T = 1/3 printed with 6 decimals
    ds = load(_csv(tmp_path / "d.csv", "t,y,u", rows))
    step = ds.data.T
    assert step == pytest.approx(1 / 3, rel=1e-6)


# ------------------------------------------------------------------------------ errors


def _err(path, *args, **kw) -> str:
    with pytest.raises(DataFileError) as info:
        load(path, *args, **kw)
    return str(info.value)


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [
        (lambda r: r.__setitem__(3, [r[3][0], "", r[3][2]]), r"line 5, column 'y': missing value"),
        (lambda r: r.__setitem__(3, [r[3][0], "nan", r[3][2]]), r"line 5, column 'y'"),
        (
            lambda r: r.__setitem__(2, [r[2][0], "1.2.3", r[2][2]]),
            r"line 4, column 'y': '1.2.3' is not a number",
        ),
        (lambda r: r.insert(3, list(r[3])), r"line 6, column 't'.*repeats.*sort"),
        (
            lambda r: r.__setitem__(slice(2, 4), [r[3], r[2]]),
            r"line 5, column 't'.*decreases.*sort",
        ),
        (lambda r: r.pop(4), r"column 't'.*off the regular grid"),
        (
            lambda r: r.__setitem__(5, ["2.61", *r[5][1:]]),
            r"line 7, column 't'.*off the regular grid",
        ),
        (lambda r: r.__setitem__(1, r[1][:2]), r"line 3 has 2 cell\(s\) but the header"),
    ],
)
def test_malformed_rows_name_line_and_column(tmp_path, mutate, pattern):
    rows = _grid_rows()
    mutate(rows)
    msg = _err(_csv(tmp_path / "d.csv", "t,y,u", rows))
    assert re.search(pattern, msg), msg
    assert "d.csv" in msg


@pytest.mark.parametrize(
    ("header", "pattern"),
    [
        ("time,y,u", r"column 'time' is not recognised.*'k' or 't'"),
        ("t,Y,u", r"column 'Y' is not recognised.*Did you mean 'y'"),
        ("t,y,u,temp", r"column 'temp' is not recognised"),
        ("t,out,u", r"column 'out' is not recognised"),
        ("t,y,y", r"column 'y' appears twice"),
        ("t;y;u", r"comma-separated"),
        ("k,t,y", r"both 'k' and 't'"),
    ],
)
def test_wrong_column_names(tmp_path, header, pattern):
    ncol = len(re.split("[,;]", header))
    rows = [[k, 0.1 * k, 1.0, 2.0][:ncol] for k in range(6)]
    if ";" in header:
        rows = [[";".join(str(c) for c in r)] for r in rows]
    msg = _err(_csv(tmp_path / "d.csv", header, rows, {"T": 1.0}))
    assert re.search(pattern, msg), msg


def test_missing_output_column(tmp_path):
    msg = _err(_csv(tmp_path / "d.csv", "t,u", [[k, 1.0] for k in range(6)]))
    assert "no output column 'y'" in msg


def test_index_column_errors(tmp_path):
    rows = [[k, 1.0, 0.0] for k in range(6)]
    assert "T is not given" in _err(_csv(tmp_path / "a.csv", "k,y,u", rows))
    gap = [r for r in rows if r[0] != 3]
    assert re.search(
        r"line 6, column 'k': index jumps from 2 to 4",
        _err(_csv(tmp_path / "b.csv", "k,y,u", gap, {"T": 1})),
    )
    frac = [[k + 0.5 * (k == 2), 1.0, 0.0] for k in range(6)]
    assert "not an integer" in _err(_csv(tmp_path / "c.csv", "k,y,u", frac, {"T": 1}))
    assert "metadata say T = 2" in _err(_csv(tmp_path / "d.csv", "k,y,u", rows, {"T": 2}), T=1.0)


@pytest.mark.parametrize(
    ("meta", "pattern"),
    [
        ({"T": -1}, r"metadata 'T' .* must be a finite number > 0"),
        ({"T": "fast"}, r"metadata 'T'"),
        ({"time_unit": "hours"}, r"'time_unit' .* must be one of"),
        ({"noise_std": "-0.1"}, r"'noise_std'.*>= 0"),
    ],
)
def test_bad_metadata(tmp_path, meta, pattern):
    msg = _err(_csv(tmp_path / "d.csv", "k,y,u", [[k, 1.0, 0.0] for k in range(6)], meta))
    assert re.search(pattern, msg), msg


def test_sidecar_errors(tmp_path):
    path = _csv(tmp_path / "d.csv", "k,y,u", [[k, 1.0, 0.0] for k in range(6)], {"T": 1.0})
    (tmp_path / "d.json").write_text("{not json")
    assert "not valid JSON" in _err(path)
    (tmp_path / "d.json").write_text(json.dumps({"T": 2.0}))
    assert "in the file but 2.0 in d.json" in _err(path)
    (tmp_path / "d.json").write_text("[1, 2]")
    assert "JSON object" in _err(path)


def test_input_errors(tmp_path):
    data = _csv(tmp_path / "d.csv", "t,y", [[k, 1.0] for k in range(6)])
    assert "no input column 'u' and no input file" in _err(data)
    both = _csv(tmp_path / "b.csv", "t,y,u", [[k, 1.0, 0.0] for k in range(6)])
    assert "keep one of them" in _err(both, data)
    short = _csv(tmp_path / "short.csv", "t,u", [[k, 1.0] for k in range(4)])
    assert "must cover every sample" in _err(data, short)
    shifted = _csv(tmp_path / "shift.csv", "t,u", [[k + 0.5, 1.0] for k in range(8)])
    assert "not on the data's grid" in _err(data, shifted)
    other_T = _csv(tmp_path / "T.csv", "t,u", [[2.0 * k, 1.0] for k in range(8)])
    assert "on the data's grid" in _err(data, other_T)
    sw = _csv(tmp_path / "sw.csv", "time,level", [[0, 1.0], [3, -1.0], [9, 1.0]])
    assert re.search(r"ends at 6 s, not after its last switch", _err(data, sw))
    unsorted = _csv(tmp_path / "us.csv", "time,level", [[0, 1.0], [3, -1.0], [2, 1.0]], {"end": 10})
    assert re.search(r"line 5, column 'time'.*decreases", _err(data, unsorted))
    half = _csv(tmp_path / "half.csv", "time,u", [[0, 1.0]])
    assert "column 'u' is not recognised" in _err(data, half)
    assert "no such file" in _err(data, tmp_path / "nope.csv")


def test_switch_input_default_end_and_metadata_end(tmp_path):
    data = _csv(tmp_path / "d.csv", "t,y", [[k, 1.0] for k in range(6)])
    sw = _csv(tmp_path / "sw.csv", "time,level", [[0, 1.0], [2.5, -1.0]])
    assert load(data, sw).data.u.end == pytest.approx(6.0)
    sw2 = _csv(tmp_path / "sw2.csv", "time,level", [[0, 1.0], [2.5, -1.0]], {"end": 9.0})
    assert load(data, sw2).data.u.end == pytest.approx(9.0)


def test_file_level_errors(tmp_path):
    (tmp_path / "e.csv").write_text("")
    assert "no header row" in _err(tmp_path / "e.csv")
    (tmp_path / "h.csv").write_text("# T: 1\nt,y,u\n")
    assert "no data rows" in _err(tmp_path / "h.csv")
    (tmp_path / "b.csv").write_bytes(b"\xff\xfe\x00\x01binary")
    assert "not a UTF-8 text file" in _err(tmp_path / "b.csv")
    (tmp_path / "x.xlsx").write_text("t,y")
    assert "must be .csv or .npz" in _err(tmp_path / "x.xlsx")
    small = _csv(tmp_path / "s.csv", "t,y,u", [[k, 1.0, 0.0] for k in range(3)])
    assert "at least 4 are needed" in _err(small)


def test_npz_errors(tmp_path):
    t = np.arange(6.0)
    np.savez(tmp_path / "a.npz", t=t, y=np.c_[t, t], u=t)
    assert "array 'y' must be 1-D" in _err(tmp_path / "a.npz")
    np.savez(tmp_path / "b.npz", t=t, y=np.where(t == 3, np.nan, t), u=t)
    assert "array 'y', index 3: missing" in _err(tmp_path / "b.npz")
    np.savez(tmp_path / "c.npz", t=t, y=t[:5], u=t)
    assert "same length" in _err(tmp_path / "c.npz")
    np.savez(tmp_path / "d.npz", t=t, y=np.array(["a"] * 6), u=t)
    assert "must hold real numbers" in _err(tmp_path / "d.npz")
    np.savez(tmp_path / "e.npz", t=t, y=t, u=t, metadata=np.array("{bad"))
    assert "JSON object" in _err(tmp_path / "e.npz")
    np.save(tmp_path / "o.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    (tmp_path / "f.npz").write_bytes((tmp_path / "o.npy").read_bytes())
    assert "cannot read it as a NumPy .npz" in _err(tmp_path / "f.npz")
    np.savez(tmp_path / "g.npz", t=t[::-1], y=t, u=t)
    assert re.search(r"index 1, column 't'.*decreases", _err(tmp_path / "g.npz"))


# ------------------------------------------------------------------------------ properties

_VALID_ROWS = 10


def _mutations() -> st.SearchStrategy[tuple[str, int, str]]:
    """(kind, row, token): each kind makes the file malformed by construction."""
    bad_tokens = st.sampled_from(
        ["", " ", "nan", "NaN", "NA", "inf", "-inf", "x", "1,2", "1e", "--1", "null"]
    )
    return st.tuples(
        st.sampled_from(["cell", "swap", "duplicate", "drop", "rename", "shift", "short", "long"]),
        st.integers(min_value=1, max_value=_VALID_ROWS - 2),
        bad_tokens,
    )


def _mutated_csv(kind: str, row: int, token: str, column: int, name: str) -> str:
    rows = [[repr(0.5 * k), repr(float(np.sin(k))), repr(1.0)] for k in range(_VALID_ROWS)]
    header = ["t", "y", "u"]
    if kind == "cell":
        rows[row][column] = token if token != "1,2" else '"1,2"'
    elif kind == "swap":
        rows[row], rows[row + 1] = rows[row + 1], rows[row]
    elif kind == "duplicate":
        rows.insert(row, list(rows[row]))
    elif kind == "drop":
        rows.pop(row)
    elif kind == "rename":
        header[column] = name
    elif kind == "shift":
        rows[row][0] = repr(0.5 * row + 0.5 * (0.01 + 0.45 * (column + 1) / 3))
    elif kind == "short":
        rows[row] = rows[row][:column]
    elif kind == "long":
        rows[row] = [*rows[row], "0"]
    return "\n".join([",".join(header), *(",".join(r) for r in rows)]) + "\n"


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    mutation=_mutations(),
    column=st.integers(min_value=0, max_value=2),
    name=st.text(min_size=1, max_size=6).filter(
        lambda s: (
            s.strip() not in ("t", "y", "u", "k", "")
            and not any(c in s for c in ',"\n\r#')
            and s == s.strip()
        )
    ),
)
def test_every_malformed_csv_is_refused_with_a_located_message(mutation, column, name):
    kind, row, token = mutation
    text = _mutated_csv(kind, row, token, column, name)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "data.csv"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(DataFileError) as info:
            load(path)
    msg = str(info.value)
    assert "data.csv" in msg
    assert re.search(r"line \d+|column [\"']", msg), msg
    assert "Traceback" not in msg


@settings(max_examples=80, deadline=None)
@given(text=st.text(max_size=200))
def test_arbitrary_text_either_loads_or_fails_cleanly(text):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "data.csv"
        path.write_text(text, encoding="utf-8")
        try:
            ds = load(path, T=1.0)
        except DataFileError as exc:
            message = str(exc)
        else:  # only a genuinely valid file may load
            message = ""
            assert ds.data.N >= 4
    assert message or ds.data.N >= 4


@settings(max_examples=60, deadline=None)
@given(
    shape=st.sampled_from([(0,), (3,), (6, 2), ()]),
    dtype=st.sampled_from(["float64", "int32", "complex128", "bool", "U3"]),
    key=st.sampled_from(["t", "y", "u", "z"]),
)
def test_malformed_npz_arrays_are_refused(shape, dtype, key):
    good = {"t": np.arange(6.0), "y": np.ones(6), "u": np.ones(6)}
    good[key] = np.zeros(shape, dtype=dtype)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "d.npz"
        np.savez(path, **good)
        with pytest.raises(DataFileError) as info:
            load(path)
    assert "d.npz" in str(info.value)
