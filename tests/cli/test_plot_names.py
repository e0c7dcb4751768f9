"""Issue 25, item 9: `detect --plot x.txt` wrote PNG bytes to a .txt name; a --plot file
must end in .png (refused before any work), and a .png name gets a PNG."""

from click.testing import CliRunner

from jitterid.cli import main


def test_plot_names_must_end_in_png(tmp_path):
    res = CliRunner().invoke(main, ["simulate", "--out", str(tmp_path / "lab"), "--N", "60"])
    assert res.exit_code == 0, res.output
    detect = [
        "detect",
        str(tmp_path / "lab" / "data.csv"),
        "--input",
        str(tmp_path / "lab" / "input.csv"),
        "--model",
        "polepair",
        "--plot",
    ]
    res = CliRunner().invoke(main, [*detect, str(tmp_path / "x.txt")])
    assert res.exit_code == 2
    assert "give a file name ending in .png" in res.output
    assert not (tmp_path / "x.txt").exists()
    res = CliRunner().invoke(main, ["bias", "--jitter", "uniform:a=0.1", "--plot", "g.pdf"])
    assert res.exit_code == 2
    assert "ending in .png" in res.output
    res = CliRunner().invoke(main, [*detect, str(tmp_path / "r.PNG")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r.PNG").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
